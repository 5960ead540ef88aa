"""MuJoCo's soft answer predicted from the reference's rigid answer and the documented impedance.

MuJoCo solves equality constraints softly: with the constraint Jacobian J, the mass matrix M,
the smooth forces s (everything but constraint forces) and the reference acceleration aref,

    M a = s + Jᵀ f,     J a + R f = aref,      R = (1 − d)/d · A_diag          (soft)

where d is the impedance of ``solimp`` at the constraint's violation and A_diag MuJoCo's
approximation of the diagonal of J M⁻¹ Jᵀ (mj_diagApprox: for a ``connect`` row and a ``weld``'s
position rows the sum of the two bodies' translational ``body_invweight0``, for a weld's
rotation rows their rotational ones, for a ``joint`` row the two joints' ``dof_invweight0``).
With R = 0 this is the rigid problem. The prediction below never reads MuJoCo's constraint
force or acceleration:

1. the rigid engine accelerations a_r from the REFERENCE's accelerations (mapped into engine
   coordinates through the affine map G a + c the adapter uses the other way) and
   J a_r = aref + o (o below);
2. the rigid force f_r from M a_r = s + Jᵀ f_r;
3. the soft correction (y, δ) from subtracting the two systems:
   [[M, −Jᵀ], [J, R]] [y; δ] = [0; −R f_r − o], so a = a_r + y and f = f_r + δ, where o is
   the part of the rigid row acceleration −J̇ v that MuJoCo's aref leaves out (a ``joint``
   equality row's poly''(x) v2²: MuJoCo's model, predicted as it is; 0 on other rows).

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


# MuJoCo's floor on R and on solimp's width (mjMINVAL): R = max(mjMINVAL, (1 - d)/d A_diag)
MJ_MINVAL = 1e-15
# MuJoCo's bounds on solimp's impedances and midpoint (mjMINIMP, mjMAXIMP): getsolparam clamps
# them before use (soft_weld.xml's solimp "0 0.96 0.01" has an impedance of 0.0001 at rest)
MJ_MINIMP, MJ_MAXIMP = 1e-4, 0.9999


def impedance(solimp, r: float) -> float:
    """solimp = (dmin, dmax, width, midpoint, power) at violation r (MuJoCo's documented
    piecewise power sigmoid between dmin at r = 0 and dmax at |r| >= width), after MuJoCo's
    own clamping of solimp, flat where dmin = dmax or the width is 0 (getimpedance)."""
    dmin, dmax, width, mid, power = (float(x) for x in solimp)
    dmin, dmax = (min(MJ_MAXIMP, max(MJ_MINIMP, v)) for v in (dmin, dmax))
    mid, width, power = min(MJ_MAXIMP, max(MJ_MINIMP, mid)), max(0.0, width), max(1.0, power)
    if dmin == dmax or width <= MJ_MINVAL:
        return 0.5 * (dmin + dmax)
    x = abs(r) / width
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


def _diag_approx(m, e: int, k: int) -> float:
    """MuJoCo's approximation of diag(J M^-1 J^T) for row k of equality e (mj_diagApprox):
    the two bodies' translational inverse weights for a connect row and a weld's position
    rows, their rotational ones for a weld's rotation rows (k >= 3), the two joints' dof
    inverse weights for a joint row."""
    kind = int(m.eq_type[e])
    if kind == int(mujoco.mjtEq.mjEQ_JOINT):
        j1, j2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
        out = float(m.dof_invweight0[m.jnt_dofadr[j1]])
        return out + (float(m.dof_invweight0[m.jnt_dofadr[j2]]) if j2 >= 0 else 0.0)
    if kind not in (int(mujoco.mjtEq.mjEQ_CONNECT), int(mujoco.mjtEq.mjEQ_WELD)):
        raise EngineUnsupported(
            f"equality {e} is of type {kind}: no documented diagonal approximation here"
        )
    b1, b2 = _row_bodies(m, e)
    rot = int(kind == int(mujoco.mjtEq.mjEQ_WELD) and k >= 3)
    return float(m.body_invweight0[b1, rot] + m.body_invweight0[b2, rot])


def documented_R(m, d) -> np.ndarray:
    """R of every equality row from solimp and the inverse weights (connect, weld and joint
    rows): R = (1 - d)/d A_diag, d the impedance at the violation of the row's constraint (the
    norm of a connect's 3 or a weld's 6 efc_pos, as mj_makeImpedance takes it)."""
    kind = np.asarray(d.efc_type[: d.nefc])
    ids = np.asarray(d.efc_id[: d.nefc])
    pos = np.asarray(d.efc_pos[: d.nefc])
    out = np.zeros(d.nefc)
    for i in range(d.nefc):
        if kind[i] != mujoco.mjtConstraint.mjCNSTR_EQUALITY:
            raise EngineUnsupported(f"efc row {i} is not an equality row: no prediction here")
        e = int(ids[i])
        block = np.flatnonzero((kind == kind[i]) & (ids == e))
        k = int(np.searchsorted(block, i))
        violation = float(np.linalg.norm(pos[block])) if block.size > 1 else float(pos[i])
        dimp = impedance(m.eq_solimp[e], violation)
        out[i] = max(MJ_MINVAL, (1.0 - dimp) / dimp * _diag_approx(m, e, k))
    return out


def predict(M, J, smooth, aref, R, G, c, reference_accelerations, omitted=None) -> SoftPrediction:
    """The soft (qacc, efc_force) MuJoCo should return, from the reference's accelerations
    (u' = G qacc + c maps engine accelerations to the reference's speeds). ``omitted``: the
    part of -J-dot v aref leaves out per row (a joint equality's, soft_recovery.omitted_jdot_v):
    the rigid answer meets aref + omitted, MuJoCo's soft one aims at aref alone."""
    nv, ne = M.shape[0], J.shape[0]
    omitted = np.zeros(ne) if omitted is None else np.asarray(omitted, float)
    A = np.vstack([G, J])
    rhs = np.concatenate([np.asarray(reference_accelerations, float) - c, aref + omitted])
    a_r = np.linalg.lstsq(A, rhs, rcond=None)[0]
    f_r = np.linalg.lstsq(J.T, M @ a_r - smooth, rcond=None)[0]
    K = np.block([[M, -J.T], [J, np.diag(R)]])
    sol = np.linalg.solve(K, np.concatenate([np.zeros(nv), -R * f_r - omitted]))
    return SoftPrediction(a_r + sol[:nv], f_r + sol[nv : nv + ne], np.asarray(R, float))
