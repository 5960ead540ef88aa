"""How long the C compiler takes to build the built-in models' kernels
(benchmarks/reference_speed.md, "Build times").

Each model and formulation's generated module is printed as C and built into a fresh temporary
directory, one at a time (the derivation itself comes from the cache). Modules with the numeric
KKT solve have no C kernels and are left out; model names restrict it to theirs.

    python benchmarks/c_build_times.py [models...]
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

os.environ["CROSSCHECK_BACKEND"] = "python"  # derive (or read) only; the builds are timed here

from reference import models
from reference.backends import c_build as cbuild
from reference.backends import codegen
from reference.backends.c_source import c_source
from reference.numeric.model import PIVOT_RATIO_MIN, NumericModel


def main(names) -> None:
    rows, seen = [], set()
    with tempfile.TemporaryDirectory() as tmp:
        for name in names or models.names():
            model = models.get(name)
            for formulation in model.formulations:
                nm = NumericModel(model, formulation)
                stem = nm.cache_path.stem
                if stem in seen or codegen.numeric_kkt(nm.n, nm.m):
                    continue
                seen.add(stem)
                t0 = time.perf_counter()
                text, _sizes = c_source(nm.source, nm.nq, nm.n, len(nm.p), nm.m, PIVOT_RATIO_MIN)
                t1 = time.perf_counter()
                _path, _mod, build_s = cbuild.build(text, stem, Path(tmp))
                rows.append((f"{name}/{formulation}", t1 - t0, build_s, text.count("\n")))
    for label, src_s, build_s, lines in sorted(rows, key=lambda r: -r[2]):
        print(f"{label:40s} print {src_s:6.3f} s  build {build_s:6.2f} s  {lines:6d} lines of C")
    total = sum(r[2] for r in rows)
    worst = max(r[2] for r in rows)
    print(f"{len(rows)} modules: build {total:.1f} s in all, {worst:.2f} s at most")


if __name__ == "__main__":
    main(sys.argv[1:])
