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

from ..base import EngineUnsupported


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
        y = x ** power / mid ** (power - 1.0)
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
                "soft prediction: only connect rows have a documented diagonal approximation "
                f"here; equality {e} is of type {int(m.eq_type[e])}")
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
    return SoftPrediction(a_r + sol[:nv], f_r + sol[nv:nv + ne], np.asarray(R, float))


def predict_for(em, q, u, reference_accelerations) -> tuple[np.ndarray, np.ndarray]:
    """Predicted soft (accelerations, multipliers) of a built MuJoCo model at a reference
    state, in reference coordinates. Reads only model quantities at the state (M, J, smooth
    forces, aref, solimp, invweights) after mj_forward, never its constraint solution."""
    from .machinery import dense_efc_J, full_M  # dense views of MuJoCo's data

    m, d = em.m, em.d
    qe, ve = em.to_engine_state(q, u)
    em._set(qe, ve)
    mujoco.mj_forward(m, d)
    qe, ve = d.qpos.copy(), d.qvel.copy()
    if d.nefc == 0:
        raise EngineUnsupported("no equality rows: MuJoCo's answer is not soft here")
    J, M = dense_efc_J(m, d), full_M(m, d)
    G = em._affine_gain(lambda z: em._acc_to_reference(qe, ve, z), np.zeros(m.nv))
    c = np.asarray(em._acc_to_reference(qe, ve, np.zeros(m.nv)), float)
    soft = predict(M, J, d.qfrc_smooth.copy(), d.efc_aref[:d.nefc].copy(), documented_R(m, d),
                   G, c, reference_accelerations)
    acc = np.asarray(em._acc_to_reference(qe, ve, soft.engine_accelerations), float)
    lam = em._multipliers(qe, ve, soft.engine_accelerations, soft.engine_forces)
    return acc, (None if lam is None else np.asarray(lam, float))


def agreement(n_states: int = 200, models=None) -> list[dict]:
    """MuJoCo's raw soft answer against predict_for over the run's consistent states (the
    initial state and n_states - 1 seeded random ones, crosscheck.sampling) of every MuJoCo
    model with soft rows: the worst miss max |raw - predicted| (scaled as compare.scaled_error),
    the predicted soft effect's range and the judged ratio (compare.soft_prediction), of the
    accelerations and (lam_*) the multipliers."""
    from reference.models import get
    from reference.numeric import NumericModel

    from ...compare import scaled_error, soft_prediction
    from ...sampling import consistent_states
    from .adapter import MujocoAdapter

    ad, rows = MujocoAdapter(), []
    for name in models or ad.models():
        if name in ad.unsupported():
            continue
        nm = NumericModel(get(name))
        for variant in ad.variants(name):
            em = ad.build(name, None, variant)
            if not em.soft_constraints:
                continue
            w: dict = {"model": name, "variant": variant}
            for q, u in consistent_states(nm, n_states):
                ref, fw = nm.forward(q, u), em.forward(q, u)
                acc, lam = em.predict_soft(q, u, ref.accelerations)
                pairs = [("", fw.accelerations, acc, ref.accelerations)]
                if fw.multipliers is not None and lam is not None:
                    pairs.append(("lam_", fw.multipliers, lam, ref.multipliers))
                for key, raw, p, r in pairs:
                    pred = scaled_error(p, r)
                    for k, v in (("miss", scaled_error(raw, p)), ("pred_max", pred),
                                 ("ratio", soft_prediction(raw, r, p - r)[0])):
                        w[key + k] = max(w.get(key + k, 0.0), v)
                    w[key + "pred_min"] = min(w.get(key + "pred_min", np.inf), pred)
            rows.append(w)
    return rows


if __name__ == "__main__":
    import sys

    n = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    keys = ("miss", "ratio", "pred_min", "pred_max")
    print(f"{'model':20s} {'variant':8s} " + " ".join(f"{k:>9s}" for k in keys)
          + " " + " ".join(f"{'lam_' + k:>12s}" for k in keys))
    for r in agreement(n, sys.argv[2:] or None):
        print(f"{r['model']:20s} {str(r['variant'] or '-'):8s} "
              + " ".join(f"{r[k]:9.2e}" for k in keys) + " "
              + " ".join(f"{r.get('lam_' + k, float('nan')):12.2e}" for k in keys))
