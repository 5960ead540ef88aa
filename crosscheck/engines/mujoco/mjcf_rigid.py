"""MuJoCo's rigid answer for any MJCF file: the exact KKT solve from MuJoCo's own quantities.

MuJoCo's equality constraints are soft, so mj_forward's qacc differs from the rigid motion by
its impedance. The rigid answer is recovered from MuJoCo's own smooth dynamics, without its
constraint solver: after mj_forward,

    [ M  -J^T ] [qacc  ]   [qfrc_smooth]
    [ J   0   ] [lambda] = [-Jdot v    ]

with M from mj_fullM (armature included), qfrc_smooth = passive - bias + applied + actuator
(MuJoCo's own sum), J and Jdot v of every active equality from mj_jac and mj_jacDot at the
anchors MuJoCo itself uses (engine_core_constraint.c): connect p1 - p2, weld p1 - p2 and
omega1 - omega2 (the weld's quaternion rows span the same space on the manifold), joint
q1 - poly(q2) with Jdot v = -poly''(q2) v2^2. Dependent rows are solved as in
reference.numeric.redundant (unique qacc, minimum-norm lambda).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from crosscheck.engines.mujoco.soft_recovery import joint_equality_row
from reference.mjcf.checks import disabled
from reference.numeric import redundant

EQ = mujoco.mjtEq


@dataclass
class RigidForward:
    qacc: np.ndarray
    multipliers: np.ndarray
    rank: int
    J: np.ndarray
    qacc_soft: np.ndarray  # mj_forward's own (soft) answer, for comparison


def _point(m, d, e: int, side: int, weld: bool):
    """Body id, world point and (for welds) nothing else, as MuJoCo's equality code does."""
    obj = (m.eq_obj1id, m.eq_obj2id)[side][e]
    if m.eq_objtype[e] == mujoco.mjtObj.mjOBJ_SITE:
        return int(m.site_bodyid[obj]), np.array(d.site_xpos[obj])
    k = (1 - side) if weld else side
    anchor = m.eq_data[e, 3 * k : 3 * k + 3]
    return int(obj), d.xpos[obj] + d.xmat[obj].reshape(3, 3) @ anchor


def _body_rows(m, d, body: int, point, rot: bool):
    jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    dp, dr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    if body:
        mujoco.mj_jac(m, d, jp, jr, np.asarray(point, float), body)
        mujoco.mj_jacDot(m, d, dp, dr, np.asarray(point, float), body)
    J = np.vstack([jp, jr]) if rot else jp
    Jd = np.vstack([dp, dr]) if rot else dp
    return J, Jd @ d.qvel


def equality_rows(m, d):
    """J (rows, nv) and Jdot v of the active equalities at the state in d (after mj_forward)."""
    Js, jdv = [], []
    if disabled(m, "mjDSBL_EQUALITY") or disabled(m, "mjDSBL_CONSTRAINT"):
        return np.zeros((0, m.nv)), np.zeros(0)
    for e in range(m.neq):
        if not d.eq_active[e]:
            continue
        t = m.eq_type[e]
        if t in (int(EQ.mjEQ_CONNECT), int(EQ.mjEQ_WELD)):
            weld = t == int(EQ.mjEQ_WELD)
            rot = weld and m.eq_data[e, 10] != 0
            b1, p1 = _point(m, d, e, 0, weld)
            b2, p2 = _point(m, d, e, 1, weld)
            J1, a1 = _body_rows(m, d, b1, p1, rot)
            J2, a2 = _body_rows(m, d, b2, p2, rot)
            Js.append(J1 - J2)
            jdv.append(a1 - a2)
        elif t == int(EQ.mjEQ_JOINT):
            row, acc = joint_equality_row(m, d, e)
            Js.append(row[None, :])
            jdv.append(np.array([acc]))
        else:
            raise ValueError(f"equality #{e}: type {t} has no rigid rows here")
    if not Js:
        return np.zeros((0, m.nv)), np.zeros(0)
    return np.vstack(Js), np.concatenate(jdv)


def rigid_forward(m, qpos, qvel, *, applied=None) -> RigidForward:
    """MuJoCo's rigid accelerations and minimum-norm multipliers at (qpos, qvel)."""
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    d.qvel[:] = qvel
    if applied is not None:
        d.qfrc_applied[:] = applied
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    J, jdv = equality_rows(m, d)
    rank, _s = redundant.numerical_rank(J)
    qacc, lam, _piv, rank = redundant.solve(
        M, np.array(d.qfrc_smooth), J, -jdv, rank_expected=rank, augment=False, where="MuJoCo"
    )
    return RigidForward(qacc, lam, rank, J, np.array(d.qacc))


# ---- agreement of the reference with MuJoCo's rigid answer --------------------------------------
def sample_states(imp, count: int, seed: int = 7):
    """The import's initial state in MuJoCo's (qpos, qvel), then `count` seeded random states
    (qpos0 moved by N(0, 0.5^2) per dof, qvel ~ N(0, 1)) projected onto the manifold."""
    from reference.mjcf.checks import project_state
    from reference.mjcf.loader import qvel_from_rates

    m = imp.mj
    q0 = np.array(imp.model.initial_q)
    yield q0, qvel_from_rates(imp.joints, q0, imp.model.initial_u, m.nv)
    rng = np.random.default_rng(seed)
    for _ in range(count):
        q = np.array(m.qpos0, float)
        mujoco.mj_integratePos(m, q, 0.5 * rng.standard_normal(m.nv), 1.0)
        yield project_state(m, q, rng.standard_normal(m.nv))


def agreement(imp, nm, count: int = 4, seed: int = 7) -> list[dict]:
    """Per state: the reference's u' mapped to qacc against MuJoCo's rigid qacc (relative to
    max(1, |qacc|)), MuJoCo's soft qacc against its rigid one, and both ranks."""
    from reference.mjcf.loader import qvel_from_rates, rates_from_qvel

    rows = []
    for qpos, qvel in sample_states(imp, count, seed):
        rigid = rigid_forward(imp.mj, qpos, qvel)
        u = rates_from_qvel(imp.joints, qpos, qvel)
        nm.check_consistent(qpos, u)
        fw = nm.forward(qpos, u)
        qacc = qvel_from_rates(imp.joints, qpos, fw.accelerations, imp.mj.nv)
        scale = max(1.0, float(np.max(np.abs(rigid.qacc), initial=0.0)))
        rows.append(
            {
                "error": float(np.max(np.abs(qacc - rigid.qacc), initial=0.0)) / scale,
                "soft_vs_rigid": float(np.max(np.abs(rigid.qacc_soft - rigid.qacc), initial=0.0))
                / scale,
                "rank": fw.rank,
                "mujoco_rank": rigid.rank,
            }
        )
    return rows


def main(argv=None) -> int:
    """python -m crosscheck.engines.mujoco.mjcf_rigid FILE [--formulations kane,lagrange]
    [--states N]"""
    import argparse
    import time

    from reference.mjcf.loader import import_mjcf
    from reference.numeric.model import NumericModel

    ap = argparse.ArgumentParser(
        prog="python -m crosscheck.engines.mujoco.mjcf_rigid",
        description="reference vs MuJoCo's rigid answer on an MJCF file",
    )
    ap.add_argument("file")
    ap.add_argument("--formulations", default="kane")
    ap.add_argument("--states", type=int, default=4)
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args(argv)
    imp = import_mjcf(args.file)
    for form in args.formulations.split(","):
        t0 = time.perf_counter()
        nm = NumericModel(imp.model, form)
        took = time.perf_counter() - t0
        rows = agreement(imp, nm, args.states, args.seed)
        for i, r in enumerate(rows):
            print(
                f"{form} state {i}: error {r['error']:.1e}  soft-vs-rigid "
                f"{r['soft_vs_rigid']:.1e}  rank {r['rank']} (MuJoCo {r['mujoco_rank']})"
            )
        print(
            f"{form}: worst {max(r['error'] for r in rows):.1e}  (derivation + load {took:.1f} s)"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
