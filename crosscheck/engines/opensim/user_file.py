"""OpenSim's model of a user's MJCF file, built from MuJoCo's compiled model
(crosscheck.engines.compiled_model: the numbers the reference is built from) and solved by
Simbody's exact constrained solve.

The model, element by element:

- each MuJoCo body is an OpenSim Body with its compiled mass, mass centre and central inertia
  (body frame = MuJoCo's body frame); a body without joints is welded to its parent
  (WeldJoint at body_pos/body_quat);
- each hinge or slide is a CustomJoint with one rotation about, or one translation along, the
  compiled axis; its parent frame sits at body_pos + body_quat * anchor with body_quat's axes,
  its child frame at the anchor, and the coordinate is MuJoCo's qpos itself (the transform's
  LinearFunction(1, -qpos0): the angle or offset is qpos - qpos0, as mj_kinematics reads it).
  A body with several joints gets a massless intermediate body per extra joint, composed in
  MuJoCo's order (each joint turns the body about its own anchor);
- a ball is a BallJoint at the anchor, a free joint a FreeJoint on the ground. OpenSim runs
  both in Euler-angle mode (body-fixed X-Y-Z, singular at a middle angle of +-pi/2), so the
  joint's parent frame is turned by R0, the joint's rotation at the file's initial state: the
  angles are then those of R0^T R(q), near zero at the states the checks sample;
- gravity from opt.gravity; a hinge's or slide's stiffness (about springref) and damping as a
  SpringGeneralizedForce on its coordinate; armature as a rotor (a body with inertia a about
  the ground's Z axis, on its own pin) held to the joint's coordinate by a
  CoordinateCouplerConstraint, so its kinetic energy is a qdot^2 / 2 as MuJoCo's; an actuator
  on one hinge or slide at its stated control as an ExpressionBasedCoordinateForce, k F(L, V)
  affine in q and qdot;
- connect: PointConstraint at the compiled anchors; weld: WeldConstraint of the two compiled
  frames (a PointConstraint where torquescale is 0, as MuJoCo has no rotation rows then);
  joint: CoordinateCouplerConstraint, q1 = q1_0 + poly(q2 - q2_0) (PolynomialFunction).

State maps: hinges and slides are MuJoCo's qpos and qvel; a ball's or free joint's angles are
the X-Y-Z angles of R0^T R(q), its speeds the child's angular velocity in the (turned) parent
frame, R_FM omega_local, and a free joint's translation R0^T p; back, the quaternion is
q0 (x) quat(R_FM), the sign of the initial state's q0 (a rotation of less than pi from it keeps
the sign, so a trajectory's quaternion stays continuous). The local angular acceleration is
R_FM^T u' (d/dt R_FM^T = -[w]x R_FM^T and w x w = 0).

Multipliers: the equalities' generalized force -G_eq^T lambda from Simbody's own rows and
multipliers (calcG; the equalities' constraints come first in the ConstraintSet, the rotors'
couplers last), on MuJoCo's qvel through the velocity map, then the minimum-norm multipliers
with that J^T lambda (crosscheck.engines.user_file_model). Simbody solves dependent rows
itself (a planar loop's out-of-plane row: docs/engines/opensim.md has the figures).

Not built, each named in the skip record: armature or damping on a ball or free joint
(MuJoCo's acts on the joint's relative angular velocity in the child's frame; OpenSim's
coordinate forces act on coordinates, and a ball's speeds are not its coordinates' rates), an
actuator on a fixed tendon over several joints (OpenSim's coordinate forces act on one
coordinate each), and a joint equality without a second joint (CoordinateCouplerConstraint
needs an independent coordinate).
"""

from __future__ import annotations

import numpy as np
import opensim as osim

from crosscheck.engines.base import EngineForward, EngineUnsupported
from crosscheck.engines.compiled_model import (
    Equality,
    Joint,
    joint_frame,
    mat_quat,
    quat_matrix,
    quat_mul,
)
from crosscheck.engines.kinematics import rotation_xyz, xyz_angles
from crosscheck.engines.opensim.engine_model import OsimModel, vec3
from crosscheck.engines.user_file_model import (
    QUATERNION_MASS,
    Frame,
    MultiplierAnswer,
    UserFileMaps,
)

__all__ = ["BUILT_FROM", "OsimUserFile", "refusals"]

BUILT_FROM = "OpenSim model built from MuJoCo's compiled model"


def _np3(v) -> np.ndarray:
    return np.array([v.get(0), v.get(1), v.get(2)], float)


def refusals(cm) -> list[str]:
    """What this builder does not express in a compiled model.

    Parameters
    ----------
    cm : crosscheck.engines.compiled_model.CompiledModel

    Returns
    -------
    list of str
        One sentence per element: the element, and why (module docstring).
    """
    out = []
    for j in cm.joints:
        if j.kind in ("ball", "free") and (np.any(j.armature) or np.any(j.damping)):
            what = "armature" if np.any(j.armature) else "damping"
            out.append(
                f"{what} on {j.kind} joint {j.name!r}: MuJoCo's acts on the joint's relative "
                "angular velocity in the child's frame, and OpenSim's coordinate forces act on "
                "coordinates (a ball's speeds are not its coordinates' rates)"
            )
    for a in cm.actuators:
        if len(a.terms) > 1:
            out.append(
                f"actuator {a.name!r} drives a fixed tendon over {len(a.terms)} joints: "
                "OpenSim's coordinate forces act on one coordinate each"
            )
    for e in cm.equalities:
        if e.kind == "joint" and e.joints[1] < 0:
            out.append(
                f"joint equality {e.name!r} has no second joint (joint1 held at a constant): "
                "OpenSim's CoordinateCouplerConstraint needs an independent coordinate"
            )
    return out


def _custom_joint(name, parent, child, at_parent, rot_parent, at_child, coord, axis, slide, qpos0):
    """A CustomJoint with one coordinate (MuJoCo's qpos; the transform reads qpos - qpos0)
    rotating about, or translating along, ``axis`` (the joint frames' components)."""
    st = osim.SpatialTransform()
    base = 3 if slide else 0
    ta = st.updTransformAxis(base)
    names = osim.ArrayStr()
    names.append(coord)  # appended one by one: ArrayStr(name, 1) crashes the constructor
    ta.setCoordinateNames(names)
    ta.setAxis(vec3(*axis))
    f = osim.LinearFunction(1.0, -float(qpos0))
    ta.setFunction(f)
    f.thisown = False  # the transform axis owns it now
    for k, spare in enumerate(joint_frame(axis).T[:2], start=1):
        st.updTransformAxis(base + k).setAxis(vec3(*spare))
    other = 0 if slide else 3
    for k, b in enumerate(np.eye(3)):
        st.updTransformAxis(other + k).setAxis(vec3(*b))
    return osim.CustomJoint(
        name,
        parent,
        vec3(*at_parent),
        vec3(*xyz_angles(rot_parent)),
        child,
        vec3(*at_child),
        vec3(),
        st,
    )


def _poly_in_q2(c, qpos0_1: float, qpos0_2: float) -> list[float]:
    """Coefficients (highest power first, PolynomialFunction's order) of
    q1 = q1_0 + sum c_k (q2 - q2_0)^k as a polynomial in q2."""
    p = np.polynomial.polynomial.Polynomial(np.asarray(c, float))
    p = p(np.polynomial.polynomial.Polynomial([-qpos0_2, 1.0])) + qpos0_1
    coef = np.trim_zeros(np.asarray(p.coef, float), "b")
    return [float(x) for x in coef[::-1]] if coef.size else [0.0]


def _branch_signs(q0, angles) -> np.ndarray:
    """Per row of X-Y-Z angles (a ball's or free joint's R_FM along a run): the sign that keeps
    q0 (x) quat(R_FM) continuous from the first row on (each row's quaternion turned to the one
    nearer the previous row's)."""
    signs, previous = np.ones(len(angles)), None
    for k, a in enumerate(angles):
        q = quat_mul(q0, mat_quat(rotation_xyz(*a)))
        if previous is not None and q @ previous < 0:
            signs[k] = -1.0
        previous = signs[k] * q
    return signs


class OsimUserFile(UserFileMaps, OsimModel):
    """OpenSim's model of a user's MJCF file (see the module docstring)."""

    solver = "Simbody realizeAcceleration (direct constrained solve)"

    def __init__(self, model_name: str, params: dict | None = None):
        self.model_name = model_name
        self._load(model_name, params)
        refused = refusals(self.cm)
        if refused:
            raise EngineUnsupported(
                f"{model_name}: OpenSim's model of the file: " + "; ".join(refused)
            )
        self.mass_matrix_note = QUATERNION_MASS
        q0, u0 = self.imp.model.initial_q, self.imp.model.initial_u  # type: ignore[attr-defined]
        self._q0 = self._initial_rotations(self.mj_state(q0, u0)[0])
        self._R0 = {j: quat_matrix(q) for j, q in self._q0.items()}
        OsimModel.__init__(self, model_name, dict(params or {}))
        self.constrained_solve = bool(self.cm.equalities)
        self.probe_state = osim.State(self.state)  # the rows' kinematics, apart from forward's
        if self.n_multipliers != self.equality_rows + len(self.rotors):
            raise EngineUnsupported(  # _multipliers reads the equalities' rows of G first
                f"{model_name}: Simbody has {self.n_multipliers} constraint rows, the "
                f"equalities {self.equality_rows} and the rotors {len(self.rotors)}"
            )

    # ---- building ----------------------------------------------------------------------------
    def _initial_rotations(self, qpos) -> dict[int, np.ndarray]:
        """The quaternion of each ball and free joint at the initial state (R0 its rotation,
        module docstring; the quaternion's sign is the one read back near that state)."""
        return {
            j.index: np.array(qpos[j.qposadr + (3 if j.kind == "free" else 0) :][:4], float)
            for j in self.cm.joints
            if j.kind in ("ball", "free")
        }

    def _build(self) -> None:
        cm, model = self.cm, self.model
        model.setGravity(vec3(*cm.gravity))
        self.bodies: dict[int, object] = {0: model.getGround()}
        self.coord_specs: list[tuple[Joint, int]] = []  # (joint, component) per coordinate
        self.rotors: list[Joint] = []
        self.actuator_names: list[str] = []
        for b in cm.bodies:
            self._add_body(b)
        self.equality_rows = 0  # Simbody's rows of the equalities: 3 per point, 6 per weld
        for e in cm.equalities:
            model.addConstraint(self._constraint(e))
            self.equality_rows += e.rows
        for j in self.rotors:  # after the equalities: the ConstraintSet's first ones are those
            self._rotor(j)
        for a in cm.actuators:
            self._actuator(a)
        # OpenSim's coordinate index of each (MuJoCo joint, component; -1 for a rotor)
        self.coord_slots: dict[int, dict[int, int]] = {}
        for i, (j, k) in enumerate(self.coord_specs):
            self.coord_slots.setdefault(j.index, {})[k] = i
        self.defaults = self._default_values()

    def _add_body(self, b) -> None:
        model = self.model
        body = osim.Body(
            f"body{b.index}",
            float(b.mass),
            vec3(*b.com),
            osim.Inertia(*np.diag(b.inertia), b.inertia[0, 1], b.inertia[0, 2], b.inertia[1, 2]),
        )
        model.addBody(body)
        parent = self.bodies[b.parent]
        if not b.joints:
            model.addJoint(
                osim.WeldJoint(
                    f"weld{b.index}",
                    parent,
                    vec3(*b.pos),
                    vec3(*xyz_angles(b.rot)),
                    body,
                    vec3(),
                    vec3(),
                )
            )
            self.bodies[b.index] = body
            return
        at, rot = b.pos, b.rot  # the first joint's parent frame: the body's frame in its parent
        for k, j in enumerate(b.joints):
            last = k == len(b.joints) - 1
            child = (
                body if last else osim.Body(f"body{b.index}_{k}", 0.0, vec3(), osim.Inertia(0.0))
            )
            if not last:
                model.addBody(child)
            model.addJoint(self._joint(j, parent, child, at + rot @ j.anchor, rot))
            parent, at, rot = child, np.zeros(3), np.eye(3)
            if j.kind in ("hinge", "slide") and (j.stiffness or np.any(j.damping)):
                self._spring(j)
            if j.kind in ("hinge", "slide") and np.any(j.armature):
                self.rotors.append(j)
        self.bodies[b.index] = body

    def _joint(self, j: Joint, parent, child, at, rot):
        if j.kind in ("hinge", "slide"):
            self.coord_specs.append((j, 0))
            return _custom_joint(
                f"joint{j.index}", parent, child, at, rot, j.anchor, f"q{j.index}",
                j.axis / np.linalg.norm(j.axis), j.kind == "slide", j.qpos0,
            )  # fmt: skip
        R0 = self._R0[j.index]
        if j.kind == "ball":
            joint = osim.BallJoint(
                f"joint{j.index}", parent, vec3(*at), vec3(*xyz_angles(rot @ R0)), child,
                vec3(*j.anchor), vec3(),
            )  # fmt: skip
            names = [f"q{j.index}_r{k}" for k in range(3)]
        else:  # free: qpos is the body's world pose (a top-level body)
            joint = osim.FreeJoint(
                f"joint{j.index}", self.model.getGround(), vec3(), vec3(*xyz_angles(R0)), child,
                vec3(), vec3(),
            )  # fmt: skip
            names = [f"q{j.index}_{s}" for s in ("rx", "ry", "rz", "tx", "ty", "tz")]
        for k, name in enumerate(names):
            joint.upd_coordinates(k).setName(name)
            self.coord_specs.append((j, k))
        return joint

    def _spring(self, j: Joint) -> None:
        f = osim.SpringGeneralizedForce(f"q{j.index}")
        f.setName(f"spring{j.index}")
        f.setStiffness(float(j.stiffness))
        f.setRestLength(float(j.springref))
        f.setViscosity(float(j.damping[0]))
        self.model.addForce(f)

    def _actuator(self, a) -> None:
        """An actuator on one hinge or slide at its stated control: k F(L, V) with L = k q,
        V = k q' on the coordinate (ExpressionBasedCoordinateForce: affine in q and qdot)."""
        ((j, k),) = a.terms
        expr = f"{k * a.constant!r} + {k * k * a.per_length!r}*q + {k * k * a.per_velocity!r}*qdot"
        f = osim.ExpressionBasedCoordinateForce(f"q{j}", expr)
        f.setName(f"actuator_{j}_{len(self.actuator_names)}")
        self.actuator_names.append(a.name)
        self.model.addForce(f)

    def _rotor(self, j: Joint) -> None:
        a = float(j.armature[0])
        rotor = osim.Body(f"rotor{j.index}", 1.0, vec3(), osim.Inertia(a, a, a))
        self.model.addBody(rotor)
        pin = osim.PinJoint(
            f"rotor_pin{j.index}", self.model.getGround(), vec3(), vec3(), rotor, vec3(), vec3()
        )
        pin.upd_coordinates(0).setName(f"rotor{j.index}")
        self.model.addJoint(pin)
        self.coord_specs.append((j, -1))  # a rotor: its angle is the joint's qpos
        c = osim.CoordinateCouplerConstraint()
        c.setName(f"armature{j.index}")
        names = osim.ArrayStr()
        names.append(f"q{j.index}")
        c.setIndependentCoordinateNames(names)
        c.setDependentCoordinateName(f"rotor{j.index}")
        f = osim.LinearFunction(1.0, 0.0)
        c.setFunction(f)
        f.thisown = False
        self.model.addConstraint(c)

    def _side_frame(self, side) -> tuple[object, np.ndarray, np.ndarray]:
        return self.bodies[side.body], side.pos, side.rot

    def _constraint(self, e: Equality):
        if e.kind == "joint":
            j1, j2 = self.cm.joint(e.joints[0]), self.cm.joint(e.joints[1])
            c = osim.CoordinateCouplerConstraint()
            names = osim.ArrayStr()
            names.append(f"q{j2.index}")
            c.setIndependentCoordinateNames(names)
            c.setDependentCoordinateName(f"q{j1.index}")
            f = osim.PolynomialFunction(osim.Vector(_poly_in_q2(e.polycoef, j1.qpos0, j2.qpos0)))
            c.setFunction(f)
            f.thisown = False
        elif e.kind == "connect" or e.torquescale == 0.0:
            (b1, p1, _), (b2, p2, _) = (self._side_frame(s) for s in e.sides)
            c = osim.PointConstraint(b1, vec3(*p1), b2, vec3(*p2))
        else:
            (b1, p1, R1), (b2, p2, R2) = (self._side_frame(s) for s in e.sides)
            c = osim.WeldConstraint(
                f"eq{e.index}",
                b1,
                vec3(*p1),
                vec3(*xyz_angles(R1)),
                b2,
                vec3(*p2),
                vec3(*xyz_angles(R2)),
            )
        c.setName(f"eq{e.index}")
        return c

    def _default_values(self) -> dict[str, float]:
        """The coordinates at the file's initial state (consistent), so initSystem's assembly
        starts on the constraint manifold."""
        q0 = np.asarray(self.imp.model.initial_q, float)  # type: ignore[attr-defined]
        qe, _ = self._engine_state(q0, np.zeros(self.cm.nv))
        return {
            self._coord_name(j, k): float(v) for (j, k), v in zip(self.coord_specs, qe, strict=True)
        }

    @staticmethod
    def _coord_name(j: Joint, k: int) -> str:
        if k < 0:
            return f"rotor{j.index}"
        if j.kind in ("hinge", "slide"):
            return f"q{j.index}"
        names = ("r0", "r1", "r2") if j.kind == "ball" else ("rx", "ry", "rz", "tx", "ty", "tz")
        return f"q{j.index}_{names[k]}"

    # ---- state maps: MuJoCo's (qpos, qvel) <-> OpenSim's coordinates ----------------------
    def _engine_state(self, qpos, qvel) -> tuple[np.ndarray, np.ndarray]:
        qe, ve = [], []
        for j, k in self.coord_specs:
            a, d = j.qposadr, j.dofadr
            if k < 0 or j.kind in ("hinge", "slide"):
                qe.append(qpos[a])
                ve.append(qvel[d])
                continue
            R0 = self._R0[j.index]
            qa = a + 3 if j.kind == "free" else a
            dw = d + 3 if j.kind == "free" else d
            Rfm = R0.T @ quat_matrix(qpos[qa : qa + 4])
            if k < 3:
                qe.append(xyz_angles(Rfm)[k])
                ve.append((Rfm @ qvel[dw : dw + 3])[k])
            else:
                qe.append((R0.T @ qpos[a : a + 3])[k - 3])
                ve.append((R0.T @ qvel[d : d + 3])[k - 3])
        return np.array(qe, float), np.array(ve, float)

    def _mj_state(self, qe, ve) -> tuple[np.ndarray, np.ndarray]:
        qpos, qvel = np.zeros(self.cm.nq), np.zeros(self.cm.nv)
        for j in self.cm.joints:
            idx = self.coord_slots[j.index]
            a, d = j.qposadr, j.dofadr
            if j.kind in ("hinge", "slide"):
                qpos[a], qvel[d] = qe[idx[0]], ve[idx[0]]
                continue
            R0 = self._R0[j.index]
            Rfm = rotation_xyz(*[qe[idx[k]] for k in range(3)])
            w = Rfm.T @ np.array([ve[idx[k]] for k in range(3)])
            if j.kind == "free":
                qpos[a : a + 3] = R0 @ np.array([qe[idx[k]] for k in range(3, 6)])
                qvel[d : d + 3] = R0 @ np.array([ve[idx[k]] for k in range(3, 6)])
                a, d = a + 3, d + 3
            qpos[a : a + 4] = quat_mul(self._q0[j.index], mat_quat(Rfm))  # near q0's sign
            qvel[d : d + 3] = w
        return qpos, qvel

    def _qacc(self, qe, ae) -> np.ndarray:
        """MuJoCo's qacc from OpenSim's u' (a ball's or free joint's angular part: the local
        angular acceleration R_FM^T u', since d/dt R_FM^T = -[w]x R_FM^T and w x w = 0)."""
        qacc = np.zeros(self.cm.nv)
        for j in self.cm.joints:
            ix, d = self.coord_slots[j.index], j.dofadr
            if j.kind in ("hinge", "slide"):
                qacc[d] = ae[ix[0]]
                continue
            Rfm = rotation_xyz(*[qe[ix[k]] for k in range(3)])
            alpha = Rfm.T @ np.array([ae[ix[k]] for k in range(3)])
            if j.kind == "free":
                qacc[d : d + 3] = self._R0[j.index] @ np.array([ae[ix[k]] for k in range(3, 6)])
                d += 3
            qacc[d : d + 3] = alpha
        return qacc

    def _acc_to_reference(self, qe, ve, ae):
        qpos, qvel = self.recall(qe, *self._mj_state(qe, ve))
        return self.reference_accelerations(qpos, qvel, self._qacc(qe, ae))

    # ---- rows and multipliers ----------------------------------------------------------------
    def _side_frames(self, qpos, qvel) -> list[tuple[Frame, Frame]]:
        s = self.probe_state
        qe, ve = self._engine_state(qpos, qvel)
        self._set_state_on(s, qe, ve, 0.0)
        self.model.realizeVelocity(s)
        out = []
        for e in self.cm.equalities:
            if e.kind != "joint":
                out.append(tuple(self._frame_motion(side, s) for side in e.sides))
        return out  # type: ignore[return-value]

    def _frame_motion(self, side, s) -> Frame:
        body = self.bodies[side.body]
        T = body.getTransformInGround(s)  # held while read: views into temporaries
        Rt = T.R()
        R = np.array([[Rt.get(i, k) for k in range(3)] for i in range(3)])
        p = _np3(T.p())
        sv = body.getVelocityInGround(s)
        w, v = _np3(sv.get(0)), _np3(sv.get(1))
        r = R @ side.pos
        return R @ side.rot, p + r, w, v + np.cross(w, r)

    def _multipliers(self, lam_s):
        """The equalities' generalized force -G_eq^T lambda_eq from Simbody's own rows and
        multipliers (the equalities' constraints come first in the ConstraintSet, so their
        rows are G's first ones; the rotors' couplers come last), on MuJoCo's qvel through the
        velocity map (power: N^T force, v_e = N qvel), then the reference's terms."""
        qe, ve = self._read(self.state.getQ()), self._read(self.state.getU())
        qpos, _ = self.recall(qe, *self._mj_state(qe, ve))
        G = osim.Matrix()
        self.model.getMatterSubsystem().calcG(self.state, G)
        m = self.equality_rows
        Ge = np.asarray(G.to_numpy(), float).reshape(-1, self.nu_e)[:m][:, self._u_index]
        force = -Ge.T @ np.asarray(lam_s, float)[:m]
        N = self.velocity_map(qpos)
        self._answer: MultiplierAnswer = self.multiplier_answer(qpos, force=N.T @ force)
        return self._answer.multipliers

    def forward(self, q, u, t: float = 0.0) -> EngineForward:
        ef = super().forward(q, u, t)
        ef.raw["model_source"] = BUILT_FROM
        return self.apply_multipliers(ef, self._answer)

    def simulate(self, q0, u0, t_eval, **kw):
        """OsimModel.simulate with each quaternion read back on the branch the motion keeps:
        q and -q are one rotation, and q0 (x) quat(R_FM) changes sign where the rotation from
        R0 passes pi (a free body spinning), so the branch is followed through every step the
        Manager took (its states table) and each output takes the sign it has there."""
        tr = super().simulate(q0, u0, t_eval, **kw)
        table = self.last_states_table
        times = np.asarray(table.getIndependentColumn(), float)
        values = np.asarray(table.getMatrix().to_numpy(), float).reshape(len(times), -1)
        labels = list(table.getColumnLabels())
        rows = np.searchsorted(times, tr.t, side="right") - 1  # each output's last row
        for j in self.cm.joints:
            if j.kind not in ("ball", "free"):
                continue
            cols = [labels.index(f"/jointset/joint{j.index}/{self._coord_name(j, k)}/value")
                    for k in range(3)]  # fmt: skip
            sign = _branch_signs(self._q0[j.index], values[:, cols])[rows]
            a = j.qposadr + (3 if j.kind == "free" else 0)
            tr.q[:, a : a + 4] *= sign[:, None]
            tr.u[:, a : a + 4] *= sign[:, None]
        return tr

    def _engine_mass_matrix(self, qe) -> np.ndarray:
        """Simbody's M (SimbodyMatterSubsystem.calcM) at qe, in OpenSim's coordinate order."""
        s = self.probe_state
        self._set_state_on(s, qe, np.zeros(self.nu_e), 0.0)
        self.model.realizePosition(s)
        M = osim.Matrix()
        self.model.getMatterSubsystem().calcM(s, M)
        M = np.asarray(M.to_numpy(), float).reshape(self.nu_e, self.nu_e)
        return M[np.ix_(self._u_index, self._u_index)]

    def _energy_of(self, state) -> tuple[float, float]:
        """Kinetic and potential energy from OpenSim, plus the joint springs' k (q - q_ref)^2 / 2,
        which Model.calcPotentialEnergy leaves out."""
        self.model.realizeVelocity(state)
        V = float(self.model.calcPotentialEnergy(state))
        cs = self.model.getCoordinateSet()
        for j in self.cm.joints:
            if j.kind in ("hinge", "slide") and j.stiffness:
                V += 0.5 * j.stiffness * (cs.get(f"q{j.index}").getValue(state) - j.springref) ** 2
        return float(self.model.calcKineticEnergy(state)), V
