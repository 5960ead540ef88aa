"""Pinocchio's model of a user's MJCF file, built from MuJoCo's compiled model.

Pinocchio's own MJCF parser loses dynamics on real files (it ignores <option gravity>, does
not parse joint stiffness, leaves damping unapplied, drops `joint` equalities; what it kept on
a given file is ``parser_findings``), so the model whose dynamics are compared is built from
MuJoCo's compiled numbers instead, element by element, and solved by Pinocchio's algorithms:

- bodies in MuJoCo's order; a body's frame is body_pos/body_quat in its parent's; each hinge or
  slide is a RevoluteUnaligned / PrismaticUnaligned joint about jnt_axis through jnt_pos (a
  second joint on the same body is placed relative to the first, T(p2 - p1), as
  mj_kinematics composes them); ball -> Spherical, free -> FreeFlyer; a body without joints is
  appended to its parent's joint;
- inertia: body_mass at body_ipos with body_inertia rotated by body_iquat; gravity from
  opt.gravity; armature in model.armature;
- passive forces as tau: -dof_damping qvel - stiffness (qpos - springref) on hinges and slides;
  the actuators at their stated controls as tau (reference.mjcf.actuators: MuJoCo's gain and
  bias force through the joint or fixed tendon);
- equality rows from Pinocchio's kinematics: connect p1 - p2 at the compiled anchors (frame
  Jacobians, LOCAL_WORLD_ALIGNED; J-dot v the anchors' classical accelerations at a = 0), weld
  the same plus the rotation rows torquescale/2 R2^T (omega1 - omega2) (the reference's rows on
  the manifold, reference.mjcf.loader; none for a weld with torquescale 0, as the reference),
  joint q1 - poly(q2);
- the solve: pin.forwardDynamics(model, data, q, v, tau, J, gamma), Pinocchio's exact KKT, on
  an independent subset of the rows (pivoted QR of J^T; a planar loop closed by a 3-D connect
  has a dependent row that makes the Delassus matrix singular), the forces then expressed as
  the minimum-norm multipliers of all rows with the same J^T lambda (reference.numeric.redundant),
  and J^T lambda itself in Pinocchio's speeds (``constraint_forces``); a quaternion's
  unit-norm row has no Pinocchio counterpart and alone is left out (``multiplier_rows``), and
  the mass matrix of a file with quaternions is compared in Pinocchio's speeds.

State: Pinocchio's q is MuJoCo's qpos with hinge/slide offsets removed (q - qpos0: Pinocchio's
joints are at zero in the compiled pose) and quaternions as (x, y, z, w); v is qvel (a free
joint's linear part in the body frame, MuJoCo's in the world frame).
"""

from __future__ import annotations

import time

import mujoco
import numpy as np
import pinocchio as pin
import scipy.linalg

from crosscheck.engines.base import EngineForward, EngineModel, EngineTrajectory
from crosscheck.engines.mujoco.user_file import (
    QUATERNION_NOTE,
    equality_rows,
    rate_derivatives,
    user_import,
)

JNT = mujoco.mjtJoint
EQ = mujoco.mjtEq
# the pivoted QR's rank cut on J^T: rows whose residual pivot is below this times the largest
# are dependent (the four-bar's out-of-plane row is ~1e-17 of the others; independent rows of
# the test files are above 1e-3)
RANK_RTOL = 1e-10
BUILT_FROM = "Pinocchio model built from MuJoCo's compiled model (not pin's MJCF parser)"


def _se3(quat_wxyz, pos) -> pin.SE3:
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat_wxyz, float))
    return pin.SE3(R.reshape(3, 3), np.asarray(pos, float))


def _body_inertia(m, b) -> pin.Inertia:
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, np.asarray(m.body_iquat[b], float))
    R = R.reshape(3, 3)
    return pin.Inertia(
        float(m.body_mass[b]), np.array(m.body_ipos[b], float), R @ np.diag(m.body_inertia[b]) @ R.T
    )


def build_pin_model(m):
    """(pin.Model, body -> (joint id, body frame in that joint's frame), MuJoCo joint -> pin
    joint id) from MuJoCo's compiled model m."""
    model = pin.Model()
    place: dict[int, tuple[int, pin.SE3]] = {0: (0, pin.SE3.Identity())}
    jmap: dict[int, int] = {}
    for b in range(1, m.nbody):
        parent_joint, parent_in_joint = place[int(m.body_parentid[b])]
        frame = parent_in_joint * _se3(m.body_quat[b], m.body_pos[b])  # body in parent joint
        joint, prev = parent_joint, np.zeros(3)
        for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]):
            t, pos = int(m.jnt_type[j]), np.array(m.jnt_pos[j], float)
            axis = np.array(m.jnt_axis[j], float)
            if t == int(JNT.mjJNT_HINGE):
                jm = pin.JointModelRevoluteUnaligned(axis)
            elif t == int(JNT.mjJNT_SLIDE):
                jm = pin.JointModelPrismaticUnaligned(axis)
            elif t == int(JNT.mjJNT_BALL):
                jm = pin.JointModelSpherical()
            else:  # MuJoCo's free joint: qpos is the body's world pose (a top-level body)
                jm, pos, frame = pin.JointModelFreeFlyer(), np.zeros(3), pin.SE3.Identity()
            placement = frame * pin.SE3(np.eye(3), pos - prev)
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
            joint = model.addJoint(joint, jm, placement, name)
            jmap[j] = joint
            model.armature[model.idx_vs[joint] : model.idx_vs[joint] + model.nvs[joint]] = (
                m.dof_armature[m.jnt_dofadr[j] : m.jnt_dofadr[j] + model.nvs[joint]]
            )
            frame, prev = pin.SE3.Identity(), pos
        body_in_joint = frame * pin.SE3(np.eye(3), -prev)
        model.appendBodyToJoint(joint, body_in_joint.act(_body_inertia(m, b)), pin.SE3.Identity())
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or f"body{b}"
        model.addFrame(pin.Frame(name, joint, body_in_joint, pin.FrameType.BODY))
        place[b] = (joint, body_in_joint)
    from reference.mjcf.checks import disabled

    model.gravity.linear = (
        np.zeros(3) if disabled(m, "mjDSBL_GRAVITY") else np.array(m.opt.gravity, float)
    )
    return model, place, jmap


class UserFilePinModel(EngineModel):
    """Pinocchio on a user's MJCF file (see the module docstring)."""

    engine = "pinocchio"
    solver = "pin.forwardDynamics (KKT on the independent rows)"

    def __init__(self, model_name: str, params: dict | None = None):
        self.model_name = model_name
        self.imp = user_import(model_name)
        m = self.mj = self.imp.mj
        self.model, place, self.jmap = build_pin_model(m)
        self.data = self.model.createData()
        self.mass_matrix_note = None
        self._quat = any(
            ji.type in (int(JNT.mjJNT_BALL), int(JNT.mjJNT_FREE)) for ji in self.imp.joints
        )
        self._answered = equality_rows(self.imp)
        self._m_ref = len(self.imp.model.constraint_names)
        self._eq = self._equalities(place)
        self.constrained_solve = bool(self._eq)

    # ---- state maps ------------------------------------------------------------------------
    def _pin_state(self, qpos, qvel):
        m, q, v = self.mj, np.zeros(self.model.nq), np.array(qvel, float)
        for j, jid in self.jmap.items():
            a, iq, iv = m.jnt_qposadr[j], self.model.idx_qs[jid], self.model.idx_vs[jid]
            t = int(m.jnt_type[j])
            if t in (int(JNT.mjJNT_HINGE), int(JNT.mjJNT_SLIDE)):
                q[iq] = qpos[a] - m.qpos0[a]
                continue
            if t == int(JNT.mjJNT_FREE):
                q[iq : iq + 3] = qpos[a : a + 3]
                R = _se3(qpos[a + 3 : a + 7], np.zeros(3)).rotation
                v[iv : iv + 3] = R.T @ np.asarray(qvel[m.jnt_dofadr[j] : m.jnt_dofadr[j] + 3])
                a, iq = a + 3, iq + 3
            w, x, y, z = qpos[a : a + 4]
            q[iq : iq + 4] = (x, y, z, w)
        return q, v

    def _mj_state(self, q, v):
        m, qpos, qvel = self.mj, np.zeros(self.mj.nq), np.array(v, float)
        for j, jid in self.jmap.items():
            a, iq, iv = m.jnt_qposadr[j], self.model.idx_qs[jid], self.model.idx_vs[jid]
            t = int(m.jnt_type[j])
            if t in (int(JNT.mjJNT_HINGE), int(JNT.mjJNT_SLIDE)):
                qpos[a] = q[iq] + m.qpos0[a]
                continue
            if t == int(JNT.mjJNT_FREE):
                qpos[a : a + 3] = q[iq : iq + 3]
                x, y, z, w = q[iq + 3 : iq + 7]
                R = _se3((w, x, y, z), np.zeros(3)).rotation
                qvel[iv : iv + 3] = R @ np.asarray(v[iv : iv + 3])
                a, iq = a + 3, iq + 3
            x, y, z, w = q[iq : iq + 4]
            qpos[a : a + 4] = (w, x, y, z)
        return qpos, qvel

    def to_engine_state(self, q, u):
        from reference.mjcf.loader import qvel_from_rates

        q = np.asarray(q, float)
        return self._pin_state(
            q, qvel_from_rates(self.imp.joints, q, np.asarray(u, float), self.mj.nv)
        )

    def from_engine_state(self, qe, ve):
        from reference.mjcf.loader import rates_from_qvel

        qpos, qvel = self._mj_state(qe, ve)
        return qpos, rates_from_qvel(self.imp.joints, qpos, qvel)

    def _qacc(self, qe, ve, ae):
        """MuJoCo's qacc from Pinocchio's a (a free joint's linear part: the world derivative
        of R v_local is R (a_local + omega x v_local))."""
        qacc = np.array(ae, float)
        for j, jid in self.jmap.items():
            if int(self.mj.jnt_type[j]) != int(JNT.mjJNT_FREE):
                continue
            iq, iv = self.model.idx_qs[jid], self.model.idx_vs[jid]
            x, y, z, w = qe[iq + 3 : iq + 7]
            R = _se3((w, x, y, z), np.zeros(3)).rotation
            vl, om = np.asarray(ve[iv : iv + 3]), np.asarray(ve[iv + 3 : iv + 6])
            qacc[iv : iv + 3] = R @ (np.asarray(ae[iv : iv + 3]) + np.cross(om, vl))
        return qacc

    # ---- forces and rows ---------------------------------------------------------------------
    def _tau(self, qe, ve) -> np.ndarray:
        qpos, qvel = self._mj_state(qe, ve)
        m = self.mj
        tau = -np.asarray(m.dof_damping) * qvel
        for j, jid in self.jmap.items():
            if int(m.jnt_type[j]) in (int(JNT.mjJNT_HINGE), int(JNT.mjJNT_SLIDE)):
                a = m.jnt_qposadr[j]
                tau[self.model.idx_vs[jid]] -= m.jnt_stiffness[j] * (qpos[a] - m.qpos_spring[a])
        # the actuators act on hinges and slides only, whose dofs are the same in both
        tau += self.imp.actuation.qfrc(qpos, qvel, m.nv)
        # tau is in Pinocchio's v; damping on a free joint's linear dofs is refused by the import
        return tau

    def _equalities(self, place):
        """One entry per active equality: (kind, frame ids..., data) for the rows."""
        m, out = self.mj, []
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        for e in range(m.neq):
            if not m.eq_active0[e]:
                continue
            t = int(m.eq_type[e])
            if t in (int(EQ.mjEQ_CONNECT), int(EQ.mjEQ_WELD)):
                weld = t == int(EQ.mjEQ_WELD)
                frames = []
                for side in (0, 1):
                    obj = (m.eq_obj1id, m.eq_obj2id)[side][e]
                    if m.eq_objtype[e] == mujoco.mjtObj.mjOBJ_SITE:
                        body = int(m.site_bodyid[obj])
                        local = _se3(m.site_quat[obj], m.site_pos[obj])
                    else:
                        body, k = int(obj), (1 - side) if weld else side
                        local = pin.SE3(np.eye(3), np.array(m.eq_data[e, 3 * k : 3 * k + 3]))
                    joint, body_in_joint = place[body]
                    frames.append(
                        self.model.addFrame(
                            pin.Frame(
                                f"eq{e}_{side}",
                                joint,
                                body_in_joint * local,
                                pin.FrameType.OP_FRAME,
                            )
                        )
                    )
                ts = float(m.eq_data[e, 10]) if weld else 0.0
                out.append(("weld" if weld else "connect", frames, ts))
            elif t == int(EQ.mjEQ_JOINT):
                j1, j2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
                out.append(("joint", (j1, j2), np.array(m.eq_data[e, :5], float)))
        self.data = self.model.createData()
        return out

    def _rows(self, qe, ve):
        """J (rows, nv) and gamma = J-dot v of the equality rows (J a + gamma = 0)."""
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, qe, ve, np.zeros(model.nv))
        pin.computeJointJacobians(model, data, qe)
        pin.updateFramePlacements(model, data)
        LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        Js, gs = [], []
        for kind, objs, extra in self._eq:
            if kind == "joint":
                j1, j2 = objs
                row = np.zeros(model.nv)
                row[model.idx_vs[self.jmap[j1]]] = 1.0
                g = 0.0
                if j2 >= 0:
                    c = extra
                    x = qe[model.idx_qs[self.jmap[j2]]]  # MuJoCo's qpos - qpos0
                    v2 = ve[model.idx_vs[self.jmap[j2]]]
                    row[model.idx_vs[self.jmap[j2]]] = -(
                        c[1] + 2 * c[2] * x + 3 * c[3] * x**2 + 4 * c[4] * x**3
                    )
                    g = -(2 * c[2] + 6 * c[3] * x + 12 * c[4] * x**2) * v2**2
                Js.append(row[None])
                gs.append(np.array([g]))
                continue
            # (6, nv): pin hands a model with one dof its Jacobian as a vector
            J = [np.reshape(pin.getFrameJacobian(model, data, f, LWA), (6, model.nv)) for f in objs]
            acc = [pin.getFrameClassicalAcceleration(model, data, f, LWA) for f in objs]
            Js.append(J[0][:3] - J[1][:3])
            gs.append(acc[0].linear - acc[1].linear)
            if kind == "weld" and extra != 0.0:  # torquescale 0: no rotation rows
                R2 = data.oMf[objs[1]].rotation
                Js.append(0.5 * extra * R2.T @ (J[0][3:] - J[1][3:]))
                gs.append(0.5 * extra * R2.T @ (acc[0].angular - acc[1].angular))
        if not Js:
            return np.zeros((0, model.nv)), np.zeros(0)
        return np.vstack(Js), np.concatenate(gs)

    # ---- answers -----------------------------------------------------------------------------
    def _solve(self, qe, ve):
        """(a, lambda, rank, J^T lambda in Pinocchio's v) at an engine state."""
        model, data = self.model, self.data
        tau = self._tau(qe, ve)
        J, gamma = self._rows(qe, ve)
        if J.shape[0] == 0:
            return pin.aba(model, data, qe, ve, tau), np.zeros(0), 0, np.zeros(model.nv)
        _Q, Rq, piv = scipy.linalg.qr(J.T, mode="economic", pivoting=True)
        diag = np.abs(np.diag(Rq))
        rank = int(np.sum(diag > RANK_RTOL * diag[0]))
        keep = np.sort(piv[:rank])
        a = pin.forwardDynamics(model, data, qe, ve, tau, J[keep], gamma[keep])
        generalized = J[keep].T @ np.array(data.lambda_c, float)
        lam = np.linalg.pinv(J.T, rcond=1e-12) @ generalized
        return np.array(a, float), lam, rank, generalized

    def _linear_part(self, fun, n: int) -> np.ndarray:
        """The matrix of a map linear in its argument (the state maps at a fixed q)."""
        return np.column_stack([np.asarray(fun(e), float) for e in np.eye(n)])

    def forward(self, q, u, t: float = 0.0) -> EngineForward:
        qe, ve = self.to_engine_state(q, u)
        a, lam, rank, generalized = self._solve(qe, ve)
        qpos, qvel = self._mj_state(qe, ve)
        acc = rate_derivatives(self.imp.joints, qpos, qvel, self._qacc(qe, ve, a))
        raw = {
            "engine_accelerations": a,
            "rank": rank,
            "rows": len(lam),
            "model_source": BUILT_FROM,
        }
        multipliers = np.zeros(self._m_ref)  # the quaternion norm rows: none in Pinocchio
        multipliers[list(self._answered)] = lam
        H = self._linear_part(lambda dv: self.from_engine_state(qe, dv)[1], self.model.nv)
        return EngineForward(
            acc,
            multipliers,
            raw,
            multipliers_note=QUATERNION_NOTE if self._quat else None,
            iterations=1 if len(lam) else 0,
            multiplier_rows=self._answered if self._quat else None,
            constraint_forces=generalized if len(lam) else None,
            speed_map=H,
        )

    def derivatives(self, q, u, t, directions):
        """Pinocchio's analytical derivatives, the file's rows as its constraint models
        (crosscheck/engines/pinocchio/user_file_derivatives.py)."""
        from crosscheck.engines.linearization import derivatives_along
        from crosscheck.engines.pinocchio.user_file_derivatives import UserFileDerivatives

        if "_derivatives" not in self.__dict__:
            self._derivatives = UserFileDerivatives(self)
        return derivatives_along(self._derivatives.maps(), q, u, directions)

    def energy(self, q, u) -> tuple[float, float]:
        qe, ve = self.to_engine_state(q, u)
        model, data, m = self.model, self.data, self.mj
        K = pin.computeKineticEnergy(model, data, qe, ve)
        K += 0.5 * float(self._armature_not_in_K() @ (ve * ve))
        # pin sums joints 1.., so bodies welded to the world (inertias[0]) are added here:
        # MuJoCo's d.energy and the reference count them (a constant)
        I0 = model.inertias[0]
        V = pin.computePotentialEnergy(model, data, qe) - I0.mass * float(
            model.gravity.linear @ I0.lever
        )
        qpos, _ = self._mj_state(qe, ve)
        for j in self.jmap:
            if int(m.jnt_type[j]) in (int(JNT.mjJNT_HINGE), int(JNT.mjJNT_SLIDE)):
                a = m.jnt_qposadr[j]
                V += 0.5 * m.jnt_stiffness[j] * (qpos[a] - m.qpos_spring[a]) ** 2
        return float(K), float(V)

    def _armature_not_in_K(self) -> np.ndarray:
        """The armature pin's kinetic energy leaves out, per dof (checked once, dof by dof:
        pin 4.1 counts a PrismaticUnaligned joint's armature in computeKineticEnergy and not a
        RevoluteUnaligned one's, so a file with both needs each dof's own answer)."""
        if not hasattr(self, "_arm_k"):
            model = self.model
            data = model.createData()
            q = pin.neutral(model)
            M = pin.crba(model, data, q)
            M = np.triu(M) + np.triu(M, 1).T
            missing = np.zeros(model.nv)
            for k, v in enumerate(np.eye(model.nv)):
                gap = 0.5 * M[k, k] - pin.computeKineticEnergy(model, data, q, v)
                armature = float(model.armature[k])
                missing[k] = (
                    armature if abs(gap - 0.5 * armature) <= 1e-12 * max(1, M[k, k]) else 0.0
                )
            self._arm_k = missing
        return self._arm_k

    def violation(self, qe, ve) -> tuple[float, float]:
        """Position and velocity residuals of the equality rows (max abs) at an engine state:
        connect/weld points p1 - p2 (the weld's rotation rows by their rate only), joint
        q1 - poly(q2)."""
        J, _g = self._rows(qe, ve)  # also updates the frame placements at qe
        pos = [0.0]
        for kind, objs, extra in self._eq:
            if kind == "joint":
                j1, j2 = objs
                x1 = qe[self.model.idx_qs[self.jmap[j1]]]
                x2 = qe[self.model.idx_qs[self.jmap[j2]]] if j2 >= 0 else 0.0
                pos.append(abs(x1 - sum(c * x2**k for k, c in enumerate(extra))))
            else:
                dp = self.data.oMf[objs[0]].translation - self.data.oMf[objs[1]].translation
                pos.append(float(np.max(np.abs(dp))))
        return max(pos), float(np.max(np.abs(J @ ve), initial=0.0))

    def simulate(
        self,
        q0,
        u0,
        t_eval,
        *,
        integrator: str,
        rtol: float | None = None,
        timestep: float | None = None,
    ) -> EngineTrajectory:
        """solve_ivp (method `integrator`, rtol = atol) on Pinocchio's forward dynamics, no
        constraint stabilization (as the built-in models, machinery.PinEngineModel.simulate):
        in the reference's coordinates (qpos and coordinate rates: q' = u, u' = forward())
        where the file has hinges and slides only, they being Pinocchio's too; with ball or free
        joints in Pinocchio's own (q_e, v_e), quaternions renormalized (ode.py), as the
        built-in models are: off the unit sphere the reference's quaternion rates carry a
        radial part Pinocchio's velocities do not, and integrated in those coordinates its
        drift, and the energy error with it, grows 15x faster (MuJoCo's connect.xml: position
        drift 7.1e-9 against the reference's index-1 4.7e-10 over 5 s at rtol 1e-10)."""
        from scipy.integrate import solve_ivp

        from crosscheck.engines.pinocchio.engine_model import (
            check_integrator,
            ivp_method,
            ivp_trajectory,
        )
        from crosscheck.engines.pinocchio.ode import joint_layout, normalized, right_hand_side

        check_integrator(integrator, rtol)
        t_start = time.perf_counter()
        t_eval = np.asarray(t_eval, dtype=float)
        if self._quat:
            layout = joint_layout(self.model)
            rhs = right_hand_side(layout, lambda qe, ve, t: self._solve(qe, ve)[0])
            y0 = np.concatenate(self.to_engine_state(q0, u0))
            n, where = self.model.nq, "Pinocchio's (q, v), quaternions renormalized"
        else:
            layout, n, where = None, len(q0), "reference (qpos, rates)"
            y0 = np.concatenate([q0, u0])

            def rhs(t, y):
                return np.concatenate([y[n:], self.forward(y[:n], y[n:]).accelerations])

        sol = solve_ivp(
            rhs,
            (0.0, float(t_eval[-1])),
            y0,
            method=ivp_method(integrator),
            rtol=rtol,
            atol=rtol,
            t_eval=t_eval,
        )
        rows = []
        for y in sol.y.T:
            if layout is None:
                q, u = y[:n], y[n:]
                qe, ve = self.to_engine_state(q, u)
            else:
                qe, ve = normalized(layout, y[:n]), y[n:]
                q, u = self.from_engine_state(qe, ve)
            rows.append((q, u, *self.violation(qe, ve), sum(self.energy(q, u))))
        return ivp_trajectory(
            sol, rows, integrator, rtol, t_start, {"stabilization": "none", "coordinates": where}
        )

    def _crba(self, qe) -> np.ndarray:
        M = pin.crba(self.model, self.data, qe)
        return np.triu(M) + np.triu(M, 1).T

    def mass_matrix(self, q) -> np.ndarray | None:
        if self._quat:
            return None  # mass_matrix_in_engine_speeds
        return self._crba(self.to_engine_state(q, np.zeros(len(q)))[0])

    def mass_matrix_in_engine_speeds(self, q):
        """Pinocchio's M (crba) and H (u = H v) for a file with quaternions."""
        if not self._quat:
            return None
        qe, _ = self.to_engine_state(q, np.zeros(len(q)))
        H = self._linear_part(lambda dv: self.from_engine_state(qe, dv)[1], self.model.nv)
        return self._crba(qe), H

    def fingerprint(self) -> str:
        """SHA-256 of the file and the stated controls."""
        import hashlib
        from pathlib import Path

        h = hashlib.sha256(Path(self.imp.path).read_bytes())
        h.update(repr(sorted(self.imp.actuation.controls.items())).encode())
        return h.hexdigest()
