"""MJCF files into reference Models: MuJoCo compiles, the reference derives.

The file is compiled by MuJoCo (mujoco.MjModel.from_xml_path), so defaults, classes, frames,
geom-derived masses and inertias and the compiled equality anchors are MuJoCo's own numbers.
The reference Model is then written in the file's joint coordinates, qpos in MuJoCo's order:

- hinge and slide: one coordinate each, measured from the joint's `ref` (MuJoCo's qpos0), as
  mj_kinematics does (rotation about the axis through the anchor; translation along the axis);
- ball: the quaternion (w, x, y, z) with its unit-norm row (q.q - 1)/2 = 0; free: position and
  quaternion. The speeds are the coordinate rates (so Lagrange's and Kane's equations both
  apply, as for the top of Exercises 6.5/6.6); MuJoCo's qvel is the local angular velocity
  omega = 2 (w v' - w' v - v x v') of a quaternion (w, v), see `qvel_from_rates`;
- bodies: mass, mass center (body_ipos) and central inertia (body_inertia rotated by
  body_iquat) from the compiled model; gravity from opt.gravity;
- joint armature (an inertia a on the joint's rate, a massless rotor), damping (-d times the
  joint's qvel), stiffness with springref on hinges and slides (potential k (q - q_spring)^2/2);
- equality constraints at their compiled anchors: connect (p1 - p2 = 0, MuJoCo's rows),
  weld (p1 - p2 = 0 and the vector part of the relative rotation, R2^T R1 R_rel = 1, scaled as
  MuJoCo's quaternion rows at the manifold), joint (q1 - q1_0 = sum c_i (q2 - q2_0)^i).

- actuators on hinges and slides at a stated control (reference.mjcf.actuators): MuJoCo's gain
  and bias force as a load on the joint's rate;
- contacts, joint and tendon limits and force clamps act at some states only: the import keeps
  a Monitor of them (reference.mjcf.unilateral), and the checks run where none acts.

Anything else that changes the dynamics at every state is refused with the element's name and
the way out (reference.mjcf.checks). Constants enter the equations as exact rationals of the
compiled doubles (short ones where the double is exactly a short fraction), so no digit is lost
in code generation.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import mujoco
import numpy as np
import sympy as sp

from reference.dag import Calculus
from reference.errors import ModelFileError, OffManifoldError
from reference.forces import ForceElements, combine, joint_damper, joint_spring
from reference.mjcf.actuators import Actuation, actuation, stated_controls
from reference.mjcf.exact import num
from reference.mjcf.speeds import qvel_from_rates, rates_from_qvel
from reference.mjcf.unilateral import Monitor, always_in_contact, present
from reference.system import Body, Model, Torque, skew, vec

T_SYM = sp.Symbol("t", real=True)
JNT = mujoco.mjtJoint
EQ = mujoco.mjtEq

# Entries of unit vectors and rotation matrices (dimensionless, size 1) below this are the
# round-off of MuJoCo's frame arithmetic (e.g. 6e-17 from euler="0 90 0"), set to exact zero so
# structural zeros stay zero in the derivation; 1e-14 is 100 times that round-off and far below
# any deliberate axis component.
UNIT_CHOP = 1e-14

# A consistent initial state (qpos0 or keyframe 0) violates its equality rows and quaternion
# norms by round-off only; 1e-9 (as reference.numeric.model.MANIFOLD_TOL) separates that from a
# mistake in the file.
INITIAL_TOL = 1e-9


def unit_vec(v) -> sp.Matrix:
    return sp.Matrix([0 if abs(c) < UNIT_CHOP else num(c) for c in np.asarray(v, float)])


def quat_matrix_const(quat) -> sp.Matrix:
    """MuJoCo's own rotation matrix of a compiled quaternion, exact."""
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat, float))
    return sp.Matrix(3, 3, [0 if abs(c) < UNIT_CHOP else num(c) for c in R])


def quat_rotation(w, x, y, z) -> sp.Matrix:
    """Rotation of a unit quaternion (w, x, y, z), homogeneous quadratic (as top.rotation)."""
    v = sp.Matrix([x, y, z])
    return (w**2 - (v.T * v)[0]) * sp.eye(3) + 2 * v * v.T + 2 * w * skew(v)


def quat_omega(quat, rates) -> sp.Matrix:
    """Local angular velocity 2 (w v' - w' v - v x v') of a quaternion and its rates."""
    w, v = quat[0], sp.Matrix(quat[1:])
    wd, vd = rates[0], sp.Matrix(rates[1:])
    return 2 * (w * vd - wd * v - v.cross(vd))


def axis_rotation(a: sp.Matrix, angle) -> sp.Matrix:
    """Rodrigues: rotation by `angle` about the unit axis a."""
    K = skew(a)
    return sp.eye(3) + sp.sin(angle) * K + (1 - sp.cos(angle)) * K * K


_NORM_REASON = (
    "quaternion normalization: Lagrange's K and V see variations off the unit "
    "sphere that the partial velocities do not (as the top's, Exercise 6.6)"
)


@dataclass(frozen=True)
class JointInfo:
    """One MJCF joint in the reference: its coordinates and the MuJoCo dofs' velocity
    expressions (qvel as functions of the rates)."""

    name: str
    type: int
    qposadr: int
    dofadr: int
    coords: tuple
    rates: tuple
    dof_velocity: tuple  # expressions of the rates, one per MuJoCo dof


@dataclass(frozen=True)
class MjcfImport:
    """The reference Model of an MJCF file with what maps it to MuJoCo's state.

    ``actuation``: the actuators at their stated controls; ``monitor``: what acts at some
    states only (contacts, limits, force clamps), None where the file has none;
    ``projection``: how far the initial state was moved onto the constraint manifold (the
    violation before, the largest change of qpos and of qvel), None where it was not."""

    model: Model
    path: str
    mj: object  # mujoco.MjModel
    joints: tuple[JointInfo, ...]
    notes: tuple[str, ...] = field(default_factory=tuple)
    actuation: Actuation = field(default_factory=Actuation)
    monitor: Monitor | None = None
    projection: dict[str, float] | None = None


# ---- file ---------------------------------------------------------------------------------------
def compile_file(path) -> mujoco.MjModel:
    """MuJoCo's compiled model, or a ModelFileError carrying MuJoCo's own message."""
    path = Path(path)
    if not path.is_file():
        raise ModelFileError(f"{path}: no such file")
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except Exception as exc:  # mujoco raises ValueError with the XML/compiler message
        msg = " ".join(str(exc).split())
        raise ModelFileError(f"{path}: MuJoCo rejects the file: {msg}") from exc


def _name(m, obj, i: int, prefix: str) -> str:
    n = mujoco.mj_id2name(m, obj, i)
    return n if n else f"{prefix}{i}"


def _ident(s: str) -> str:
    out = "".join(c if c.isalnum() or c == "_" else "_" for c in s)
    return out if out and not out[0].isdigit() else f"j_{out}"


# ---- kinematics ---------------------------------------------------------------------------------
def _joint_symbols(m, j: int):
    base = _ident(_name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint"))
    t = m.jnt_type[j]
    if t == int(JNT.mjJNT_FREE):
        names = [f"{base}_{s}" for s in ("x", "y", "z", "qw", "qx", "qy", "qz")]
    elif t == int(JNT.mjJNT_BALL):
        names = [f"{base}_{s}" for s in ("qw", "qx", "qy", "qz")]
    else:
        names = [base]
    q = tuple(sp.Symbol(n, real=True) for n in names)
    u = tuple(sp.Symbol(f"{n}_dot", real=True) for n in names)
    return q, u


def _frames(m):
    """World position and rotation of every body frame, and its angular velocity in body
    components, as expressions of the coordinates and rates; plus the joint table."""
    pos = {0: sp.zeros(3, 1)}
    rot = {0: sp.eye(3)}
    omega = {0: sp.zeros(3, 1)}
    joints: list[JointInfo] = []
    for b in range(1, m.nbody):
        par = m.body_parentid[b]
        Rb = quat_matrix_const(m.body_quat[b])
        p = pos[par] + rot[par] * sp.Matrix([num(c) for c in m.body_pos[b]])
        R = rot[par] * Rb
        w = Rb.T * omega[par]
        for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]):
            q, u = _joint_symbols(m, j)
            t, adr = m.jnt_type[j], m.jnt_qposadr[j]
            anchor = sp.Matrix([num(c) for c in m.jnt_pos[j]])
            if t == int(JNT.mjJNT_FREE):
                p, R = sp.Matrix(q[:3]), quat_rotation(*q[3:])
                w = quat_omega(q[3:], u[3:])
                dofs = tuple(u[:3]) + tuple(w)
            elif t == int(JNT.mjJNT_BALL):
                Rj = quat_rotation(*q)
                a_w = p + R * anchor
                R = R * Rj
                p = a_w - R * anchor
                w_loc = quat_omega(q, u)
                w = Rj.T * w + w_loc
                dofs = tuple(w_loc)
            else:
                a = unit_vec(m.jnt_axis[j])
                x = q[0] - num(m.qpos0[adr])
                if t == int(JNT.mjJNT_SLIDE):
                    p = p + R * a * x
                else:
                    Rj = axis_rotation(a, x)
                    a_w = p + R * anchor
                    R = R * Rj
                    p = a_w - R * anchor
                    w = Rj.T * w + a * u[0]
                dofs = (u[0],)
            joints.append(
                JointInfo(
                    _name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint"),
                    int(t),
                    int(adr),
                    int(m.jnt_dofadr[j]),
                    q,
                    u,
                    dofs,
                )
            )
        pos[b], rot[b], omega[b] = p, R, w
    return pos, rot, omega, joints


def _central_inertia(m, b: int) -> sp.Matrix:
    Ri = np.zeros(9)
    mujoco.mju_quat2Mat(Ri, m.body_iquat[b])
    Ri = Ri.reshape(3, 3)
    I = Ri @ np.diag(m.body_inertia[b]) @ Ri.T
    I = 0.5 * (I + I.T)
    chop = UNIT_CHOP * float(np.max(np.abs(I)) or 1.0)
    return sp.Matrix(3, 3, [0 if abs(c) < chop else num(c) for c in I.reshape(-1)])


def _bodies(m, pos, rot, omega, coords, kin) -> tuple[Body, ...]:
    # v_G on the expressions' graph: every body's r_G reuses its parent's frame, which
    # sympy's tree-walking diff would write out again for each body (Cassie: 166 s against 2)
    calc = Calculus(coords, kin, T_SYM)
    out = []
    for b in range(1, m.nbody):
        if m.body_mass[b] == 0 and not np.any(m.body_inertia[b]):
            continue  # a pure frame: no kinetic energy, no weight
        r_G = pos[b] + rot[b] * sp.Matrix([num(c) for c in m.body_ipos[b]])
        out.append(
            Body(
                _name(m, mujoco.mjtObj.mjOBJ_BODY, b, "body"),
                num(m.body_mass[b]),
                v_G=calc.rate(r_G),
                inertia=_central_inertia(m, b),
                omega=omega[b],
                r_G=r_G,
                R=rot[b],
            )
        )
    return tuple(out)


# ---- passive elements ---------------------------------------------------------------------------
def _passive(m, joints) -> tuple[tuple[Body, ...], ForceElements]:
    """Armature as massless rotors, damping as joint dampers, hinge/slide springs."""
    from reference.mjcf.checks import disabled

    rotors, elements = [], []
    for ji in joints:
        for k, w in enumerate(ji.dof_velocity):
            dof = ji.dofadr + k
            a, d = float(m.dof_armature[dof]), float(m.dof_damping[dof])
            if a:
                rotors.append(
                    Body(
                        f"armature:{ji.name}:{k}",
                        sp.Integer(0),
                        v_G=sp.zeros(3, 1),
                        inertia=sp.diag(num(a), 0, 0),
                        omega=vec(w, 0, 0),
                        r_G=sp.zeros(3, 1),
                        R=sp.eye(3),
                    )
                )
            if d and not disabled(m, "mjDSBL_DAMPER"):
                elements.append(joint_damper(f"{ji.name}:{k}", w, num(d)))
        jid = next(j for j in range(m.njnt) if m.jnt_qposadr[j] == ji.qposadr)
        k_s = float(m.jnt_stiffness[jid])
        if (
            k_s
            and not disabled(m, "mjDSBL_SPRING")
            and ji.type in (int(JNT.mjJNT_HINGE), int(JNT.mjJNT_SLIDE))
        ):
            elements.append(
                joint_spring(ji.name, ji.coords[0], num(k_s), num(m.qpos_spring[ji.qposadr]))
            )
    return tuple(rotors), combine(*elements)


# ---- equality constraints -----------------------------------------------------------------------
def _eq_point_and_frame(m, e: int, side: int, pos, rot, weld: bool):
    """World point and frame rotation of side 0/1 of equality e (body or site semantic)."""
    obj = (m.eq_obj1id, m.eq_obj2id)[side][e]
    data = m.eq_data[e]
    if m.eq_objtype[e] == mujoco.mjtObj.mjOBJ_SITE:
        body = m.site_bodyid[obj]
        local = sp.Matrix([num(c) for c in m.site_pos[obj]])
        frame = rot[body] * quat_matrix_const(m.site_quat[obj])
        return pos[body] + rot[body] * local, frame
    # body semantic: connect anchors data[0:3] (body 1), data[3:6] (body 2); weld the reverse
    k = (1 - side) if weld else side
    local = sp.Matrix([num(c) for c in data[3 * k : 3 * k + 3]])
    frame = rot[obj] * (quat_matrix_const(data[6:10]) if (weld and side == 0) else sp.eye(3))
    return pos[obj] + rot[obj] * local, frame


def _equalities(m, pos, rot, joints):
    """Configuration constraints and their names, MuJoCo's row order and sign."""
    from reference.mjcf.checks import disabled

    rows, names = [], []
    if disabled(m, "mjDSBL_EQUALITY") or disabled(m, "mjDSBL_CONSTRAINT"):
        return rows, names
    by_jnt = {ji.qposadr: ji for ji in joints}
    for e in range(m.neq):
        if not m.eq_active0[e]:
            continue
        label = _name(m, mujoco.mjtObj.mjOBJ_EQUALITY, e, "equality")
        t = m.eq_type[e]
        if t in (int(EQ.mjEQ_CONNECT), int(EQ.mjEQ_WELD)):
            weld = t == int(EQ.mjEQ_WELD)
            p1, R1 = _eq_point_and_frame(m, e, 0, pos, rot, weld)
            p2, R2 = _eq_point_and_frame(m, e, 1, pos, rot, weld)
            rows += list(p1 - p2)
            names += [f"{label}_{c}" for c in "xyz"]
            ts = float(m.eq_data[e, 10]) if weld else 0.0
            if weld and ts != 0.0:
                E = R2.T * R1  # identity on the manifold
                # vee((E - E^T)/4) = sin(theta)/2 axis: MuJoCo's quaternion rows
                # (sin(theta/2) axis) to first order, so the rows and multipliers match there
                vee = sp.Matrix([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]]) / 4
                rows += list(num(ts) * vee)
                names += [f"{label}_r{c}" for c in "xyz"]
        elif t == int(EQ.mjEQ_JOINT):
            j1, j2 = m.eq_obj1id[e], m.eq_obj2id[e]
            q1 = by_jnt[m.jnt_qposadr[j1]].coords[0] - num(m.qpos0[m.jnt_qposadr[j1]])
            c = [num(x) for x in m.eq_data[e, :5]]
            if j2 >= 0:
                x = by_jnt[m.jnt_qposadr[j2]].coords[0] - num(m.qpos0[m.jnt_qposadr[j2]])
                rows.append(q1 - c[0] - sum(c[i] * x**i for i in range(1, 5)))
            else:
                rows.append(q1 - c[0])
            names.append(label)
    return rows, names


# ---- the model ----------------------------------------------------------------------------------
def initial_state(m) -> tuple[np.ndarray, np.ndarray]:
    """Keyframe 0 when the file has one, else qpos0 at rest (what mj_resetData gives)."""
    if m.nkey:
        return np.array(m.key_qpos[0], float), np.array(m.key_qvel[0], float)
    return np.array(m.qpos0, float), np.zeros(m.nv)


def _initial(m, path, project: bool):
    """The initial state (keyframe 0 or qpos0) on the constraint manifold, a note and the
    projection's size where it had to be projected; OffManifoldError where it is off and
    ``project`` is False."""
    from reference.mjcf.checks import project_state, violation

    qpos, qvel = initial_state(m)
    off = violation(m, qpos, qvel)
    scale = 1 + float(np.max(np.abs(np.concatenate([qpos, qvel])), initial=0.0))
    if off <= INITIAL_TOL * scale:
        return qpos, qvel, None, None
    if not project:
        raise OffManifoldError(
            f"{path}: the initial state ({'keyframe 0' if m.nkey else 'qpos0'}) violates "
            f"the equality constraints (positions or velocities) or quaternion norms by "
            f"{off:.3e} (tolerance {INITIAL_TOL:.0e}); fix the keyframe, or project it onto "
            f"the constraint manifold: --project on the command line (import_mjcf(..., "
            f"project=True) in Python)"
        )
    q, v = project_state(m, qpos, qvel)
    moved = {
        "violation": float(off),
        "position_change": float(np.max(np.abs(q - qpos), initial=0.0)),
        "velocity_change": float(np.max(np.abs(v - qvel), initial=0.0)),
    }
    note = (
        f"initial state projected onto the constraint manifold (it was off by {off:.3e}; "
        f"qpos moved by {moved['position_change']:.3e}, qvel by {moved['velocity_change']:.3e})"
    )
    return q, v, note, moved


def _refuse_rigid_contacts(m, qpos, path) -> None:
    """UnsupportedModelError for contacts that act at every consistent state (two geoms
    touching on bodies the equality constraints hold rigidly together), in one line."""
    from reference.mjcf.checks import Refusals

    problems = Refusals()
    for pair, b1, b2 in always_in_contact(m, qpos):
        problems.add(
            f"{pair} touch at the initial state on bodies {b1!r} and {b2!r}, which the "
            "equality constraints hold rigidly together, so the contact acts at every "
            "consistent state",
            "{n} geom pairs touch at the initial state on bodies the equality constraints "
            "hold rigidly together, so the contacts act at every consistent state",
            f'exclude the bodies (<contact><exclude body1="{b1}" body2="{b2}"/></contact>) or '
            'give the geoms contype="0" conaffinity="0"',
            pair,
        )
    problems.raise_if_any(str(path))


def _constraint_rows(m, pos, rot, joints):
    """The equality rows, then one unit-norm row per quaternion; the row names and those of
    the norm rows."""
    rows, names = _equalities(m, pos, rot, joints)
    norm_names = []
    for ji in joints:  # unit-norm rows of the quaternions
        if ji.type in (int(JNT.mjJNT_BALL), int(JNT.mjJNT_FREE)):
            qq = ji.coords[-4:]
            rows.append((sum(c**2 for c in qq) - 1) / 2)
            names.append(f"{ji.name}_norm")
            norm_names.append(names[-1])
    return rows, names, norm_names


def _actuator_loads(act: Actuation, joints) -> ForceElements:
    rates = {ji.dofadr + k: w for ji in joints for k, w in enumerate(ji.dof_velocity)}
    coords = {ji.qposadr: ji.coords[0] for ji in joints}
    return act.loads(rates, coords)


def import_mjcf(path, name: str | None = None, *, project: bool = False, ctrl=None) -> MjcfImport:
    """The reference Model of an MJCF file (see the module docstring for what is supported).

    Parameters
    ----------
    path : str or Path
        The MJCF file.
    name : str, optional
        The model's name (default: the file's stem).
    project : bool
        An initial state (keyframe 0 or qpos0) off the constraint manifold is refused with its
        size unless this is True; then it is projected (MuJoCo's own equality rows).
    ctrl : mapping of str to float, optional
        Actuator controls by name; the others are keyframe 0's ctrl, or 0.

    Returns
    -------
    MjcfImport

    Raises
    ------
    ModelFileError
        A file MuJoCo rejects, or a control for an actuator the file does not have.
    UnsupportedModelError
        Elements that act at every state and the reference cannot represent (one line).
    OffManifoldError
        An initial state off the manifold, without ``project``.
    """
    from reference.mjcf.checks import check_supported, disabled

    m = compile_file(path)
    if m.nv == 0:  # nothing to derive: every check would compare empty arrays
        raise ModelFileError(
            f"{path}: the file has no moving body (no joint: only the world body, or bodies "
            "welded to it), so it has no equations of motion to check; give a body a joint"
        )
    act, unexpressed = actuation(m, stated_controls(m, ctrl))
    notes = check_supported(m, str(path), unexpressed) + act.notes
    pos, rot, omega, joints = _frames(m)
    coords = tuple(s for ji in joints for s in ji.coords)
    rates = tuple(s for ji in joints for s in ji.rates)
    bodies = _bodies(m, pos, rot, omega, coords, rates)
    rotors, passive = _passive(m, joints)
    forces = combine(passive, _actuator_loads(act, joints))
    rows, names, norm_names = _constraint_rows(m, pos, rot, joints)
    g = np.zeros(3) if disabled(m, "mjDSBL_GRAVITY") else np.array(m.opt.gravity, float)
    qpos, qvel, note, moved = _initial(m, path, project)
    notes += (note,) if note else ()
    _refuse_rigid_contacts(m, qpos, path)
    found = present(m, act)
    model = Model(
        name=name or _ident(Path(path).stem),
        source=f"MJCF file {Path(path).name}",
        title=f"MJCF model {Path(path).name} ({len(coords)} coordinates, {len(rows)} "
        f"constraint rows)",
        parameters=(),
        coordinates=coords,
        speeds=rates,
        kinematics=rates,
        bodies=bodies + rotors,
        gravity=sp.Matrix([num(c) for c in g]),
        loads=forces.loads,
        potential=forces.potential,
        configuration_constraints=tuple(rows),
        constraint_names=tuple(names),
        # d'Alembert with the rates as speeds writes Kane's equations again (Eqs. 7 and 9
        # differ only in the rates they project on), so it would only double the derivation
        formulations=("kane", "lagrange"),
        formulation_dependent_rows=tuple((n, _NORM_REASON) for n in norm_names),
        multiplier_meaning=_MULTIPLIER_MEANING,
        initial_q=tuple(float(x) for x in qpos),
        initial_u=tuple(float(x) for x in rates_from_qvel(joints, qpos, qvel)),
        energy_conserved=not forces.loads,
        redundant_constraints=True,
        geometry_note="; ".join(notes),
    )
    model.validate()
    monitor = Monitor(m, tuple(joints), act, found) if found else None
    return MjcfImport(model, str(path), m, tuple(joints), notes, act, monitor, moved)


_MULTIPLIER_MEANING = (
    "MuJoCo's equality rows: connect/weld position rows, the force on the first object at its "
    "anchor (world components); weld rotation rows, torquescale * lambda / 2 is the moment on "
    "the first object (the second object's frame, on the manifold); joint rows, the "
    "generalized force on the first joint; quaternion norm rows depend on the formulation. "
    "With dependent rows, the minimum-norm lambda"
)


def with_initial_state(imp: MjcfImport, qpos, qvel) -> MjcfImport:
    """The same import with another initial state (MuJoCo qpos, qvel)."""
    u = rates_from_qvel(imp.joints, qpos, qvel)
    model = replace(imp.model, initial_q=tuple(map(float, qpos)), initial_u=tuple(map(float, u)))
    return replace(imp, model=model)


__all__ = [
    "JointInfo",
    "MjcfImport",
    "Torque",
    "compile_file",
    "import_mjcf",
    "initial_state",
    "num",
    "qvel_from_rates",
    "rates_from_qvel",
    "with_initial_state",
]
