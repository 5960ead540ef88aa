"""Wall time of a full `crosscheck run` (every model, default options), cold and warm, in one
process and on worker processes (benchmarks/run_time.md).

For each --jobs value: a fresh derivation cache (cold: every derivation and C build), then the
same cache again (warm). The runs' records are compared with the first run's: the worker
processes must not change a record.

    python benchmarks/startup_times.py            # --jobs 1 and 2, about 4 min
    python benchmarks/startup_times.py --jobs 2 --models slider_crank top_euler
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _run(cache: Path, out: Path, jobs: int, models: list[str]) -> tuple[float, str]:
    env = {**os.environ, "CROSSCHECK_CACHE_DIR": str(cache)}
    cmd = [sys.executable, "-m", "crosscheck", "run", *models, "--out", str(out)]
    t0 = time.perf_counter()
    r = subprocess.run(
        [*cmd, "--no-report", "--jobs", str(jobs)], env=env, capture_output=True, text=True
    )
    wall = time.perf_counter() - t0
    if r.returncode not in (0, 1):
        sys.exit(f"crosscheck run failed (exit {r.returncode}):\n{r.stderr}")
    return wall, r.stdout.strip().splitlines()[-1]


def _records(out: Path) -> list[tuple]:
    records = json.loads((out / "results.json").read_text())["records"]
    return [(r["model"], r["engine"], r["check"], r["error"], r["passed"]) for r in records]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--models", nargs="*", default=[])
    args = ap.parse_args()
    first = None
    print(f"{'run':6} {'jobs':>4} {'wall s':>8}  records equal to the first run's  summary")
    with tempfile.TemporaryDirectory() as tmp:
        for jobs in args.jobs:
            cache = Path(tmp) / f"cache-{jobs}"
            for kind in ("cold", "warm"):
                out = Path(tmp) / f"out-{jobs}-{kind}"
                wall, summary = _run(cache, out, jobs, args.models)
                records = _records(out)
                first = first or records
                same = records == first
                print(f"{kind:6} {jobs:>4} {wall:8.1f}  {same!s:34} {summary.split(' ->')[0]}")


if __name__ == "__main__":
    main()
