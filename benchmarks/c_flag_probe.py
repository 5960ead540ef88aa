"""What other optimization flags would give the C kernels (benchmarks/reference_speed.md,
"Compiler flags"): one model's generated module built with each flag set into a temporary
directory, its checked single-state forward kernel timed in one process, the sets alternated
over three rounds.

    python benchmarks/c_flag_probe.py [model]     # default top_cartesian
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np

os.environ["CROSSCHECK_BACKEND"] = "python"  # the generated source only; builds are made here

from reference import models
from reference.backends import c_build as cbuild
from reference.backends import c_source as ckernels
from reference.backends.kernels import import_file
from reference.numeric.model import PIVOT_RATIO_MIN, NumericModel

# each set replaces only the optimization level or adds one flag to the backend's own flags
VARIANTS = (["-O2"], ["-O3"], ["-O2", "-fno-trapping-math"], ["-O2", "-mavx2"], ["-O1"])


def main(name: str) -> None:
    nm = NumericModel(models.get(name))
    text, _sizes = ckernels.c_source(nm.source, nm.nq, nm.n, len(nm.p), nm.m, PIVOT_RATIO_MIN)
    base = [f for f in cbuild.CFLAGS if f != "-O2"]
    includes = [f"-I{d}" for d in cbuild._include_dirs()]
    q, u = np.array(nm.model.initial_q, float), np.array(nm.model.initial_u, float)
    out, pa, db = np.empty(nm.n + nm.m + 1), nm.kernel_parameters, nm.kernels.zero_db
    kernels = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, extra in enumerate(VARIANTS):
            modname = f"_crosscheck_flag_probe_{i}"
            src, so = Path(tmp) / f"{modname}.c", Path(tmp) / f"{modname}.so"
            src.write_text(text.replace(ckernels.MODULE_NAME, modname))
            t0 = time.perf_counter()
            cmd = [*cbuild.compiler(), *extra, *base, *includes, str(src), "-o", str(so), "-lm"]
            subprocess.run(cmd, check=True, capture_output=True)
            build_s = time.perf_counter() - t0
            kernels.append((extra, build_s, import_file(so, modname).forward))
        for _round in range(3):
            for extra, build_s, f in kernels:
                call = lambda f=f: f(q, u, 0.0, pa, db, out)
                us = min(timeit.repeat(call, number=50_000, repeat=5)) / 50_000 * 1e6
                print(f"{name} {' '.join(extra):24s} build {build_s:5.2f} s  {us:.3f} us per call")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "top_cartesian")
