"""What an MJCF file may hold for the reference, and its initial state's distance from the
constraint manifold.

The reference models rigid bodies, joints, gravity, joint armature, damping and (hinge/slide)
springs, and the equality constraints connect, weld and joint. Everything else that changes
the dynamics is refused here, once, with every offending element named and the way out:
tendons that act (stiffness, damping, friction, limits, armature), actuators that can push,
flex bodies, contacts between bodies that could touch (contype/conaffinity, explicit pairs),
joint limits, dry friction, fluid forces, gravity compensation, nonlinear springs and dampers,
plugins, and equality types other than the three. Elements that cannot act are accepted and
reported as notes (an inactive equality, a disabled feature).
"""

from __future__ import annotations

import mujoco
import numpy as np

from reference.errors import OffManifoldError, UnsupportedModelError

OBJ = mujoco.mjtObj
EQ = mujoco.mjtEq


def disabled(m, flag: str) -> bool:
    bit = getattr(mujoco.mjtDisableBit, flag, None)
    return bit is not None and bool(m.opt.disableflags & int(bit))


def _n(m, obj, i, prefix):
    n = mujoco.mj_id2name(m, obj, i)
    return f"{prefix} {n!r}" if n else f"{prefix} #{i}"


def _contact_pairs(m) -> list[str]:
    """Geom pairs MuJoCo's broad phase would test (contype/conaffinity, weld and parent
    filters, <exclude>), by name; empty when contacts are disabled."""
    if disabled(m, "mjDSBL_CONTACT") or disabled(m, "mjDSBL_CONSTRAINT"):
        return []
    excluded = {int(s) for s in m.exclude_signature[: m.nexclude]}
    weld, parent = m.body_weldid, m.body_parentid
    out = []
    for g1 in range(m.ngeom):
        for g2 in range(g1 + 1, m.ngeom):
            c1, a1, c2, a2 = (
                m.geom_contype[g1],
                m.geom_conaffinity[g1],
                m.geom_contype[g2],
                m.geom_conaffinity[g2],
            )
            if not ((c1 & a2) or (c2 & a1)):
                continue
            b1, b2 = m.geom_bodyid[g1], m.geom_bodyid[g2]
            w1, w2 = weld[b1], weld[b2]
            if w1 == w2:
                continue  # same rigid group (or both static)
            if (
                not disabled(m, "mjDSBL_FILTERPARENT")
                and w1
                and w2
                and (w1 == weld[parent[w2]] or w2 == weld[parent[w1]])
            ):
                continue
            lo, hi = min(b1, b2), max(b1, b2)
            if (lo << 16) + hi in excluded or (hi << 16) + lo in excluded:  # MuJoCo's signature
                continue
            out.append(f"{_n(m, OBJ.mjOBJ_GEOM, g1, 'geom')} / {_n(m, OBJ.mjOBJ_GEOM, g2, 'geom')}")
    return out


def _actuator_problems(m) -> list[str]:
    if m.nu == 0 or disabled(m, "mjDSBL_ACTUATION"):
        return []
    out = []
    for a in range(m.nu):
        lo, hi = m.actuator_ctrlrange[a]
        inert = (
            m.actuator_ctrllimited[a] and lo == 0 and hi == 0 and not np.any(m.actuator_biasprm[a])
        )
        if not inert:
            out.append(
                f"{_n(m, OBJ.mjOBJ_ACTUATOR, a, 'actuator')} can apply a force "
                f'(remove it, set ctrlrange="0 0" with no bias, or disable actuation: '
                f'<option><flag actuation="disable"/></option>)'
            )
    return out


def _tendon_problems(m) -> list[str]:
    out = []
    for t in range(m.ntendon):
        acts = []
        if m.tendon_stiffness[t] or np.any(m.tendon_stiffnesspoly[t]):
            acts.append("stiffness")
        if m.tendon_damping[t] or np.any(m.tendon_dampingpoly[t]):
            acts.append("damping")
        if m.tendon_frictionloss[t]:
            acts.append("frictionloss")
        if m.tendon_limited[t]:
            acts.append("limits")
        if m.tendon_armature[t]:
            acts.append("armature")
        if acts:
            out.append(
                f"{_n(m, OBJ.mjOBJ_TENDON, t, 'tendon')} acts on the bodies "
                f"({', '.join(acts)}); the reference has no tendons: remove them"
            )
    return out


def _joint_problems(m) -> list[str]:
    out = []
    limits = not (disabled(m, "mjDSBL_LIMIT") or disabled(m, "mjDSBL_CONSTRAINT"))
    friction = not (disabled(m, "mjDSBL_FRICTIONLOSS") or disabled(m, "mjDSBL_CONSTRAINT"))
    for j in range(m.njnt):
        name = _n(m, OBJ.mjOBJ_JOINT, j, "joint")
        if limits and m.jnt_limited[j]:
            out.append(
                f"{name} has a limit (range); the reference has no unilateral "
                f'constraints: set limited="false" or disable limits'
            )
        if np.any(m.jnt_stiffnesspoly[j]):
            out.append(f"{name} has a nonlinear spring (stiffnesspoly): use stiffness only")
        if m.jnt_stiffness[j] and m.jnt_type[j] in (
            int(mujoco.mjtJoint.mjJNT_BALL),
            int(mujoco.mjtJoint.mjJNT_FREE),
        ):
            out.append(
                f'{name}: springs on ball and free joints are not modelled: set stiffness="0"'
            )
        for k in range(m.jnt_dofadr[j], m.jnt_dofadr[j] + _ndof(m.jnt_type[j])):
            if friction and m.dof_frictionloss[k]:
                out.append(f"{name} has dry friction (frictionloss): set it to 0")
                break
            if np.any(m.dof_dampingpoly[k]):
                out.append(f"{name} has a nonlinear damper (dampingpoly): use damping only")
                break
    return out


def _ndof(t) -> int:
    return {int(mujoco.mjtJoint.mjJNT_FREE): 6, int(mujoco.mjtJoint.mjJNT_BALL): 3}.get(t, 1)


def check_supported(m, where: str) -> tuple[str, ...]:
    """Raise UnsupportedModelError naming every element the reference cannot represent;
    return notes on elements accepted because they cannot act."""
    problems, notes = [], []
    problems += _tendon_problems(m)
    problems += _actuator_problems(m)
    problems += _joint_problems(m)
    if m.nflex:
        problems.append(
            f"{m.nflex} flex object(s): deformable bodies are not modelled; remove them"
        )
    if m.nplugin:
        problems.append(f"{m.nplugin} plugin(s): their forces are unknown to the reference")
    if m.opt.density or m.opt.viscosity:
        problems.append("fluid forces (option density/viscosity): set both to 0")
    for b in range(m.nbody):
        if m.body_gravcomp[b]:
            problems.append(f"{_n(m, OBJ.mjOBJ_BODY, b, 'body')} has gravcomp: set it to 0")
    if m.npair and not disabled(m, "mjDSBL_CONTACT"):
        problems.append(
            f"{m.npair} explicit contact pair(s) (<contact><pair>): remove them or disable contacts"
        )
    pairs = _contact_pairs(m)
    if pairs:
        more = f" and {len(pairs) - 5} more" if len(pairs) > 5 else ""
        problems.append(
            f"contacts possible between {'; '.join(pairs[:5])}{more}: give the "
            f'geoms contype="0" conaffinity="0", add <exclude>, or disable '
            f'contacts (<option><flag contact="disable"/></option>)'
        )
    eq_on = not (disabled(m, "mjDSBL_EQUALITY") or disabled(m, "mjDSBL_CONSTRAINT"))
    for e in range(m.neq):
        name = _n(m, OBJ.mjOBJ_EQUALITY, e, "equality")
        if not m.eq_active0[e] or not eq_on:
            notes.append(f"{name} is inactive and left out")
        elif m.eq_type[e] not in (int(EQ.mjEQ_CONNECT), int(EQ.mjEQ_WELD), int(EQ.mjEQ_JOINT)):
            kind = mujoco.mjtEq(int(m.eq_type[e])).name.removeprefix("mjEQ_").lower()
            problems.append(
                f"{name} is a {kind} equality; the reference supports connect, "
                f"weld and joint: remove it"
            )
    if problems:
        raise UnsupportedModelError(
            f"{where}: not representable in the reference: " + "; ".join(problems)
        )
    return tuple(notes)


# ---- the constraint manifold, with MuJoCo's own rows --------------------------------------------
def dense_efc_J(m, d) -> np.ndarray:
    """efc_J as a dense (nefc, nv) array, from dense or sparse (CSR) storage."""
    J = np.zeros((d.nefc, m.nv))
    if not mujoco.mj_isSparse(m):
        J[:] = np.asarray(d.efc_J[: d.nefc * m.nv]).reshape(d.nefc, m.nv)
        return J
    for i in range(d.nefc):
        adr, nnz = d.efc_J_rowadr[i], d.efc_J_rownnz[i]
        J[i, d.efc_J_colind[adr : adr + nnz]] = d.efc_J[adr : adr + nnz]
    return J


def _equality_rows(m, d):
    mujoco.mj_forward(m, d)
    eq = np.flatnonzero(np.asarray(d.efc_type[: d.nefc]) == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
    return np.asarray(d.efc_pos[: d.nefc])[eq], dense_efc_J(m, d)[eq]


def _quat_norm_error(m, qpos) -> float:
    worst = 0.0
    for j in range(m.njnt):
        t, a = m.jnt_type[j], m.jnt_qposadr[j]
        if t == int(mujoco.mjtJoint.mjJNT_FREE):
            a += 3
        if t in (int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_BALL)):
            worst = max(worst, abs(float(np.linalg.norm(qpos[a : a + 4])) - 1.0))
    return worst


def violation(m, qpos, qvel=None) -> float:
    """Largest equality-row residual (MuJoCo's efc_pos), quaternion norm error at qpos, or
    velocity-row residual J qvel."""
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    pos, J = _equality_rows(m, d)
    vel = J @ np.asarray(qvel, float) if qvel is not None and J.shape[0] else np.zeros(0)
    return max(
        float(np.max(np.abs(pos), initial=0.0)),
        _quat_norm_error(m, qpos),
        float(np.max(np.abs(vel), initial=0.0)),
    )


def project_state(m, qpos, qvel, tol: float = 1e-14, max_iter: int = 50):
    """Closest consistent state: quaternions normalized, Gauss-Newton on MuJoCo's equality
    rows (minimum-norm steps through mj_integratePos), then qvel <- qvel - J^+ J qvel."""
    d = mujoco.MjData(m)
    q = np.array(qpos, float)
    mujoco.mj_normalizeQuat(m, q)
    for _ in range(max_iter):
        d.qpos[:] = q
        pos, J = _equality_rows(m, d)
        if not pos.size or np.max(np.abs(pos)) <= tol * (1 + np.max(np.abs(q))):
            break
        dv, *_ = np.linalg.lstsq(J, -pos, rcond=None)
        mujoco.mj_integratePos(m, q, dv, 1.0)
    else:
        raise OffManifoldError(
            f"projection onto the equality constraints did not converge in {max_iter} steps "
            f"(residual {np.max(np.abs(pos)):.2e}): the constraints may have no solution near "
            f"this state"
        )
    v = np.array(qvel, float)
    d.qpos[:] = q
    _pos, J = _equality_rows(m, d)
    if J.shape[0]:
        dv, *_ = np.linalg.lstsq(J, -(J @ v), rcond=None)
        v = v + dv
    return q, v
