"""MuJoCo's compiled model of a user's MJCF file as engine-neutral data: what the Exudyn and
OpenSim models of the file are built from, and the named numbers ``--perturb`` may change in
them.

The numbers are the ones the reference is built from (reference.mjcf.loader): bodies in
MuJoCo's order with their frames in the parent's (body_pos, body_quat), masses, mass centres
(body_ipos) and central inertias (body_inertia rotated by body_iquat); joints with their
anchors and axes in the body frame, MuJoCo's qpos0 (a hinge's angle and a slide's offset are
qpos - qpos0, as mj_kinematics reads them), stiffness with springref, damping and armature;
gravity; the active equalities at their compiled anchors and frames (body or site semantic),
in MuJoCo's row order. Disabled features are left out as the reference leaves them out
(gravity, springs, dampers, equalities).

Perturbable numbers (the vocabulary of ``--perturb ENGINE:NAME=REL`` on a user's file):
``<body>.mass``, ``<body>.I1``, ``<body>.I2``, ``<body>.I3`` (the principal inertias),
``<joint>.stiffness``, ``<joint>.damping``, ``<joint>.armature`` (every dof of the joint) and
``gravity`` (the vector's length). Geometry is not perturbable, so the state and multiplier
maps, which read the geometry, never move with a perturbation.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

__all__ = [
    "Actuator",
    "Body",
    "CompiledModel",
    "Equality",
    "Joint",
    "Side",
    "body_poses",
    "describe",
    "joint_frame",
    "mat_quat",
    "perturbable",
    "quat_conj",
    "quat_matrix",
    "quat_mul",
]

JNT = mujoco.mjtJoint
EQ = mujoco.mjtEq
KINDS = {
    int(JNT.mjJNT_HINGE): "hinge",
    int(JNT.mjJNT_SLIDE): "slide",
    int(JNT.mjJNT_BALL): "ball",
    int(JNT.mjJNT_FREE): "free",
}
NDOF = {"hinge": 1, "slide": 1, "ball": 3, "free": 6}
BODY_NUMBERS = ("mass", "I1", "I2", "I3")
JOINT_NUMBERS = ("stiffness", "damping", "armature")


@dataclass(frozen=True)
class Joint:
    """One MuJoCo joint: anchor and unit axis in its body's frame, MuJoCo's qpos0 (the zero of a
    hinge's angle or a slide's offset), passive elements (damping and armature per dof)."""

    index: int
    name: str
    kind: str
    qposadr: int
    dofadr: int
    anchor: np.ndarray
    axis: np.ndarray
    qpos0: float
    stiffness: float
    springref: float
    damping: np.ndarray
    armature: np.ndarray

    @property
    def ndof(self) -> int:
        """MuJoCo's dofs of the joint (1, 3 or 6)."""
        return NDOF[self.kind]


@dataclass(frozen=True)
class Body:
    """One MuJoCo body: its frame in the parent's body frame, its joints in MuJoCo's order, its
    mass, mass centre and central inertia (body frame)."""

    index: int
    name: str
    parent: int
    pos: np.ndarray
    rot: np.ndarray
    joints: tuple[Joint, ...]
    mass: float
    com: np.ndarray
    inertia: np.ndarray


@dataclass(frozen=True)
class Side:
    """One side of a connect or weld: a frame (origin ``pos``, axes ``rot``) fixed in a body
    (0: the world)."""

    body: int
    pos: np.ndarray
    rot: np.ndarray


@dataclass(frozen=True)
class Equality:
    """An active equality in MuJoCo's row order: connect (3 rows p1 - p2, world), weld (the same
    and, when torquescale is not 0, three rotation rows), joint (q1 - q1_0 = poly(q2 - q2_0))."""

    index: int
    name: str
    kind: str
    sides: tuple[Side, ...] = ()
    torquescale: float = 0.0
    joints: tuple[int, int] = (-1, -1)
    polycoef: np.ndarray | None = None

    @property
    def rows(self) -> int:
        """The equality's rows in the reference (MuJoCo's)."""
        if self.kind == "joint":
            return 1
        return 6 if self.kind == "weld" and self.torquescale != 0.0 else 3


@dataclass(frozen=True)
class Actuator:
    """An actuator at its stated control, as the reference loads it (reference.mjcf.actuators):
    on hinges and slides ``terms`` ((joint index, k) each, k the gear times the tendon's
    coefficient), length L = sum k qpos, velocity V = sum k qvel, force F = constant +
    stiffness_term L + damping_term V (gain times the input plus bias, both affine), and k F
    on each joint's dof. A force clamp acts at some states only; the checks run where none
    acts, so it is not part of this."""

    name: str
    terms: tuple[tuple[int, float], ...]
    constant: float
    per_length: float
    per_velocity: float


@dataclass(frozen=True)
class CompiledModel:
    """A user's file as MuJoCo compiled it (see the module docstring)."""

    path: str
    bodies: tuple[Body, ...]
    equalities: tuple[Equality, ...]
    gravity: np.ndarray
    nq: int
    nv: int
    actuators: tuple[Actuator, ...] = ()

    def body(self, index: int) -> Body:
        """The body with MuJoCo index ``index`` (>= 1)."""
        return self.bodies[index - 1]

    @property
    def joints(self) -> tuple[Joint, ...]:
        """Every joint in MuJoCo's order."""
        return tuple(j for b in self.bodies for j in b.joints)

    def joint(self, index: int) -> Joint:
        """The joint with MuJoCo index ``index``."""
        return self.joints[index]

    def moving(self, index: int) -> bool:
        """Whether body ``index`` moves (it or an ancestor has a joint); 0 is the world."""
        while index:
            b = self.body(index)
            if b.joints:
                return True
            index = b.parent
        return False

    @property
    def rows(self) -> int:
        """The equality rows (the reference's constraint rows before the quaternion norms)."""
        return sum(e.rows for e in self.equalities)


def _name(m, obj, i: int, prefix: str) -> str:
    # the reference loader's names (reference.mjcf.loader._name)
    return mujoco.mj_id2name(m, obj, i) or f"{prefix}{i}"


def quat_matrix(quat) -> np.ndarray:
    """MuJoCo's rotation matrix of a quaternion (w, x, y, z)."""
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat, float))
    return R.reshape(3, 3)


def mat_quat(R) -> np.ndarray:
    """MuJoCo's quaternion (w, x, y, z) of a rotation matrix."""
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.asarray(R, float).reshape(-1))
    return q


def quat_mul(a, b) -> np.ndarray:
    """MuJoCo's quaternion product a (x) b."""
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, np.asarray(a, float), np.asarray(b, float))
    return out


def quat_conj(q) -> np.ndarray:
    """The conjugate (w, -x, -y, -z): the inverse rotation of a unit quaternion."""
    return np.array([q[0], -q[1], -q[2], -q[3]], float)


def joint_frame(axis) -> np.ndarray:
    """A rotation whose third column is the unit ``axis`` (a joint's frame: the engines'
    joints turn about, or slide along, their own z axis; the other two columns complete it)."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    t = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(t, a)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(a, x), a])


def perturbable(m) -> dict[str, float]:
    """The named numbers of a compiled model that ``--perturb`` may change.

    Parameters
    ----------
    m : mujoco.MjModel
        The compiled model.

    Returns
    -------
    dict of str to float
        ``<body>.mass``, ``<body>.I1..I3``, ``<joint>.stiffness``, ``<joint>.damping``,
        ``<joint>.armature`` (the largest over the joint's dofs) and ``gravity`` (its length),
        with their compiled values.
    """
    out: dict[str, float] = {}
    for b in range(1, m.nbody):
        name = _name(m, mujoco.mjtObj.mjOBJ_BODY, b, "body")
        out[f"{name}.mass"] = float(m.body_mass[b])
        for k in range(3):
            out[f"{name}.I{k + 1}"] = float(m.body_inertia[b, k])
    for j in range(m.njnt):
        name = _name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")
        dofs = slice(m.jnt_dofadr[j], m.jnt_dofadr[j] + NDOF[KINDS[int(m.jnt_type[j])]])
        out[f"{name}.stiffness"] = float(m.jnt_stiffness[j])
        out[f"{name}.damping"] = float(np.max(m.dof_damping[dofs]))
        out[f"{name}.armature"] = float(np.max(m.dof_armature[dofs]))
    out["gravity"] = float(np.linalg.norm(m.opt.gravity))
    return out


def _scale(overrides: dict, defaults: dict, key: str) -> float:
    """The relative change of one named number (1 when it is not overridden)."""
    if key not in overrides or defaults[key] == 0.0:
        return 1.0
    return float(overrides[key]) / defaults[key]


def _joint(m, j: int, scale) -> Joint:
    from reference.mjcf.checks import disabled

    kind = KINDS[int(m.jnt_type[j])]
    name = _name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")
    dofs = slice(m.jnt_dofadr[j], m.jnt_dofadr[j] + NDOF[kind])
    adr = int(m.jnt_qposadr[j])
    spring = kind in ("hinge", "slide") and not disabled(m, "mjDSBL_SPRING")
    damper = not disabled(m, "mjDSBL_DAMPER")
    return Joint(
        index=j,
        name=name,
        kind=kind,
        qposadr=adr,
        dofadr=int(m.jnt_dofadr[j]),
        anchor=np.array(m.jnt_pos[j], float),
        axis=np.array(m.jnt_axis[j], float),
        qpos0=float(m.qpos0[adr]) if kind in ("hinge", "slide") else 0.0,
        stiffness=float(m.jnt_stiffness[j]) * scale(f"{name}.stiffness") if spring else 0.0,
        springref=float(m.qpos_spring[adr]),
        damping=np.array(m.dof_damping[dofs], float) * scale(f"{name}.damping") * damper,
        armature=np.array(m.dof_armature[dofs], float) * scale(f"{name}.armature"),
    )


def _body(m, b: int, joints: tuple[Joint, ...], scale) -> Body:
    name = _name(m, mujoco.mjtObj.mjOBJ_BODY, b, "body")
    Ri = quat_matrix(m.body_iquat[b])
    principal = np.array([m.body_inertia[b, k] * scale(f"{name}.I{k + 1}") for k in range(3)])
    inertia = Ri @ np.diag(principal) @ Ri.T
    return Body(
        index=b,
        name=name,
        parent=int(m.body_parentid[b]),
        pos=np.array(m.body_pos[b], float),
        rot=quat_matrix(m.body_quat[b]),
        joints=joints,
        mass=float(m.body_mass[b]) * scale(f"{name}.mass"),
        com=np.array(m.body_ipos[b], float),
        inertia=0.5 * (inertia + inertia.T),
    )


def _side(m, e: int, side: int, weld: bool) -> Side:
    """Side 0/1 of a connect or weld, as the reference reads it (reference.mjcf.loader)."""
    obj = int((m.eq_obj1id, m.eq_obj2id)[side][e])
    if m.eq_objtype[e] == mujoco.mjtObj.mjOBJ_SITE:
        return Side(
            int(m.site_bodyid[obj]),
            np.array(m.site_pos[obj], float),
            quat_matrix(m.site_quat[obj]),
        )
    # body semantic: connect anchors data[0:3] (body 1), data[3:6] (body 2); weld the reverse,
    # with the relative pose's rotation data[6:10] on body 1
    data = m.eq_data[e]
    k = (1 - side) if weld else side
    rot = quat_matrix(data[6:10]) if (weld and side == 0) else np.eye(3)
    return Side(obj, np.array(data[3 * k : 3 * k + 3], float), rot)


def _equalities(m) -> tuple[Equality, ...]:
    from reference.mjcf.checks import disabled

    if disabled(m, "mjDSBL_EQUALITY") or disabled(m, "mjDSBL_CONSTRAINT"):
        return ()
    out = []
    for e in range(m.neq):
        if not m.eq_active0[e]:
            continue
        name = _name(m, mujoco.mjtObj.mjOBJ_EQUALITY, e, "equality")
        t = int(m.eq_type[e])
        if t in (int(EQ.mjEQ_CONNECT), int(EQ.mjEQ_WELD)):
            weld = t == int(EQ.mjEQ_WELD)
            sides = (_side(m, e, 0, weld), _side(m, e, 1, weld))
            ts = float(m.eq_data[e, 10]) if weld else 0.0
            out.append(Equality(e, name, "weld" if weld else "connect", sides, ts))
        elif t == int(EQ.mjEQ_JOINT):
            joints = (int(m.eq_obj1id[e]), int(m.eq_obj2id[e]))
            poly = np.array(m.eq_data[e, :5], float)
            out.append(Equality(e, name, "joint", joints=joints, polycoef=poly))
    return tuple(out)


def _actuators(m, actuation) -> tuple[Actuator, ...]:
    """The reference's actuators (reference.mjcf.actuators.Actuation, where the loader has
    them) in the form above."""
    if actuation is None:
        return ()
    joint_of_dof = {int(m.jnt_dofadr[j]): j for j in range(m.njnt)}
    out = []
    for a in getattr(actuation, "joint", ()):
        g0, g1, g2 = a.gain
        b0, b1, b2 = a.bias
        out.append(
            Actuator(
                a.name,
                tuple((joint_of_dof[dof], float(k)) for dof, _adr, k in a.terms),
                g0 * a.input + b0,
                g1 * a.input + b1,
                g2 * a.input + b2,
            )
        )
    return tuple(out)


def describe(
    m, path: str = "", overrides: dict[str, float] | None = None, actuation=None
) -> CompiledModel:
    """The compiled model as engine-neutral data (module docstring).

    Parameters
    ----------
    m : mujoco.MjModel
        The compiled model.
    path : str
        The file it was compiled from.
    overrides : dict of str to float, optional
        Absolute values of named numbers (``perturbable``'s names) in place of the compiled
        ones; a number is scaled with every dof and principal axis it names.
    actuation : reference.mjcf.actuators.Actuation, optional
        The import's actuators at their stated controls.

    Returns
    -------
    CompiledModel

    Raises
    ------
    KeyError
        A name in ``overrides`` that is not one of ``perturbable``'s.
    """
    from reference.mjcf.checks import disabled

    overrides = dict(overrides or {})
    defaults = perturbable(m)
    unknown = sorted(set(overrides) - set(defaults))
    if unknown:
        raise KeyError(f"not numbers of the compiled model: {unknown}")

    def scale(key: str) -> float:
        return _scale(overrides, defaults, key)

    bodies = []
    for b in range(1, m.nbody):
        first = int(m.body_jntadr[b])
        joints = tuple(_joint(m, j, scale) for j in range(first, first + m.body_jntnum[b]))
        bodies.append(_body(m, b, joints, scale))
    g = np.zeros(3) if disabled(m, "mjDSBL_GRAVITY") else np.array(m.opt.gravity, float)
    return CompiledModel(
        path=path,
        bodies=tuple(bodies),
        equalities=_equalities(m),
        gravity=g * scale("gravity"),
        nq=int(m.nq),
        nv=int(m.nv),
        actuators=_actuators(m, actuation),
    )


def _axis_rotation(axis, angle: float) -> np.ndarray:
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def body_poses(cm: CompiledModel, qpos) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """World pose of every body frame at a configuration, composed as mj_kinematics does (each
    joint turns or shifts the body frame about its anchor, in the joints' order; a free joint's
    qpos is the body's world pose).

    Parameters
    ----------
    cm : CompiledModel
    qpos : array_like
        MuJoCo's qpos.

    Returns
    -------
    dict of int to (ndarray, ndarray)
        Body index (0: the world) -> (rotation matrix, origin), world components.
    """
    qpos = np.asarray(qpos, float)
    poses = {0: (np.eye(3), np.zeros(3))}
    for b in cm.bodies:
        Rp, pp = poses[b.parent]
        R, p = Rp @ b.rot, pp + Rp @ b.pos
        for j in b.joints:
            a = j.qposadr
            if j.kind == "free":
                R, p = quat_matrix(qpos[a + 3 : a + 7]), qpos[a : a + 3].copy()
                continue
            if j.kind == "slide":
                p = p + R @ (j.axis * (qpos[a] - j.qpos0))
                continue
            Rj = quat_matrix(qpos[a : a + 4]) if j.kind == "ball" else None
            if Rj is None:
                Rj = _axis_rotation(j.axis / np.linalg.norm(j.axis), qpos[a] - j.qpos0)
            anchor = p + R @ j.anchor
            R = R @ Rj
            p = anchor - R @ j.anchor
        poses[b.index] = (R, p)
    return poses
