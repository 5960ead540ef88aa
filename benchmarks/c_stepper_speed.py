"""The C stepper against the Python stepper (benchmarks/reference_speed.md, "The compiled
stepper"): the records `crosscheck bench` writes to bench.json "stepper"
(crosscheck/bench/stepper.py), for the given models (default: four), seven interleaved rounds
(three with --quick), as a table; "/ tol" is the largest output difference in units of rtol
(1 + max |q|, |u|). With --profile: cProfile of 200 C-stepper runs of the slider-crank (index1,
rtol 1e-10, every step recorded), what the run spends outside the C loop.

    python benchmarks/c_stepper_speed.py [--quick] [models...]
    python benchmarks/c_stepper_speed.py --profile
"""

from __future__ import annotations

import os
import sys

os.environ.setdefault("CROSSCHECK_BACKEND", "c")

from crosscheck.bench.stepper import RTOL, stepper_records

MODELS = ("pendulum_xy", "slider_crank", "double_pendulum_3d", "top_cartesian")


def main(names, quick=False):
    print(
        f"{'model':20s} {'method':10s} {'outputs':8s} {'python ms':>10s} {'C ms':>8s} "
        f"{'ratio':>6s} {'nfev py/C':>11s} {'max |dy|':>9s} {'/ tol':>7s}  stepper"
    )
    for r in stepper_records(names, quick=quick):
        head = f"{r['model']:20s} {r['method']:10s} {r['outputs']:8s}"
        if "failed" in r:
            print(f"{head} failed: {r['failed']}")
            continue
        print(
            f"{head} {r['python_wall_s'] * 1e3:10.2f} {r['c_wall_s'] * 1e3:8.2f} "
            f"{r['speedup']:6.1f} {r['nfev_python']:5d}/{r['nfev_c']:<5d} "
            f"{r['max_difference']:9.1e} {r['max_difference'] / (RTOL * r['state_scale']):7.3f}"
            f"  {r['stepper']}"
        )


def profile() -> None:
    import cProfile
    import pstats

    from reference import NumericModel, models
    from reference.integrate.driver import simulate

    nm = NumericModel(models.get("slider_crank"))
    q0, u0 = nm.model.initial_q, nm.model.initial_u

    def runs():
        for _ in range(200):
            simulate(nm, q0, u0, 2.0, "index1", rtol=RTOL, atol=RTOL, energy="none", stepper="c")

    runs()  # warm: the kernels and the tableau
    pr = cProfile.Profile()
    pr.runcall(runs)
    pstats.Stats(pr).sort_stats("tottime").print_stats(12)


if __name__ == "__main__":
    if sys.argv[1:] == ["--profile"]:
        profile()
    else:
        args = sys.argv[1:]
        quick = "--quick" in args
        main([a for a in args if a != "--quick"] or MODELS, quick)
