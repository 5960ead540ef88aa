"""Measure the reference's constraint drift against its stabilization's own guarantee.

For every constrained model: the 5 s reference run with coordinate projection and without
(index1), both at rtol = atol = 1e-12, and per output time the ratios
    |f(q, t)| / (PROJECTION_TOL (1 + |q|_inf))   and   |A u + a0| / (eps max(|u|_inf, 1)).
and the largest |A u + a0| itself. With projection the first ratio is <= 1 by construction
(Gauss-Newton's stopping test) and the second is round-off; the reference's drift tolerances
(crosscheck/checks/trajectory/tolerances.py) are built from these bounds, and the index-1 run's
velocity drift is what INDEX1_VELOCITY_DRIFT quotes (docs/tolerances.md).

    python benchmarks/drift_guarantee.py [MODEL ...]
"""

from __future__ import annotations

import sys

import numpy as np

from crosscheck.checks.trajectory.check import REF_RTOL, output_grid
from reference import NumericModel, models
from reference.integrate.driver import PROJECTION_TOL, simulate

EPS = float(np.finfo(float).eps)


def main(names) -> None:
    for name in names or models.names():
        nm = NumericModel(models.get(name))
        if not nm.m:
            continue
        q0, u0 = nm.project(nm.model.initial_q, nm.model.initial_u)
        for method in ("projection", "index1"):
            r = simulate(
                nm, q0, u0, 5.0, method, rtol=REF_RTOL, atol=REF_RTOL, t_eval=output_grid(5.0)
            )
            pos, vel, vel_abs = [], [], 0.0
            for t, q, u in zip(r.t, r.q, r.u, strict=True):
                f, v = nm.residuals(q, u, t)
                qs, us = 1.0 + np.max(np.abs(q)), max(1.0, float(np.max(np.abs(u))))
                pos.append(float(np.max(np.abs(f), initial=0.0)) / (PROJECTION_TOL * qs))
                vel.append(float(np.max(np.abs(v), initial=0.0)) / (EPS * us))
                vel_abs = max(vel_abs, float(np.max(np.abs(v), initial=0.0)))
            print(
                f"{name:24s} {method:10s} |f|/(tol(1+|q|)) {max(pos):10.3g}  "
                f"|Au+a0|/(eps|u|) {max(vel):10.3g}  max|Au+a0| {vel_abs:10.3g}",
                flush=True,
            )


if __name__ == "__main__":
    main(sys.argv[1:])
