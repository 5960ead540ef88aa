"""What a trajectory is judged by: the scaled state error against the reference, the
constraint and velocity residuals, and the energy (drift, or work-energy balance) along a run.

State error: max over the output times of max |x - x_ref| / max(max |x_ref|, 1), x = (q, u) in
the reference's coordinates. Angles are unwrapped in time and a whole-turn offset at t = 0 is
removed, so a coordinate reported modulo 2 pi does not count as an error.
"""

from __future__ import annotations

import numpy as np

from crosscheck.checks.instantaneous import constraint_residual, energy_drift, work_energy_balance
from reference import NumericModel


def state_error(q, u, ref_q, ref_u) -> np.ndarray:
    """Scaled state error at every output time (angles unwrapped, whole-turn offset removed)."""
    qa, qb = np.unwrap(np.asarray(q), axis=0), np.unwrap(np.asarray(ref_q), axis=0)
    offset = 2 * np.pi * np.round((qa[0] - qb[0]) / (2 * np.pi))
    diff = np.hstack([qa - qb - offset, np.asarray(u) - np.asarray(ref_u)])
    scale = max(float(np.max(np.abs(np.hstack([ref_q, ref_u])))), 1.0)
    return np.max(np.abs(diff), axis=1) / scale


def residual_series(nm: NumericModel, t, q, u) -> tuple[np.ndarray, np.ndarray]:
    """max |f(q, t)| and max |A u + a0| at every output time (0 where there are no rows)."""
    res = np.array(
        [constraint_residual(nm, qi, ui, ti) for ti, qi, ui in zip(t, q, u, strict=True)]
    )
    res = res.reshape(len(t), 2)
    return res[:, 0], res[:, 1]


def energy_series(nm: NumericModel, t, q, u) -> np.ndarray:
    return np.array([sum(nm.energy(qi, ui, ti)) for ti, qi, ui in zip(t, q, u, strict=True)])


def energy_measure(ctx, t, q, u) -> float:
    """The energy figure a trajectory record judges: drift where energy is conserved, else
    the work-energy balance against the reference's work (ctx: nm, conserved, work)."""
    E = energy_series(ctx.nm, t, q, u)
    return energy_drift(E) if ctx.conserved else work_energy_balance(E, ctx.work)
