"""Where a `crosscheck run` spends its trajectory time: the wall time and the number of calls of
every engine model's `simulate` (per class that defines one) and of the reference's, in one
process (`--jobs 1` is added: with worker processes the parent only waits). Whatever the run
does besides is the rest of the total.

    CROSSCHECK_CACHE_DIR=<warm> python benchmarks/engine_simulate_times.py \\
        --out <dir> --no-report [--engines pinocchio,mujoco]
"""

from __future__ import annotations

import collections
import functools
import sys
import time

from crosscheck import cli  # the standard library only: numpy and the engines load in main()

SPENT: collections.Counter[str] = collections.Counter()
CALLS: collections.Counter[str] = collections.Counter()


def _timed(key: str, fn):
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            SPENT[key] += time.perf_counter() - t0
            CALLS[key] += 1

    return wrapper


def _subclasses(cls):
    for sub in cls.__subclasses__():
        yield sub
        yield from _subclasses(sub)


def main() -> None:
    cli.one_blas_thread()  # as the `crosscheck` program sets them, before numpy and MuJoCo load
    cli.no_mujoco_rendering()
    from crosscheck.checks.trajectory import check as trajectory
    from crosscheck.engines.base import EngineModel
    from crosscheck.engines.registry import available_engines, get_engine

    for name in available_engines():  # imports every adapter, so its model classes exist
        get_engine(name)
    for cls in set(_subclasses(EngineModel)):
        if "simulate" in cls.__dict__:
            cls.simulate = _timed(f"{cls.__module__}.{cls.__qualname__}", cls.simulate)
    trajectory.simulate = _timed(
        "reference (crosscheck.checks.trajectory.check.simulate)", trajectory.simulate
    )
    t0 = time.perf_counter()
    try:
        cli.main(["run", *sys.argv[1:], "--jobs", "1"])
    except SystemExit:
        pass
    print(f"total {time.perf_counter() - t0:.2f} s")
    for key, spent in SPENT.most_common():
        print(f"  {key:60s} {spent:7.2f} s  {CALLS[key]:4d} calls")


if __name__ == "__main__":
    main()
