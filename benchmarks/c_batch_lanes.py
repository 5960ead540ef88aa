"""The C batch's four-lane body (benchmarks/reference_speed.md, "The four-lane batch").

10^4 consistent states per model, timed through the batch kernel with the parameters shared
(splatted once per batch) and with one parameter row per state (gathered per block of four, as
a sweep runs), and through NumericModel.forward_batch; every 37th state is compared with the
checked single-state call, to the bit.

    python benchmarks/c_batch_lanes.py [models...]
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

os.environ.setdefault("CROSSCHECK_BACKEND", "c")

from crosscheck.checks.sampling import consistent_states
from reference import models
from reference.numeric.model import NumericModel

N = 10_000
MODELS = ("pendulum_xy", "slider_crank", "double_pendulum_3d", "top_cartesian")


def best_us(call, repeats: int = 7) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return min(times) / N * 1e6


def measure(name: str) -> str:
    nm = NumericModel(models.get(name))
    if nm.backend != "c":
        sys.exit(f"{name}: backend {nm.backend}, not c (no working C compiler?)")
    states = consistent_states(nm, 64)
    reps = N // len(states) + 1
    Q = np.ascontiguousarray(np.tile([q for q, _ in states], (reps, 1))[:N], float)
    U = np.ascontiguousarray(np.tile([u for _, u in states], (reps, 1))[:N], float)
    UD, LAM, piv = nm.forward_batch(Q, U, 0.0)
    same = True
    for i in range(0, N, 37):
        one = nm.forward(Q[i], U[i])
        row = np.r_[one.accelerations, one.multipliers, one.pivot_ratio]
        same &= np.array_equal(np.r_[UD[i], LAM[i], piv[i]], row)
    kernel, pa = nm.kernels.batch("forward"), nm.kernel_parameters
    T, DB = np.zeros(1), nm.kernels.zero_db[None]
    shared, per_state = pa[None], np.ascontiguousarray(np.tile(pa, (N, 1)))
    out, st = np.empty((N, nm.n + nm.m + 1)), np.empty(N, np.int64)
    lanes = best_us(lambda: kernel(Q, U, T, shared, DB, out, st))
    rows = best_us(lambda: kernel(Q, U, T, per_state, DB, out, st))
    public = best_us(lambda: nm.forward_batch(Q, U, 0.0))
    return (
        f"{name:20s} four lanes {lanes:.3f}  per-state parameters {rows:.3f}  "
        f"forward_batch {public:.3f}"
        f" us per state (min of 7 x {N}); equal to the single call to the bit: {same}"
    )


def main(names) -> None:
    for name in names:
        print(measure(name))


if __name__ == "__main__":
    main(sys.argv[1:] or MODELS)
