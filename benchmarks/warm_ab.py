"""Warm `crosscheck run` wall times of an earlier commit and of this checkout, interleaved (A, B,
A, B, ...), so that the machine's drift over minutes (other jobs, clock changes) falls on both
alike. Each side gets its own derivation cache, warmed by one run first.

The earlier commit is checked out into a temporary git worktree and run with PYTHONPATH
pointing at it (the engines' entry points resolve to its modules). Output goes to files, not
pipes: the time is the command's own, up to its exit, as at a terminal (a pipe's reader also
waits for the workers' server to exit).

    python benchmarks/warm_ab.py 9ce6640 --reps 3 -- --engines pinocchio,mujoco
    python benchmarks/warm_ab.py 9ce6640 --reps 2 -- --jobs 1
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent


def _run(tree: Path, cache: Path, out: Path, run_args: list[str]) -> float:
    env = {**os.environ, "PYTHONPATH": str(tree), "CROSSCHECK_CACHE_DIR": str(cache)}
    cmd = [sys.executable, "-m", "crosscheck", "run", "--out", str(out), "--no-report"]
    with open(out.with_suffix(".log"), "w") as log:
        t0 = time.perf_counter()
        r = subprocess.run([*cmd, *run_args], cwd=tree, env=env, stdout=log, stderr=log)
        wall = time.perf_counter() - t0
    if r.returncode != 0:
        sys.exit(f"{tree}: exit {r.returncode}; see {out.with_suffix('.log')}")
    return wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rev", help="the earlier commit (A)")
    ap.add_argument("--reps", type=int, default=3)
    argv = sys.argv[1:]
    cut = argv.index("--") if "--" in argv else len(argv)
    args = ap.parse_args(argv[:cut])  # after --: crosscheck run's own options
    args.run_args = argv[cut + 1 :]
    with tempfile.TemporaryDirectory(prefix="warm-ab-") as tmp:
        base = Path(tmp)
        old = base / "a"
        subprocess.run(
            ["git", "-C", str(HERE), "worktree", "add", "-q", "--detach", str(old), args.rev],
            check=True,
        )
        try:
            sides = {"A": old, "B": HERE}
            walls: dict[str, list[float]] = {k: [] for k in sides}
            for side, tree in sides.items():  # warm each cache once
                _run(tree, base / f"cache-{side}", base / f"out-{side}", args.run_args)
            for rep in range(args.reps):
                for side, tree in sides.items():
                    wall = _run(tree, base / f"cache-{side}", base / f"out-{side}", args.run_args)
                    walls[side].append(wall)
                print(f"rep {rep + 1}: A {walls['A'][-1]:6.2f} s   B {walls['B'][-1]:6.2f} s")
            for side in sides:
                w = walls[side]
                print(f"{side} median {statistics.median(w):.2f} s (min {min(w):.2f})")
        finally:
            subprocess.run(["git", "-C", str(HERE), "worktree", "remove", "--force", str(old)])


if __name__ == "__main__":
    main()
