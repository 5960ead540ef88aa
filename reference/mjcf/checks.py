"""What an MJCF file may hold for the reference, and its initial state's distance from the
constraint manifold.

The reference models rigid bodies, joints, gravity, joint armature, damping and (hinge/slide)
springs, the equality constraints connect, weld and joint, and actuators on hinges and slides at
a stated control (reference.mjcf.actuators). Contacts, joint and tendon limits and force clamps
act at some states only: they are checked where they do not act (reference.mjcf.unilateral).
What acts at every state and the reference cannot represent is refused here, once, in one line
that names every offending element, grouped by problem, and the way out: tendons that act
(stiffness, damping, friction, armature), actuators it cannot express, flex bodies, dry
friction, fluid forces, gravity compensation, nonlinear springs and dampers, springs on ball
and free joints, plugins, and equality types other than the three. Elements that cannot act are
accepted and reported as notes (an inactive equality, a disabled feature).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from reference.errors import OffManifoldError, UnsupportedModelError

OBJ = mujoco.mjtObj
EQ = mujoco.mjtEq
# names listed in a refusal's group before "and N more": the line stays readable
LISTED = 5

__all__ = [
    "Refusals",
    "check_supported",
    "dense_efc_J",
    "disabled",
    "element",
    "project_state",
    "violation",
]


def disabled(m, flag: str) -> bool:
    """Whether a MuJoCo disable flag (mjDSBL_...) is set in the file's options."""
    bit = getattr(mujoco.mjtDisableBit, flag, None)
    return bit is not None and bool(m.opt.disableflags & int(bit))


def element(m, obj, i: int) -> str:
    """An element's name in the file, or #index where it has none."""
    return mujoco.mj_id2name(m, obj, i) or f"#{i}"


@dataclass
class Refusals:
    """Problems grouped by kind, for one line: 'joint 'a' has dry friction (frictionloss): set
    it to 0' for one element, '3 joints have dry friction (frictionloss): a, b, c: set it to 0'
    for several."""

    groups: dict[tuple, list[str]] = field(default_factory=dict)

    def add(self, one: str, many: str, way_out: str, name: str) -> None:
        """One offending element; ``one`` takes {name}, ``many`` takes {n}."""
        self.groups.setdefault((one, many, way_out), []).append(name)

    def lines(self) -> list[str]:
        out = []
        for (one, many, way_out), names in self.groups.items():
            if len(names) == 1:
                out.append(f"{one.format(name=repr(names[0]))}: {way_out}")
                continue
            listed = ", ".join(names[:LISTED])
            more = f" and {len(names) - LISTED} more" if len(names) > LISTED else ""
            out.append(f"{many.format(n=len(names))}: {listed}{more}: {way_out}")
        return out

    def raise_if_any(self, where: str, extra: list[str] | None = None) -> None:
        problems = self.lines() + list(extra or [])
        if problems:
            raise UnsupportedModelError(
                f"{where}: not representable in the reference: " + "; ".join(problems)
            )


def _actuator_problems(problems: Refusals, unexpressed: list[tuple[str, str]]) -> None:
    for name, why in unexpressed:
        problems.add(
            f"actuator {{name}} has {why}",
            f"{{n}} actuators have {why}",
            "the reference expresses actuators on hinge and slide joints (directly or through "
            "a fixed tendon) with fixed or affine gain and bias; one that applies no force at "
            "its control is left out (--ctrl NAME=0), or remove them, or disable actuation "
            '(<option><flag actuation="disable"/></option>)',
            name,
        )


def _tendon_problems(m, problems: Refusals) -> None:
    for t in range(m.ntendon):
        acts = []
        if m.tendon_stiffness[t] or np.any(m.tendon_stiffnesspoly[t]):
            acts.append("stiffness")
        if m.tendon_damping[t] or np.any(m.tendon_dampingpoly[t]):
            acts.append("damping")
        if m.tendon_frictionloss[t] and not disabled(m, "mjDSBL_FRICTIONLOSS"):
            acts.append("frictionloss")
        if m.tendon_armature[t]:
            acts.append("armature")
        if acts:
            what = ", ".join(acts)
            problems.add(
                f"tendon {{name}} acts on the bodies ({what})",
                f"{{n}} tendons act on the bodies ({what})",
                "the reference has no tendons: remove them",
                element(m, OBJ.mjOBJ_TENDON, t),
            )


def _joint_problems(m, problems: Refusals) -> None:
    friction = not (disabled(m, "mjDSBL_FRICTIONLOSS") or disabled(m, "mjDSBL_CONSTRAINT"))
    spatial = (int(mujoco.mjtJoint.mjJNT_BALL), int(mujoco.mjtJoint.mjJNT_FREE))
    for j in range(m.njnt):
        name = element(m, OBJ.mjOBJ_JOINT, j)
        if np.any(m.jnt_stiffnesspoly[j]):
            problems.add(
                "joint {name} has a nonlinear spring (stiffnesspoly)",
                "{n} joints have nonlinear springs (stiffnesspoly)",
                "use stiffness only",
                name,
            )
        if m.jnt_stiffness[j] and m.jnt_type[j] in spatial:
            problems.add(
                "joint {name} is a ball or free joint with a spring",
                "{n} ball or free joints have springs",
                'springs on ball and free joints are not modelled: set stiffness="0"',
                name,
            )
        dofs = range(m.jnt_dofadr[j], m.jnt_dofadr[j] + _ndof(m.jnt_type[j]))
        if friction and any(m.dof_frictionloss[k] for k in dofs):
            problems.add(
                "joint {name} has dry friction (frictionloss)",
                "{n} joints have dry friction (frictionloss)",
                "set it to 0",
                name,
            )
        if any(np.any(m.dof_dampingpoly[k]) for k in dofs):
            problems.add(
                "joint {name} has a nonlinear damper (dampingpoly)",
                "{n} joints have nonlinear dampers (dampingpoly)",
                "use damping only",
                name,
            )


def _ndof(t) -> int:
    return {int(mujoco.mjtJoint.mjJNT_FREE): 6, int(mujoco.mjtJoint.mjJNT_BALL): 3}.get(t, 1)


def _model_problems(m, problems: Refusals) -> list[str]:
    """The whole-model problems (one line each) and the bodies with gravcomp."""
    out = []
    if m.nflex:
        out.append(f"{m.nflex} flex object(s): deformable bodies are not modelled; remove them")
    if m.nplugin:
        out.append(f"{m.nplugin} plugin(s): their forces are unknown to the reference")
    if m.opt.density or m.opt.viscosity:
        out.append("fluid forces (option density/viscosity): set both to 0")
    for b in range(m.nbody):
        if m.body_gravcomp[b]:
            problems.add(
                "body {name} has gravcomp",
                "{n} bodies have gravcomp",
                "set it to 0",
                element(m, OBJ.mjOBJ_BODY, b),
            )
    return out


def check_supported(m, where: str, unexpressed: list[tuple[str, str]] = ()) -> tuple[str, ...]:
    """Raise UnsupportedModelError naming, in one line grouped by problem, every element that
    acts at every state and that the reference cannot represent (``unexpressed``: the
    actuators reference.mjcf.actuators cannot express, as (name, why)); return notes on
    elements accepted because they cannot act."""
    problems, notes = Refusals(), []
    _tendon_problems(m, problems)
    _actuator_problems(problems, list(unexpressed))
    _joint_problems(m, problems)
    whole = _model_problems(m, problems)
    eq_on = not (disabled(m, "mjDSBL_EQUALITY") or disabled(m, "mjDSBL_CONSTRAINT"))
    for e in range(m.neq):
        name = element(m, OBJ.mjOBJ_EQUALITY, e)
        if not m.eq_active0[e] or not eq_on:
            notes.append(f"equality {name!r} is inactive and left out")
        elif m.eq_type[e] not in (int(EQ.mjEQ_CONNECT), int(EQ.mjEQ_WELD), int(EQ.mjEQ_JOINT)):
            kind = mujoco.mjtEq(int(m.eq_type[e])).name.removeprefix("mjEQ_").lower()
            problems.add(
                f"equality {{name}} is a {kind} equality",
                f"{{n}} equalities are {kind} equalities",
                "the reference supports connect, weld and joint: remove them",
                name,
            )
    problems.raise_if_any(where, whole)
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
