"""Pinocchio models of Exercises 6.1, 6.2 and 6.4 (geometry as assumed in the reference's
docstrings)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from crosscheck.engines.pinocchio.engine_model import PROX_REDUNDANT, PinEngineModel, at, lamina

# ======================================================================================
# Exercises 6.1, 6.2, 6.4 (geometry as assumed in the reference's docstrings)


# ======================================================================================


class Exercise61(PinEngineModel):
    """Exercise 6.1 (Y up): bar with end A on the X guide and end B on the Y guide, block P
    fixed to B. Engine: root slide PX (x, the massless end slider A, spring k and damper c on
    it), the bar hinged at A with its axis A -> B as the hinge frame's x axis (angle
    phi = theta + pi/2 from +X, mass center at (l/2, 0, 0), planar-lamina inertia from
    m l^2/12), root slide PY (y) carrying the block m_p with F pushing it down; loop closed at
    B between the bar end (l, 0, 0) and the block (CONTACT_3D, PROX_REDUNDANT: the z row is 0).
    q_e = (x, theta + pi/2, y). tau = (-k x - c x', 0, -F).

    Multipliers. The reference's (lambda1, lambda2) are generalized forces conjugate to x and
    y in its relaxed coordinates (the bar's mass center G = (x/2, y/2), theta free), yet they
    are fixed by the mechanism's forces. Let F_A, F_B be the forces on the bar at A and B
    (world axes). The bar's Newton equations m x''/2 = F_Ax + F_Bx, m y''/2 = F_Ay + F_By - m g,
    the massless slider's F_Ax = -k x - c x' and the block's m_p y'' = -F_By - m_p g - F, put
    into the reference's rows (1/4) m x'' + c x' + k x = lambda1 and
    ((1/4) m + m_p) y'' + ((1/2) m + m_p) g = lambda2 - F, give
        lambda1 = (F_Bx - F_Ax) / 2,   lambda2 = (F_Ay - F_By) / 2,
    and these satisfy its theta row too: the moment of F_A, F_B about G (A - G = (l/2)(S, -C),
    B - G = -(A - G)) is (l/2)(S (F_Ay - F_By) - C (F_Bx - F_Ax)) = l (-lambda1 C + lambda2 S).
    In the engine F_B = contact_force (the block's force on the bar at B) and F_A is the
    slider's force on the bar through the hinge: rnea's data.f of the bar joint with the
    closure force applied as an external force (_rnea_with_constraint_forces), rotated to
    world axes. raw["pin_A_force_momentum"] is F_A recomputed independently from the bar's
    momentum balance m a_G - m g_vec - F_B (a_G from forwardKinematics) and
    raw["spring_damper_force"] is tau_x = -k x - c x' (= F_Ax: the slider is massless).

    mass_matrix is None: the reference's M is that of its relaxed coordinates."""

    nq_ref = n_ref = 3
    solver = "constraint"
    prox_settings = PROX_REDUNDANT
    mass_matrix_note = (
        "the reference's M belongs to its relaxed dependent coordinates "
        "(x, y, theta independent, the bar's mass center at (x/2, y/2)), which "
        "no engine model of the mechanism has: the engine's (x, bar angle, y) "
        "are tied by the closure at B"
    )

    def _build(self):
        p = self.params
        jA = self.model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
        jb = self.model.addJoint(jA, pin.JointModelRZ(), pin.SE3.Identity(), "bar")
        self.model.appendBodyToJoint(
            jb,
            pin.Inertia(
                p["m"], np.array([p["l"] / 2, 0.0, 0.0]), lamina(p["m"] * p["l"] ** 2 / 12)
            ),
            pin.SE3.Identity(),
        )
        jP = self.model.addJoint(0, pin.JointModelPY(), pin.SE3.Identity(), "y")
        self.model.appendBodyToJoint(
            jP, pin.Inertia(p["m_p"], np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity()
        )
        self.cms.append(
            pin.RigidConstraintModel(
                pin.ContactType.CONTACT_3D,
                self.model,
                jb,
                at(p["l"], 0, 0),
                jP,
                pin.SE3.Identity(),
                pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
            )
        )
        self.j_bar = jb
        self.G = at(p["l"] / 2, 0, 0)

    def _applied(self, qe, ve, t):
        p = self.params
        return np.array([-p["k"] * qe[0] - p["c"] * ve[0], 0.0, -p["F"]])

    def _spring_potential(self, qe):
        return 0.5 * self.params["k"] * qe[0] ** 2

    def to_engine_state(self, q, u):
        x, y, th = np.asarray(q, float)
        xd, yd, thd = np.asarray(u, float)
        return np.array([x, th + math.pi / 2, y]), np.array([xd, thd, yd])

    def from_engine_state(self, qe, ve):
        return (np.array([qe[0], qe[2], qe[1] - math.pi / 2]), np.array([ve[0], ve[2], ve[1]]))

    def _acc_to_reference(self, qe, ve, ae):
        return np.array([ae[0], ae[2], ae[1]])

    def _end_forces(self, qe, ve, ae, lam_e):
        """(F_A, F_B), the forces on the bar at A (the slider's, rnea) and at B (the block's,
        contact_force), world axes."""
        self._rnea_with_constraint_forces(qe, ve, ae, lam_e)
        d = self.data
        F_A = d.oMi[self.j_bar].rotation @ d.f[self.j_bar].linear
        return F_A, np.array(lam_e[0:3], float)

    def _multipliers(self, qe, ve, ae, lam_e):
        F_A, F_B = self._end_forces(qe, ve, ae, lam_e)
        return np.array([0.5 * (F_B[0] - F_A[0]), 0.5 * (F_A[1] - F_B[1])])

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        F_A, F_B = self._end_forces(qe, ve, ae, lam_e)
        raw["force_of_block_on_bar_at_B"] = F_B
        raw["pin_A_force_rnea"] = F_A
        pin.forwardKinematics(self.model, self.data, qe, ve, ae)
        a_G = self._anchor_classical_acc(self.j_bar, self.G)
        mb = self.params["m"]
        raw["pin_A_force_momentum"] = mb * a_G - mb * self.model.gravity.linear - F_B
        raw["spring_damper_force"] = float(self._applied(qe, ve, 0.0)[0])


class Exercise62(PinEngineModel):
    """Exercise 6.2 (Y DOWN in the reference, Y up in the engine): block m1 on a root slide PX
    (x; spring k, damper c and F on it), the slender bar hinged at A = the block's origin,
    hanging along -Y_e at theta = 0 (mass center (0, -l/2, 0) in the hinge frame, so the hinge
    angle is theta), planar-lamina inertia from m2 l^2/12. Engine q = (x, theta); the
    reference's dependent (x_G, y_G) = G - A with y down: read from forwardKinematics
    (x_G = dX, y_G = -dY_e), and their accelerations from the classical accelerations of G
    and A. Multipliers: the force of the pin A on the bar = rnea's data.f of the bar joint
    (parent on child) in world axes, Y flipped: (lambda1, lambda2) = (F_x, -F_y_e)."""

    nq_ref = n_ref = 4
    solver = "aba"
    mass_matrix_note = (
        "the reference's M belongs to its relaxed dependent coordinates "
        "(x, theta, x_G, y_G with the bar's mass center free of the bar angle), "
        "which no engine model of the mechanism has: the engine has (x, theta)"
    )

    def _build(self):
        p = self.params
        jb = self.model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
        self.model.appendBodyToJoint(
            jb, pin.Inertia(p["m1"], np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity()
        )
        jr = self.model.addJoint(jb, pin.JointModelRZ(), pin.SE3.Identity(), "theta")
        self.model.appendBodyToJoint(
            jr,
            pin.Inertia(
                p["m2"], np.array([0.0, -p["l"] / 2, 0.0]), lamina(p["m2"] * p["l"] ** 2 / 12)
            ),
            pin.SE3.Identity(),
        )
        self.G = at(0, -p["l"] / 2, 0)

    def _applied(self, qe, ve, t):
        p = self.params
        return np.array([p["F"] - p["c"] * ve[0] - p["k"] * qe[0], 0.0])

    def _spring_potential(self, qe):
        return 0.5 * self.params["k"] * qe[0] ** 2

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        return q[0:2].copy(), u[0:2].copy()

    def from_engine_state(self, qe, ve):
        pin.forwardKinematics(self.model, self.data, qe, ve)
        dp = self._anchor_position(2, self.G) - self._anchor_position(1, pin.SE3.Identity())
        dv = self._anchor_velocity(2, self.G) - self._anchor_velocity(1, pin.SE3.Identity())
        return (np.array([qe[0], qe[1], dp[0], -dp[1]]), np.array([ve[0], ve[1], dv[0], -dv[1]]))

    def _acc_to_reference(self, qe, ve, ae):
        pin.forwardKinematics(self.model, self.data, qe, ve, ae)
        da = self._anchor_classical_acc(2, self.G) - self._anchor_classical_acc(
            1, pin.SE3.Identity()
        )
        return np.array([ae[0], ae[1], da[0], -da[1]])

    def _multipliers(self, qe, ve, ae, lam_e):
        d = self.data
        pin.forwardKinematics(self.model, d, qe)
        pin.rnea(self.model, d, qe, ve, ae)
        F = d.oMi[2].rotation @ d.f[2].linear
        return np.array([F[0], -F[1]])


class Exercise64(PinEngineModel):
    """Exercise 6.4 (Z up): disk D on a hinge RZ at O (phi; inertia diag(m_d R^2/4, m_d R^2/4,
    m_d R^2/2), motor M_phi), the bar on a hinge RX at P = (0, R, 0) in the disk frame (theta;
    M_theta, spring k and damper c act between D and B, i.e. on this joint), mass center at
    (0, 0, -l/2) in the hinge frame, inertia diag(m l^2/12, m l^2/12, 0) exactly as the
    reference (the disk keeps the mass matrix definite). Engine q = (phi, theta); (y_G, z_G)
    are G's coordinates in the disk frame, from the hinge placement and rotation:
    r = P + Rx(theta) c, r' = w x (Rx c), r'' = w' x (Rx c) + w x (w x Rx c), w = (theta', 0, 0).
    Multipliers: force of the pin on the bar in disk axes: rnea's data.f[2] (parent on child,
    bar-hinge frame) rotated by Rx(theta): (lambda1, lambda2) = its (y, z) components."""

    nq_ref = n_ref = 4
    solver = "aba"
    up = np.array([0.0, 0.0, 1.0])
    mass_matrix_note = (
        "the reference's M belongs to its relaxed dependent coordinates "
        "(phi, theta, y_G, z_G with the bar's mass center free of the bar "
        "angle), which no engine model of the mechanism has: the engine has "
        "(phi, theta)"
    )

    def _build(self):
        p = self.params
        jd = self.model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "phi")
        Id = p["m_d"] * p["R"] ** 2
        self.model.appendBodyToJoint(
            jd,
            pin.Inertia(p["m_d"], np.zeros(3), np.diag([Id / 4, Id / 4, Id / 2])),
            pin.SE3.Identity(),
        )
        jb = self.model.addJoint(jd, pin.JointModelRX(), at(0, p["R"], 0), "theta")
        Ib = p["m"] * p["l"] ** 2 / 12
        self.model.appendBodyToJoint(
            jb,
            pin.Inertia(p["m"], np.array([0.0, 0.0, -p["l"] / 2]), np.diag([Ib, Ib, 0.0])),
            pin.SE3.Identity(),
        )

    def _applied(self, qe, ve, t):
        p = self.params
        return np.array([p["M_phi"], p["M_theta"] - p["k"] * qe[1] - p["c"] * ve[1]])

    def _spring_potential(self, qe):
        return 0.5 * self.params["k"] * qe[1] ** 2

    def _G_disk(self, th, thd, thdd):
        c = self.model.inertias[2].lever
        P = self.model.jointPlacements[2].translation
        Rc = pin.utils.rotate("x", th) @ c
        w, wd = np.array([thd, 0.0, 0.0]), np.array([thdd, 0.0, 0.0])
        return (P + Rc, np.cross(w, Rc), np.cross(wd, Rc) + np.cross(w, np.cross(w, Rc)))

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        return q[0:2].copy(), u[0:2].copy()

    def from_engine_state(self, qe, ve):
        r, rd, _ = self._G_disk(qe[1], ve[1], 0.0)
        return (np.array([qe[0], qe[1], r[1], r[2]]), np.array([ve[0], ve[1], rd[1], rd[2]]))

    def _acc_to_reference(self, qe, ve, ae):
        _, _, rdd = self._G_disk(qe[1], ve[1], ae[1])
        return np.array([ae[0], ae[1], rdd[1], rdd[2]])

    def _multipliers(self, qe, ve, ae, lam_e):
        d = self.data
        pin.rnea(self.model, d, qe, ve, ae)
        F = d.liMi[2].rotation @ d.f[2].linear  # disk axes
        return np.array([F[1], F[2]])
