"""MuJoCo's soft answer at a state, read against the rigid problem: the rigid answer recovered
from MuJoCo's own soft solve (de-regularized), the error the documented impedance predicts and
its bounds, independent residuals, and the soft answer predicted from the reference's rigid one
(soft_prediction.py). The conventions are in the package's adapter docstring.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

from crosscheck.checks.tolerances import scaled_error
from crosscheck.engines.base import EngineUnsupported
from crosscheck.engines.mujoco.soft_prediction import documented_R, predict


def dense_efc_J(m, d) -> np.ndarray:
    """efc_J as a dense (nefc, nv) array, from dense or CSR storage (mj_isSparse)."""
    nefc, nv = d.nefc, m.nv
    if nefc == 0:
        return np.zeros((0, nv))
    if mujoco.mj_isSparse(m):
        J = np.zeros((nefc, nv))
        for i in range(nefc):
            adr, nnz = d.efc_J_rowadr[i], d.efc_J_rownnz[i]
            J[i, d.efc_J_colind[adr : adr + nnz]] = d.efc_J[adr : adr + nnz]
        return J
    return np.array(d.efc_J[: nefc * nv]).reshape(nefc, nv)


def full_M(m, d) -> np.ndarray:
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    return M


def kkt_lstsq(M, J, rhs_c, equilibrate: bool = False):
    """Least-squares solution (y, delta) of [[M, -J^T], [J, 0]] [y; delta] = [0; rhs_c].

    equilibrate: solve with every row of J scaled to unit norm (D J, D rhs_c, then delta = D
    delta'), its zero rows left out (their delta is 0): the same solution, but a weld with a
    tiny torquescale (rows 1e-3 of the others) leaves singular values of 1e-9 in the plain
    matrix, where lstsq loses 1e-7 of the answer (MuJoCo's weld.xml), and one with torquescale
    0 has zero rows."""
    if equilibrate:
        rhs_c = np.asarray(rhs_c, float)
        norms = np.linalg.norm(J, axis=1)
        keep = norms > 0
        scale = 1.0 / norms[keep]
        shape = (-1,) + (1,) * (rhs_c.ndim - 1)
        y, sub, rank = kkt_lstsq(M, J[keep] * scale[:, None], rhs_c[keep] * scale.reshape(shape))
        delta = np.zeros((J.shape[0], *rhs_c.shape[1:]))
        delta[keep] = sub * scale.reshape(shape)
        return y, delta, rank
    nv, ne = M.shape[0], J.shape[0]
    K = np.zeros((nv + ne, nv + ne))
    K[:nv, :nv] = M
    K[:nv, nv:] = -J.T
    K[nv:, :nv] = J
    rhs_c = np.asarray(rhs_c, float)
    rhs = np.concatenate([np.zeros((nv, *rhs_c.shape[1:])), rhs_c])
    sol, _res, rank, _sv = np.linalg.lstsq(K, rhs, rcond=None)
    return sol[:nv], sol[nv:], int(rank)


def joint_equality_row(m, d, e: int) -> tuple[np.ndarray, float]:
    """J (nv,) and J-dot v of joint equality e, q1 - qpos0_1 - poly(q2 - qpos0_2), at the state
    in d (engine_core_constraint.c: both joints measured from qpos0, `ref` included there):
    J-dot v = -poly''(x) v2^2."""
    row = np.zeros(m.nv)
    row[m.jnt_dofadr[m.eq_obj1id[e]]] = 1.0
    j2 = int(m.eq_obj2id[e])
    if j2 < 0:
        return row, 0.0
    c = m.eq_data[e, :5]
    a2 = m.jnt_qposadr[j2]
    x = d.qpos[a2] - m.qpos0[a2]
    v2 = d.qvel[m.jnt_dofadr[j2]]
    row[m.jnt_dofadr[j2]] -= c[1] + 2 * c[2] * x + 3 * c[3] * x**2 + 4 * c[4] * x**3
    return row, float(-(2 * c[2] + 6 * c[3] * x + 12 * c[4] * x**2) * v2**2)


def omitted_jdot_v(m, d) -> np.ndarray:
    """The part of the rigid row acceleration -J-dot v that MuJoCo's aref leaves out, per efc
    row: on a joint equality row all of it, poly''(x) v2^2 (its mj_Jdotv subtracts J-dot v on
    connect and weld rows only), 0 on every other row. Where it is not 0, MuJoCo's model is
    not the rigid one: its soft solve aims at J qacc = -(stabilization) there."""
    out = np.zeros(d.nefc)
    for i in range(d.nefc):
        if d.efc_type[i] != mujoco.mjtConstraint.mjCNSTR_EQUALITY:
            continue
        e = int(d.efc_id[i])
        if m.eq_type[e] == mujoco.mjtEq.mjEQ_JOINT:
            out[i] = -joint_equality_row(m, d, e)[1]
    return out


class _Rows(NamedTuple):
    """MuJoCo's equality rows at the state in d, after mj_forward."""

    f: np.ndarray  # efc_force, the soft solve's forces
    J: np.ndarray
    M: np.ndarray
    R: np.ndarray  # efc_R, the regularization MuJoCo used
    diagA: np.ndarray  # efc_diagA, its approximation of diag(J M^-1 J^T)
    imp: np.ndarray  # the impedance d of every row
    aref: np.ndarray


def _rows(m, d) -> _Rows:
    nefc = d.nefc
    return _Rows(
        d.efc_force[:nefc].copy(),
        dense_efc_J(m, d),
        full_M(m, d),
        d.efc_R[:nefc].copy(),
        d.efc_diagA[:nefc].copy(),
        d.efc_KBIP[:nefc, 2].copy(),
        d.efc_aref[:nefc].copy(),
    )


def _predicted_error(em, qe, ve, qacc, rows: _Rows, omitted):
    """The reference-coordinate rigid answer predicted from the impedance alone,
    R_pred = (1 - d)/d diagA, and aref's omitted J-dot v: (eps, R_pred, accelerations,
    multipliers)."""
    eps = (1.0 - rows.imp) / rows.imp
    R_pred = eps * rows.diagA
    y_p, delta_p, _ = kkt_lstsq(rows.M, rows.J, R_pred * rows.f + omitted, em.equilibrate_rows)
    acc_p = em._acc_to_reference(qe, ve, qacc + y_p)
    lam_p = em._multipliers(qe, ve, qacc + y_p, rows.f + delta_p)
    return eps, R_pred, acc_p, lam_p


def _error_bounds(em, qe, ve, qacc, rows: _Rows, eps) -> tuple[float, float, float]:
    """Rigorous bounds given f: delta = A^-1 R f = eps A^-1 D f (one d for all rows), so
    |G_lam delta|_inf <= eps |G_lam A^-1 D|_inf |f|_inf and likewise for the accelerations
    with M^-1 J^T A^-1 D; G_* are the (affine) maps' linear parts, A^-1 D from the KKT.
    Returns the (relative force, multiplier, acceleration) bounds."""
    f = rows.f
    Y, X, _ = kkt_lstsq(rows.M, rows.J, np.diag(rows.diagA), em.equilibrate_rows)
    G_lam = em._affine_gain(lambda z: em._multipliers(qe, ve, qacc, z), f)
    G_acc = em._affine_gain(lambda z: em._acc_to_reference(qe, ve, z), qacc)
    f_inf = float(np.max(np.abs(f)))
    e_max = float(np.max(eps))
    bound_f = e_max * float(np.linalg.norm(X, np.inf))
    bound_lam = e_max * float(np.linalg.norm(G_lam @ X, np.inf)) * f_inf
    bound_acc = e_max * float(np.linalg.norm(G_acc @ Y, np.inf)) * f_inf
    return bound_f, bound_lam, bound_acc


def _direct_kkt(em, qe, ve, rows: _Rows, smooth, target, raw) -> None:
    """The rigid KKT assembled directly from MuJoCo's matrices (M, J, qfrc_smooth, and aref
    with its omitted J-dot v: target), independent of the soft solve: a diagnostic of the
    recovery's precision floor."""
    M, J, nv, nefc = rows.M, rows.J, rows.M.shape[0], rows.J.shape[0]
    sol = np.linalg.lstsq(
        np.block([[M, -J.T], [J, np.zeros((nefc, nefc))]]),
        np.concatenate([smooth, target]),
        rcond=None,
    )[0]
    raw["kkt_accelerations"] = em._acc_to_reference(qe, ve, sol[:nv])
    raw["kkt_multipliers"] = em._multipliers(qe, ve, sol[:nv], sol[nv:])


def _stabilization(em, d) -> np.ndarray | float:
    """-(MuJoCo's stabilization terms of aref), B efc_vel + K imp efc_pos, where the engine
    model removes them from the rigid target (em.remove_stabilization), else 0.

    At a consistent state efc_pos and efc_vel are round-off (1e-16), but aref multiplies them
    by solref's stiffness K = 1/(dmax tc dr)^2: MuJoCo's ten_armature_1_equiv.xml (solref
    0.0001) has K = 1e8, which turns that round-off into 1e-9 of the recovered answer (2.2e-9
    against the reference, over the 1e-9 bound); the rigid target is aref without them."""
    if not em.remove_stabilization:
        return 0.0
    n = d.nefc
    K, B, imp = (np.asarray(d.efc_KBIP[:n, k]) for k in (0, 1, 2))
    return B * d.efc_vel[:n] + K * imp * (d.efc_pos[:n] - d.efc_margin[:n])


def _omission(em, qe, ve, rows: _Rows, qacc_r, acc_r, omitted, raw) -> None:
    """MuJoCo's omitted J-dot v per row, and its effect: the scaled_error of the rigid answer
    of MuJoCo's own model (aiming at aref without it) against the rigid answer."""
    raw["aref_omitted_jdot_v"] = omitted
    raw["aref_omission_effect"] = 0.0
    if np.any(omitted):
        y, _delta, _ = kkt_lstsq(rows.M, rows.J, -omitted, em.equilibrate_rows)
        acc_m = em._acc_to_reference(qe, ve, qacc_r + y)
        raw["aref_omission_effect"] = scaled_error(acc_m, acc_r)


def soft_recovery(em, qe, ve, qacc, acc, raw) -> np.ndarray:
    """The mapped multipliers of MuJoCo's soft answer at the state in em.d; fills raw with the
    rigid answer recovered from it, the impedance's predicted error and its bounds, and
    independent residuals (see the package's adapter docstring)."""
    d = em.d
    rows = _rows(em.m, d)
    f, J, M, R, aref = rows.f, rows.J, rows.M, rows.R, rows.aref
    lam = em._multipliers(qe, ve, qacc, f)
    # the rigid target: aref, less its stabilization terms where the model removes them, with
    # the J-dot v MuJoCo leaves out of a joint equality row's aref (omitted_jdot_v)
    omitted = omitted_jdot_v(em.m, d)
    stab = _stabilization(em, d)
    # de-regularized answer: f_rigid = f + A^-1 R f, qacc_rigid = qacc + M^-1 J^T (A^-1 R f)
    y, delta, rank = kkt_lstsq(M, J, R * f + stab + omitted, em.equilibrate_rows)
    qacc_r, f_r = qacc + y, f + delta
    acc_r = em._acc_to_reference(qe, ve, qacc_r)
    lam_r = em._multipliers(qe, ve, qacc_r, f_r)
    eps, R_pred, acc_p, lam_p = _predicted_error(em, qe, ve, qacc, rows, omitted)
    bound_f, bound_lam, bound_acc = _error_bounds(em, qe, ve, qacc, rows, eps)
    _direct_kkt(em, qe, ve, rows, d.qfrc_smooth, aref + omitted, raw)
    _omission(em, qe, ve, rows, qacc_r, acc_r, omitted, raw)
    jdv = em._jdot_v()
    raw.update(
        {
            "engine_forces": f,
            "impedance": rows.imp,
            "soft_eps": float(np.max(eps)),
            "efc_R": R,
            "efc_diagA": rows.diagA,
            "R_model_rel_mismatch": float(
                np.max(np.abs(R - R_pred) / np.maximum(np.abs(R), 1e-300))
            ),
            "predicted_acceleration_error": acc - acc_p,  # raw - rigid, predicted from d
            "predicted_multiplier_error": lam - lam_p,
            "predicted_rel_force_bound": bound_f,
            "raw_multiplier_error_bound": bound_lam,
            "raw_acceleration_error_bound": bound_acc,
            "rigid_accelerations": acc_r,
            "rigid_multipliers": lam_r,
            "rigid_engine_accelerations": qacc_r,
            "rigid_engine_forces": f_r,
            "kkt_rank": rank,
            "efc_pos_max": float(np.max(np.abs(d.efc_pos[: d.nefc]))),
            "efc_vel_max": float(np.max(np.abs(J @ ve))),
            # soft model: J qacc - aref = -R f (MuJoCo's own solve, checked on its output)
            "soft_model_residual": float(np.max(np.abs(J @ qacc - aref + R * f))),
            # the recovered rigid answer satisfies J qacc_rigid = aref (less its stabilization
            # terms where the model removes them, with its omitted J-dot v) ...
            "rigid_residual": float(np.max(np.abs(J @ qacc_r - aref - stab - omitted))),
            # ... and M qacc_rigid = qfrc_smooth + J^T f_rigid
            "rigid_dynamics_residual": float(
                np.max(np.abs(M @ qacc_r - d.qfrc_smooth - J.T @ f_r))
            ),
        }
    )
    if jdv is not None:
        # at a consistent state MuJoCo's aref must be -J-dot v (connect rows)
        raw["aref_plus_jdot_v"] = float(np.max(np.abs(aref + jdv)))
    return lam


def predict_soft(em, q, u, reference_accelerations):
    """MuJoCo's raw soft (accelerations, multipliers) predicted from the reference's
    accelerations and the documented solref/solimp impedance (soft_prediction.py), in
    reference coordinates. Reads only model quantities at the state (M, J, smooth forces,
    aref, solimp, invweights) after mj_forward, never its constraint solution; MuJoCo's
    model, so with the J-dot v its aref leaves out of joint equality rows left out."""
    m, d = em.m, em.d
    em._set(*em.to_engine_state(q, u))
    mujoco.mj_forward(m, d)
    qe, ve = d.qpos.copy(), d.qvel.copy()
    if d.nefc == 0:
        raise EngineUnsupported("no equality rows: MuJoCo's answer is not soft here")
    G = em._affine_gain(lambda z: em._acc_to_reference(qe, ve, z), np.zeros(m.nv))
    c = np.asarray(em._acc_to_reference(qe, ve, np.zeros(m.nv)), float)
    soft = predict(
        full_M(m, d),
        dense_efc_J(m, d),
        d.qfrc_smooth.copy(),
        d.efc_aref[: d.nefc].copy(),
        documented_R(m, d),
        G,
        c,
        reference_accelerations,
        omitted_jdot_v(m, d),
    )
    acc = np.asarray(em._acc_to_reference(qe, ve, soft.engine_accelerations), float)
    lam = em._multipliers(qe, ve, soft.engine_accelerations, soft.engine_forces)
    return acc, (None if lam is None else np.asarray(lam, float))
