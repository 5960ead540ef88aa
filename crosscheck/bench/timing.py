"""Wall-clock timing for benchmarks: median of repeats, each repeat a loop of calls.

The machine is shared and noisy (2 cores): medians move by up to 2-3x between runs, so the suite
compares timings only as ratios measured in the same run, and reports the minimum beside the
median.
"""

from __future__ import annotations

import statistics
import time


def per_call_seconds(fn, *, min_time: float = 0.02, repeats: int = 7) -> dict:
    """Median and min seconds per call of fn() over `repeats` loops of about `min_time` each."""
    n = 1
    while True:  # calibrate the loop length
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        dt = time.perf_counter() - t0
        if dt >= min_time or n >= 1 << 20:
            break
        n *= 2 if dt <= 0 else max(2, min(10, int(min_time / max(dt, 1e-9)) + 1))
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        samples.append((time.perf_counter() - t0) / n)
    return {
        "median": statistics.median(samples),
        "min": min(samples),
        "loops": n,
        "repeats": repeats,
    }


def interleaved_seconds(calls: dict, *, rounds: int = 15, min_time: float = 0.02) -> dict:
    """{name: {median, min, loops, repeats}} of each zero-argument call, the calls timed in
    turn round after round (one loop of about `min_time` each per round): a change of load
    lands on every call alike, so their ratios hold better than those of back-to-back runs."""
    loops = {
        k: per_call_seconds(fn, min_time=min_time, repeats=1)["loops"] for k, fn in calls.items()
    }
    samples: dict = {k: [] for k in calls}
    for _ in range(rounds):
        for k, fn in calls.items():
            n = loops[k]
            t0 = time.perf_counter()
            for _ in range(n):
                fn()
            samples[k].append((time.perf_counter() - t0) / n)
    return {
        k: {"median": statistics.median(s), "min": min(s), "loops": loops[k], "repeats": rounds}
        for k, s in samples.items()
    }
