"""Whether a warm derivation cache stays warm for a second checkout of the same commit (a git
worktree, a CI cache restored under another path): a fresh cache is warmed by two runs from
one worktree, then two runs are timed from another (docs/compiled.md, "The C backend").

    PYTHONPATH=$PWD python scripts/second_checkout.py HEAD
    PYTHONPATH=$PWD python scripts/second_checkout.py ffbfd67 -- --engines pinocchio,mujoco
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent


def _run(tree: Path, cache: Path, out: Path, run_args: list[str]) -> float:
    env = {"PYTHONPATH": str(tree), "CROSSCHECK_CACHE_DIR": str(cache)}
    cmd = [sys.executable, "-m", "crosscheck", "run", "--out", str(out), "--no-report", *run_args]
    t0 = time.perf_counter()
    with open(out.with_suffix(".log"), "w") as log:
        r = subprocess.run(cmd, cwd=tree, env={**os.environ, **env}, stdout=log, stderr=log)
    if r.returncode != 0:
        sys.exit(f"{tree}: exit {r.returncode}; see {out.with_suffix('.log')}")
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rev")
    argv = sys.argv[1:]
    cut = argv.index("--") if "--" in argv else len(argv)
    args = ap.parse_args(argv[:cut])
    run_args = argv[cut + 1 :]
    with tempfile.TemporaryDirectory(prefix="second-checkout-") as tmp:
        base = Path(tmp)
        trees = [base / "first", base / "second"]
        for tree in trees:
            subprocess.run(
                ["git", "-C", str(HERE), "worktree", "add", "-q", "--detach", str(tree), args.rev],
                check=True,
            )
        try:
            for tree in (trees[0], trees[0], trees[1], trees[1]):
                wall = _run(tree, base / "cache", base / "out", run_args)
                print(f"{tree.name:6} checkout: {wall:6.2f} s", flush=True)
        finally:
            for tree in trees:
                subprocess.run(["git", "-C", str(HERE), "worktree", "remove", "--force", str(tree)])


if __name__ == "__main__":
    main()
