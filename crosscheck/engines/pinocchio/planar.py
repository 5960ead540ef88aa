"""Pinocchio models of the planar examples: the pendulum (Example 1), the slider-cranks
(Example 2, Note 2 / Exercise 6.3), the frame and bar (Example 3), the knife edge and the
moving support (supplements)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from crosscheck.engines.kinematics import (
    IdentityMaps,
    LinearMaps,
    frame_bar_from_engine,
    frame_bar_to_engine,
)
from crosscheck.engines.pinocchio.engine_model import PROX_REDUNDANT, Y_UP, PinEngineModel, lamina


class PendulumAngle(IdentityMaps, PinEngineModel):
    """Example 1(a). One hinge RZ at the origin; the bob (mass m, no inertia) at (0, -L, 0) in
    the hinge frame, so the engine angle is the reference's theta (from the downward vertical)
    with positions (L sin, -L cos) = (x_ref, -y_ref). Plain ABA; the reference has no multipliers.
    raw["rod_tension"] is the force of the pivot on the rod+bob body along the rod, read from
    rnea's data.f[1] (parent on body, local frame): local +y points from the bob to the pivot."""

    nq_ref = n_ref = 1
    solver = "aba"
    _P = np.eye(1)

    def _build(self):
        p = self.params
        j = self.model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "theta")
        self.model.appendBodyToJoint(
            j,
            pin.Inertia(p["m"], np.array([0.0, -p["L"], 0.0]), np.zeros((3, 3))),
            pin.SE3.Identity(),
        )

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        pin.rnea(self.model, self.data, qe, ve, ae)
        raw["rod_tension"] = float(self.data.f[1].linear @ Y_UP)


class PendulumXY(LinearMaps, PinEngineModel):
    """Example 1(b). Slides PX (x_e) then PY (y_e) carrying the bob; y_ref = -y_e, x_ref = x_e.
    The distance constraint (x^2 + y^2 - L^2)/2 = 0 is the same function in both coordinate
    sets, so with J = [x_e, y_e] and gamma = xdot_e^2 + ydot_e^2 data.lambda_c is the textbook
    lambda itself (lambda = -T/L)."""

    nq_ref = n_ref = 2
    solver = "kkt"
    _P = _Pinv = np.diag([1.0, -1.0])  # q_e = P q_ref, P P = I

    def _build(self):
        jx = self.model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
        jy = self.model.addJoint(jx, pin.JointModelPY(), pin.SE3.Identity(), "y")
        self.model.appendBodyToJoint(
            jy, pin.Inertia(self.params["m"], np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity()
        )

    def _kkt_rows(self, qe, ve, t):
        return qe.reshape(1, 2).copy(), np.array([ve @ ve])

    def _multipliers(self, qe, ve, ae, lam_e):
        return lam_e.copy()

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        raw["rod_tension"] = float(-lam_e[0] * self.map_params["L"])

    def constraint_violation(self, qe, t: float = 0.0):
        """| |p| - L |: the rod's length error."""
        return abs(float(np.hypot(qe[0], qe[1])) - self.params["L"])


# ======================================================================================
# Example 2 and Note 2 / Exercise 6.3: the slider-crank (Y UP in both)


# ======================================================================================


class _SliderCrankBase(PinEngineModel):
    def _tau(self):
        tau = np.zeros(self.model.nv)
        tau[0] = self.params["T"]  # the crank hinge is joint 1 (q index 0) in every variant
        return tau

    def _crank(self):
        p = self.params
        j1 = self.model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "theta1")
        self.model.appendBodyToJoint(
            j1,
            pin.Inertia(p["m1"], np.array([p["r1"], 0.0, 0.0]), lamina(p["I_G1"])),
            pin.SE3.Identity(),
        )
        return j1

    def _crank_and_rod(self):
        """The crank (_crank) and the rod on a hinge at B = (l1, 0, 0) of the crank (its
        coordinate phi2 = theta2 - theta1); returns the rod's joint."""
        p = self.params
        j2 = self.model.addJoint(
            self._crank(),
            pin.JointModelRZ(),
            pin.SE3(np.eye(3), np.array([p["l1"], 0.0, 0.0])),
            "phi2",
        )
        self.model.appendBodyToJoint(
            j2,
            pin.Inertia(p["m2"], np.array([p["r2"], 0.0, 0.0]), lamina(p["I_G2"])),
            pin.SE3.Identity(),
        )
        return j2


class SliderCrankFree(LinearMaps, _SliderCrankBase):
    """Example 2(a), the slider row removed. Crank hinge (theta1) and rod hinge at B relative to
    the crank (phi2 = theta2 - theta1); the end mass m3 is a point mass fixed on the rod at C
    (it does not turn, so lumping it into the rod body is exact). q_e = P q_ref with
    P = [[1, 0], [-1, 1]]. Plain ABA."""

    nq_ref = n_ref = 2
    solver = "aba"
    _P = np.array([[1.0, 0.0], [-1.0, 1.0]])
    _Pinv = np.array([[1.0, 0.0], [1.0, 1.0]])

    def _build(self):
        p = self.params
        j2 = self._crank_and_rod()
        self.model.appendBodyToJoint(
            j2,
            pin.Inertia(p["m3"], np.array([p["l2"], 0.0, 0.0]), np.zeros((3, 3))),
            pin.SE3.Identity(),
        )


class SliderCrank(_SliderCrankBase):
    """Example 2(b). Engine tree: crank hinge (theta1), rod hinge at B relative to the crank
    (phi2 = theta2 - theta1), slider on a root slide PX (x_s, the world x of C) carrying m3.
    Loop closure: CONTACT_3D at C, joint1 = rod (anchor (l2, 0, 0)), joint2 = slider (origin),
    LOCAL_WORLD_ALIGNED; rows x, y, z of which z is identically zero (ProximalSettings for a
    singular Delassus matrix, PROX_REDUNDANT).

    Force map. contact_force lambda_c is the force of the slider on the rod at C (world axes).
    The reference lumps m3 at C on the rod and its single row l1 S1 + l2 S2 = y_C = 0 makes its
    lambda the vertical force of the guide at C. In the engine the guide acts on the slider
    through the PX joint: the slider's vertical equation, with its vertical acceleration 0,
    reads N - m3 g - lambda_c,y = 0, hence

        lambda_ref = N = lambda_c,y + m3 g.

    raw["guide_force_rnea"] is N read independently from Pinocchio's rnea with the constraint
    forces applied as external forces (the y component of the PX joint's transmitted force).
    The horizontal component lambda_c,x is internal to the reference's lumped rod+m3 body.

    Coordinates: 2 reference (theta1, theta2) vs 3 engine (theta1, phi2, x_s); x_s = l1 C1 +
    l2 C2 follows from the closure, so mass_matrix/forcing return None (the reference's M also
    carries m3's vertical motion that the guide removes in the engine)."""

    nq_ref = n_ref = 2
    solver = "constraint"
    prox_settings = PROX_REDUNDANT
    mass_matrix_note = (
        "the engine's coordinates (theta1, phi2, x_slider) do not map one to one "
        "onto the reference's (theta1, theta2): x_slider follows from the loop "
        "closure, and the reference's M carries the vertical motion of m3 that "
        "the engine's guide removes"
    )

    def _build(self):
        p = self.params
        j2 = self._crank_and_rod()
        j3 = self.model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x_slider")
        self.model.appendBodyToJoint(
            j3, pin.Inertia(p["m3"], np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity()
        )
        self.j_rod, self.j_slider = j2, j3
        self.cms.append(
            pin.RigidConstraintModel(
                pin.ContactType.CONTACT_3D,
                self.model,
                j2,
                pin.SE3(np.eye(3), np.array([p["l2"], 0.0, 0.0])),
                j3,
                pin.SE3.Identity(),
                pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
            )
        )

    def to_engine_state(self, q, u):
        p = self.map_params
        th1, th2 = np.asarray(q, float)
        w1, w2 = np.asarray(u, float)
        xs = p["l1"] * math.cos(th1) + p["l2"] * math.cos(th2)
        xs_dot = -p["l1"] * math.sin(th1) * w1 - p["l2"] * math.sin(th2) * w2
        return np.array([th1, th2 - th1, xs]), np.array([w1, w2 - w1, xs_dot])

    def from_engine_state(self, qe, ve):
        return np.array([qe[0], qe[0] + qe[1]]), np.array([ve[0], ve[0] + ve[1]])

    def _acc_to_reference(self, qe, ve, ae):
        return np.array([ae[0], ae[0] + ae[1]])

    def _multipliers(self, qe, ve, ae, lam_e):
        return np.array([lam_e[1] + self.map_params["m3"] * self.map_params["g"]])

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        d = self.data
        self._rnea_with_constraint_forces(qe, ve, ae, lam_e)
        # transmitted force of the world on the slider through the PX joint, world axes
        N = d.oMi[self.j_slider].rotation @ d.f[self.j_slider].linear
        raw["guide_force_rnea"] = float(N[1])
        raw["force_on_rod_at_C"] = lam_e[0:3].copy()


class SliderCrankSplit(IdentityMaps, _SliderCrankBase):
    """Note 2 / Exercise 6.3, coordinates (theta1, x, theta2) with theta2 measured from C to B
    and r2 = |C G2|. Engine tree: crank hinge (theta1), root slide PX (x) carrying m3, rod hinge
    on the slider at C (the slider does not turn, so the rod's hinge angle is the absolute
    theta2); the rod's mass center at (r2, 0, 0) in its frame. q_e = q_ref exactly.
    Loop closure at B: CONTACT_3D, joint1 = crank (anchor (l1, 0, 0)), joint2 = rod (anchor
    (l2, 0, 0)), LOCAL_WORLD_ALIGNED, rows B_crank - B_rod. The reference's rows are
    f1 = l1 C1 - l2 C2 - x and f2 = l1 S1 - l2 S2: the same difference, so (lambda1, lambda2) =
    contact_force[0:2] = the force of the rod on the crank at B; the z row is identically 0."""

    nq_ref = n_ref = 3
    solver = "constraint"
    prox_settings = PROX_REDUNDANT
    _P = np.eye(3)

    def _build(self):
        p = self.params
        j1 = self._crank()
        j2 = self.model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
        self.model.appendBodyToJoint(
            j2, pin.Inertia(p["m3"], np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity()
        )
        j3 = self.model.addJoint(j2, pin.JointModelRZ(), pin.SE3.Identity(), "theta2")
        self.model.appendBodyToJoint(
            j3,
            pin.Inertia(p["m2"], np.array([p["r2"], 0.0, 0.0]), lamina(p["I_G2"])),
            pin.SE3.Identity(),
        )
        self.cms.append(
            pin.RigidConstraintModel(
                pin.ContactType.CONTACT_3D,
                self.model,
                j1,
                pin.SE3(np.eye(3), np.array([p["l1"], 0.0, 0.0])),
                j3,
                pin.SE3(np.eye(3), np.array([p["l2"], 0.0, 0.0])),
                pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
            )
        )

    def _multipliers(self, qe, ve, ae, lam_e):
        return lam_e[0:2].copy()


# ======================================================================================
# Example 3: rotating light frame F and bar B (no gravity)


# ======================================================================================


class FrameBar(PinEngineModel):
    """Example 3. Engine tree: hinge RZ (phi) carrying the light frame F (no body: F is light),
    then hinge RY (theta) about the arm n2 placed at (0, d, 0) in F, carrying the bar with its
    mass center at the joint origin and central principal inertias diag(I1, I2, I3) along the
    joint axes e1, e2 = n2, e3 (the reference's R = rot_z(phi) rot_y(theta)). No gravity.
    tau = (M_phi, M_theta): the motor on F about k and the motor on B about n2.

    Speeds: the reference's three dependent body-fixed omega components vs the engine's two
    joint rates: omega = phi' k + theta' e2 = (-S phi', theta', C phi') and, inversely,
    theta' = omega2, phi' = -S omega1 + C omega3 (exact on omega1 C + omega3 S = 0). The
    reference's u' are the bar's body-fixed angular acceleration components, read from
    Pinocchio's data.a of the bar joint (local frame = bar frame) after forwardKinematics.

    Multiplier: lambda is the n1 component of the bearing moment of the ground on F about O
    (reference docstring); rnea's data.f[1] is the wrench of the ground on F at O in F's axes
    (n1, n2, k), so lambda = data.f[1].angular[0] (its k component is the motor torque)."""

    nq_ref, n_ref = 2, 3
    solver = "aba"
    mass_matrix_note = (
        "the reference's three body-fixed angular velocity components are "
        "dependent speeds (tied by omega1 C + omega3 S = 0) and do not map one "
        "to one onto the engine's two joint rates (phi', theta')"
    )

    def _build(self):
        p = self.params
        j1 = self.model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "phi")
        j2 = self.model.addJoint(
            j1, pin.JointModelRY(), pin.SE3(np.eye(3), np.array([0.0, p["d"], 0.0])), "theta"
        )
        self.model.appendBodyToJoint(
            j2,
            pin.Inertia(p["m"], np.zeros(3), np.diag([p["I1"], p["I2"], p["I3"]])),
            pin.SE3.Identity(),
        )
        self.j_bar = j2

    def _tau(self):
        return np.array([self.params["M_phi"], self.params["M_theta"]])

    def to_engine_state(self, q, u):
        return frame_bar_to_engine(q, u)

    def from_engine_state(self, qe, ve):
        return frame_bar_from_engine(qe, ve)

    def _acc_to_reference(self, qe, ve, ae):
        pin.forwardKinematics(self.model, self.data, qe, ve, ae)
        return self.data.a[self.j_bar].angular.copy()

    def _multipliers(self, qe, ve, ae, lam_e):
        pin.rnea(self.model, self.data, qe, ve, ae)
        return np.array([self.data.f[1].angular[0]])


# ======================================================================================
# Supplements: the knife edge (nonholonomic) and the moving support (rheonomic)


# ======================================================================================


class KnifeEdge(IdentityMaps, PinEngineModel):
    """Knife edge / Chaplygin sled (horizontal plane, no gravity). Engine tree: slides PX (x),
    PY (y) carrying the contact point C, hinge RZ (theta) carrying the sled: mass center at
    (a, 0, 0) on the blade axis, planar-lamina inertia from I_G. q_e = q_ref. The nonholonomic
    row -S x' + C y' = 0 goes to forwardDynamics as the textbook row J = [-S, C, 0] with
    gamma = Jdot v = -(C x' + S y') theta', so data.lambda_c is the textbook lambda (the lateral
    force of the ground on the blade). Loads: P along the blade at C, tau = (P C, P S, 0), and T
    about Z. The constraint has no position level: constraint_violation is 0 and
    velocity_violation |-S x' + C y'| is the drift measure."""

    nq_ref = n_ref = 3
    solver = "kkt"
    _P = np.eye(3)

    def _build(self):
        p = self.params
        jx = self.model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
        jy = self.model.addJoint(jx, pin.JointModelPY(), pin.SE3.Identity(), "y")
        jt = self.model.addJoint(jy, pin.JointModelRZ(), pin.SE3.Identity(), "theta")
        self.model.appendBodyToJoint(
            jt,
            pin.Inertia(p["m"], np.array([p["a"], 0.0, 0.0]), lamina(p["I_G"])),
            pin.SE3.Identity(),
        )

    def _applied(self, qe, ve, t):
        th = qe[2]
        return np.array(
            [self.params["P"] * math.cos(th), self.params["P"] * math.sin(th), self.params["T"]]
        )

    def _kkt_rows(self, qe, ve, t):
        S, C = math.sin(qe[2]), math.cos(qe[2])
        J = np.array([[-S, C, 0.0]])
        return J, np.array([-(C * ve[0] + S * ve[1]) * ve[2]])

    def _multipliers(self, qe, ve, ae, lam_e):
        return lam_e.copy()

    def constraint_violation(self, qe, t: float = 0.0):
        return 0.0


class MovingSupport(PendulumXY):
    """Example 1(b) with the support moving x_s(t) = a sin(Omega t) along X (Y DOWN in the
    reference, Y up in the engine as PendulumXY). Rheonomic row f = ((x - x_s)^2 + y^2 - L^2)/2
    in engine coordinates: J = [x - x_s, y_e], and the acceleration-level row
    J a + (x' - x_s')^2 + y_e'^2 - (x - x_s) x_s'' = 0 gives gamma, including the explicit time
    terms; data.lambda_c is the textbook lambda (= -T/L). Velocity residual J v + a0 with
    a0 = -(x - x_s) x_s'."""

    def _support(self, t):
        a, W = self.params["a"], self.params["Omega"]
        return a * math.sin(W * t), a * W * math.cos(W * t), -a * W * W * math.sin(W * t)

    def _kkt_rows(self, qe, ve, t):
        xs, xsd, xsdd = self._support(t)
        J = np.array([[qe[0] - xs, qe[1]]])
        gamma = (ve[0] - xsd) ** 2 + ve[1] ** 2 - (qe[0] - xs) * xsdd
        return J, np.array([gamma])

    def _velocity_rows(self, qe, ve, t):
        xs, xsd, _ = self._support(t)
        return np.array([(qe[0] - xs) * (ve[0] - xsd) + qe[1] * ve[1]])

    def constraint_violation(self, qe, t: float = 0.0):
        xs, _, _ = self._support(t)
        return abs(float(np.hypot(qe[0] - xs, qe[1])) - self.params["L"])
