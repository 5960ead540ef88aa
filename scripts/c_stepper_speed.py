"""The C stepper against the Python stepper (docs/compiled.md, "The compiled stepper"), the
records `crosscheck bench` writes to bench.json "stepper" (crosscheck/stepper_bench.py), for
the given models (default: four) with seven interleaved rounds, as a table.

    PYTHONPATH=$PWD python scripts/c_stepper_speed.py [models...]
"""

from __future__ import annotations

import os
import sys

os.environ.setdefault("CROSSCHECK_BACKEND", "c")

from crosscheck.stepper_bench import stepper_records

MODELS = ("pendulum_xy", "slider_crank", "double_pendulum_3d", "top_cartesian")


def main(names):
    print(
        f"{'model':20s} {'method':10s} {'outputs':8s} {'python ms':>10s} {'C ms':>8s} "
        f"{'ratio':>6s} {'nfev py/C':>11s} {'max |dy|':>9s}  stepper"
    )
    for r in stepper_records(names, quick=False):
        head = f"{r['model']:20s} {r['method']:10s} {r['outputs']:8s}"
        if "failed" in r:
            print(f"{head} failed: {r['failed']}")
            continue
        print(
            f"{head} {r['python_wall_s'] * 1e3:10.2f} {r['c_wall_s'] * 1e3:8.2f} "
            f"{r['speedup']:6.1f} {r['nfev_python']:5d}/{r['nfev_c']:<5d} "
            f"{r['max_difference']:9.1e}  {r['stepper']}"
        )


if __name__ == "__main__":
    main(sys.argv[1:] or MODELS)
