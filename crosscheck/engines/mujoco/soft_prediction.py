"""MuJoCo's soft answer predicted from the reference's rigid answer and the documented impedance.

MuJoCo solves equality constraints softly: with the constraint Jacobian J, the mass matrix M,
the smooth forces s (everything but constraint forces) and the reference acceleration aref,

    M a = s + Jᵀ f,     J a + R f = aref,      R = (1 − d)/d · A_diag          (soft)

where d is the impedance of ``solimp`` at the row's violation and A_diag MuJoCo's approximation
of the diagonal of J M⁻¹ Jᵀ (for a ``connect`` row: the sum of the two bodies' translational
``body_invweight0``). With R = 0 this is the rigid problem. The prediction below never reads
MuJoCo's constraint force or acceleration:

1. the rigid engine accelerations a_r from the REFERENCE's accelerations (mapped into engine
   coordinates through the affine map G a + c the adapter uses the other way) and J a_r = aref;
2. the rigid force f_r from M a_r = s + Jᵀ f_r;
3. the soft correction (y, δ) from subtracting the two systems:
   [[M, −Jᵀ], [J, R]] [y; δ] = [0; −R f_r], so a = a_r + y and f = f_r + δ.

So raw − predicted measures MuJoCo's solve against the documented model of its own softness,
and a physics error in the engine model (a wrong mass) shows as a miss of the size of that
error over the soft effect (~1e-4), not hidden by the recovery that uses MuJoCo's own force.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from crosscheck.engines.base import EngineUnsupported


@dataclass(frozen=True)
class SoftPrediction:
    engine_accelerations: np.ndarray  # predicted soft qacc
    engine_forces: np.ndarray  # predicted soft efc_force
    R: np.ndarray  # the documented regularization of each row


def impedance(solimp, r: float) -> float:
    """solimp = (dmin, dmax, width, midpoint, power) at violation r (MuJoCo's documented
    piecewise power sigmoid between dmin at r = 0 and dmax at |r| >= width)."""
    dmin, dmax, width, mid, power = (float(x) for x in solimp)
    x = abs(r) / width if width > 0 else 1.0
    if x >= 1.0:
        return dmax
    if x <= 0.0:
        return dmin
    if x <= mid:
        y = x**power / mid ** (power - 1.0)
    else:
        y = 1.0 - (1.0 - x) ** power / (1.0 - mid) ** (power - 1.0)
    return dmin + y * (dmax - dmin)


def _row_bodies(m, e: int) -> tuple[int, int]:
    o1, o2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
    if m.eq_objtype[e] == mujoco.mjtObj.mjOBJ_SITE:
        return int(m.site_bodyid[o1]), int(m.site_bodyid[o2])
    return o1, o2


def documented_R(m, d) -> np.ndarray:
    """R of every equality row from solimp and body_invweight0 (connect rows only)."""
    out = []
    for i in range(d.nefc):
        e = int(d.efc_id[i])
        if m.eq_type[e] != mujoco.mjtEq.mjEQ_CONNECT:
            raise EngineUnsupported(
                "only connect rows have a documented diagonal approximation of A "
                f"here; equality {e} is of type {int(m.eq_type[e])}"
            )
        b1, b2 = _row_bodies(m, e)
        diag = float(m.body_invweight0[b1, 0] + m.body_invweight0[b2, 0])
        dimp = impedance(m.eq_solimp[e], float(d.efc_pos[i]))
        out.append((1.0 - dimp) / dimp * diag)
    return np.array(out)


def predict(M, J, smooth, aref, R, G, c, reference_accelerations) -> SoftPrediction:
    """The soft (qacc, efc_force) MuJoCo should return, from the reference's accelerations
    (u' = G qacc + c maps engine accelerations to the reference's speeds)."""
    nv, ne = M.shape[0], J.shape[0]
    A = np.vstack([G, J])
    rhs = np.concatenate([np.asarray(reference_accelerations, float) - c, aref])
    a_r = np.linalg.lstsq(A, rhs, rcond=None)[0]
    f_r = np.linalg.lstsq(J.T, M @ a_r - smooth, rcond=None)[0]
    K = np.block([[M, -J.T], [J, np.diag(R)]])
    sol = np.linalg.solve(K, np.concatenate([np.zeros(nv), -R * f_r]))
    return SoftPrediction(a_r + sol[:nv], f_r + sol[nv : nv + ne], np.asarray(R, float))
