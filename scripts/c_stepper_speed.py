"""The C stepper against the Python stepper (docs/compiled.md, "The compiled stepper"): the
wall time of simulate() on each model over its work-precision horizon, index1, projection and
baumgarte at rtol = atol 1e-10, every accepted step recorded (the work-precision runs) and on a
201-point grid with the work integral where the model carries it (the trajectory checks' reference
runs); best of 7, with the right-side calls and the largest output difference.

    PYTHONPATH=$PWD python scripts/c_stepper_speed.py [models...]
"""

from __future__ import annotations

import os
import sys

import numpy as np

os.environ.setdefault("CROSSCHECK_BACKEND", "c")

from crosscheck.workprecision import horizon
from reference import models
from reference.integrate import simulate
from reference.numeric import NumericModel

MODELS = ("pendulum_xy", "slider_crank", "double_pendulum_3d", "top_cartesian")
RTOL = 1e-10


def best(nm, T, method, stepper, **kw):
    m, runs = nm.model, []
    for _ in range(7):
        runs.append(
            simulate(
                nm, m.initial_q, m.initial_u, T, method, rtol=RTOL, atol=RTOL, stepper=stepper, **kw
            )
        )
    return min(r.wall_s for r in runs), runs[-1]


def main(names):
    print(
        f"{'model':20s} {'method':10s} {'outputs':8s} {'python ms':>10s} {'C ms':>8s} "
        f"{'ratio':>6s} {'nfev py/C':>11s} {'max |dy|':>9s}"
    )
    for name in names:
        nm = NumericModel(models.get(name))
        T = horizon(name)
        for method in ("index1", "projection", "baumgarte"):
            for label, kw in (
                ("steps", {"energy": "none"}),
                ("grid", {"t_eval": np.linspace(0.0, T, 201)}),
            ):
                (wp, p), (wc, c) = (best(nm, T, method, s, **kw) for s in ("python", "c"))
                d = (
                    np.max(np.abs(p.final_state - c.final_state))
                    if label == "steps"
                    else max(np.max(np.abs(p.q - c.q)), np.max(np.abs(p.u - c.u)))
                )
                print(
                    f"{name:20s} {method:10s} {label:8s} {wp * 1e3:10.2f} {wc * 1e3:8.2f} "
                    f"{wp / wc:6.1f} {p.nfev:5d}/{c.nfev:<5d} {d:9.1e}"
                )


if __name__ == "__main__":
    main(sys.argv[1:] or MODELS)
