"""The tolerances of the trajectory records, each with the reason for its size.

The reference's are its stabilization's own guarantees (a run whose projection is switched off
fails them); the engines' depend on how their integrator treats the constraint rows: not at all
(an adaptive index-1 run, INDEX1_*), exactly (minimal coordinates or position rows solved every
step, EXACT_ROWS_DRIFT) or softly (crosscheck.checks.trajectory.soft).
"""

from __future__ import annotations

import numpy as np

from crosscheck.checks import tolerances as C
from reference.integrate.driver import PROJECTION_TOL

REFERENCE_ACCURACY = C.Tolerance(
    1e-8,
    "the reference trajectory (rtol 1e-12) against a tighter one (rtol 1e-13): the "
    "engines are judged against it, so its own error must sit far below the 1e-6..1e-2 "
    "they are held to",
)
# The reference's stabilization guarantees its own bounds, so they are the tolerances: a run
# whose projection is switched off must fail here, not only at the gate. Measured over 5 s on
# every constrained model (the ratios are per output time):
#   |f| / (PROJECTION_TOL (1 + |q|_inf)): 0.88..1.00 with projection, 17..1.6e5 without (index1)
#   |A u + a0| / (eps max(|u|_inf, 1)):   0.1..1.1 with projection, 610..1e5 without
# (PYTHONPATH=$PWD python benchmarks/drift_guarantee.py). Gauss-Newton stops at
# |f| <= PROJECTION_TOL (1 + |q|_inf) at every output (reference.integrate.driver.project_q); the
# slack of 2 covers the largest |q| falling elsewhere than the largest |f|.
PROJECTION_SLACK = 2.0
# the velocity projection is an exact minimum-norm correction: what is left is the round-off of
# evaluating A u + a0, a few eps times the size of the speeds (1.1 measured, 16 allowed)
VELOCITY_ROUND_OFF = 16 * float(np.finfo(float).eps)


REF_ENERGY = C.Tolerance(
    1e-9,
    "DOP853 at rtol 1e-12: energy error well below 1e-9 relative over the 5-10 s runs measured "
    "(projection does not conserve energy exactly, docs/tolerances.md)",
)


def ref_energy(t_end: float) -> C.Tolerance:
    """REF_ENERGY with the run's own horizon in its reason."""
    return C.Tolerance(
        REF_ENERGY.value,
        f"DOP853 at rtol 1e-12 over this run's {t_end:g} s: energy error well below 1e-9 "
        "relative (measured over 5-10 s; projection does not conserve energy exactly, "
        "docs/tolerances.md)",
    )


def projected_drift(q) -> C.Tolerance:
    """The projection's own guarantee on f(q, t) over a run with coordinates q."""
    qmax = float(np.max(np.abs(np.asarray(q)))) if np.size(q) else 0.0
    return C.Tolerance(
        PROJECTION_SLACK * PROJECTION_TOL * (1.0 + qmax),
        f"coordinate projection after every step stops Gauss-Newton at |f| <= PROJECTION_TOL "
        f"(1 + |q|) = {PROJECTION_TOL:g} x {1 + qmax:.3g} (reference.integrate.driver), x"
        f"{PROJECTION_SLACK:g} for where the largest |q| falls; without projection the drift is "
        f"17x..1.6e5x that bound",
    )


def projected_velocity_drift(u) -> C.Tolerance:
    """The velocity projection's guarantee on A u + a0 over a run with speeds u."""
    umax = max(float(np.max(np.abs(np.asarray(u)))) if np.size(u) else 0.0, 1.0)
    return C.Tolerance(
        VELOCITY_ROUND_OFF * umax,
        f"the velocity projection u <- u - A^T (A A^T)^-1 (A u + a0) is exact: round-off of "
        f"A u + a0 only, 16 eps x max |u| ({umax:.3g}); measured <= 1.19 eps |u| with it, >= "
        f"605 eps |u| without",
    )


INDEX1_DRIFT = C.Tolerance(
    1e-7,
    "no stabilization: the position drift follows the integrator's error, ~10..100x its "
    "tolerance over 5..10 s (docs/tolerances.md); 1e3x rtol",
)
INDEX1_VELOCITY_DRIFT = C.Tolerance(
    1e-7,
    "no stabilization: A u + a0 drifts with the integrator's error like the positions "
    "(INDEX1_DRIFT); measured 4e-13..4e-10 for the reference's own index-1 run at rtol "
    "1e-12 (benchmarks/drift_guarantee.py)",
)
# An engine that holds the position rows exactly: its model has none (minimal coordinates), or
# its fixed-step index-3 solver solves them at every step (Exudyn's generalized-alpha). The
# drift is then the Newton tolerance or round-off: measured 0 to 1.1e-13 on every model with
# `crosscheck run` (Exudyn 1.3e-15..1.1e-13, MuJoCo's unconstrained trees <= 2.2e-16). 1e-10 is
# 1000x that, and it catches a 1e-9 change of Exudyn's rod length that the index-1 bound
# (1e-7) let pass up to 1e-6 (`crosscheck sensitivity pendulum_xy --engines exudyn`).
EXACT_ROWS_DRIFT = C.Tolerance(
    1e-10,
    "the position rows are held exactly (minimal coordinates, or solved at every step by an "
    "index-3 integrator): drift is Newton's tolerance or round-off, measured <= 1.1e-13; "
    "1000x that",
)
