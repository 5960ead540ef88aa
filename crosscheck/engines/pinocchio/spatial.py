"""Pinocchio models of the 3-D examples: the double pendulum (Example 4) and the symmetric
top with Euler parameters (Exercises 6.5-6.7)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from crosscheck.engines.kinematics import R313, E, angles313, eps_ddot, eps_rates
from crosscheck.engines.pinocchio.engine_model import (
    PROX_EXACT,
    PinEngineModel,
    R_to_quat,
    at,
    quat_to_R,
)

# ======================================================================================
# Example 4: the 3-D double pendulum (N2 up in the reference and in the engine)


# ======================================================================================


class _DoublePendulumBase(PinEngineModel):
    """Shared maps of Example 4. The engine world is the reference's N (X = N1, Y = N2 up,
    Z = N3), gravity (0, -g, 0). Each link's engine frame is its n_i frame, so its rotation
    (local -> world) is B_i = R313(theta_i)^T and its body-fixed omega is the reference's w_i.
    Links are full 3-D bodies here: inertias diag(I_11, I_22, I_33) exactly as the reference.

    Reference speeds u = (w1, w2, v_G1, v_G2); multipliers
    lambda = (F_O - F_A, F_A), F_O the ground's force on link 1 at O, F_A the force of link 1
    on link 2 at A (both N components; see the reference docstring and docs/textbook.md)."""

    nq_ref, n_ref = 6, 12

    def _links(self):
        p = self.params
        return (
            pin.Inertia(p["m1"], np.zeros(3), np.diag([p["I1_11"], p["I1_22"], p["I1_33"]])),
            pin.Inertia(p["m2"], np.zeros(3), np.diag([p["I2_11"], p["I2_22"], p["I2_33"]])),
        )

    def _rotations(self, q):
        q = np.asarray(q, float)
        return R313(*q[0:3]).T, R313(*q[3:6]).T


class DoublePendulumFree(_DoublePendulumBase):
    """Example 4 as the textbook writes it: two free bodies (FreeFlyer joints with their origin
    at G_i and axes n_i) and two point constraints, solved by constraintDynamics with the exact
    KKT (PROX_EXACT: 6 independent rows). Constraint O: joint1 = link 1 at (0, l1/2, 0),
    joint2 = the world at O; its contact_force is F_O. Constraint A: joint1 = link 2 at
    (0, l2/2, 0), joint2 = link 1 at (0, -l1/2, 0); its contact_force is the force of link 1 on
    link 2 at A = F_A. Engine velocity per link: (B^T v_G, w) (local linear velocity of the
    origin G, local omega); the engine's spatial acceleration gives
    v_G' = B (a_lin + omega x v_lin) and w' = a_ang. The speed map is linear for a fixed q,
    ve = P(q) u, so mass_matrix returns P^T M_e P; forcing is None (P depends on q)."""

    variant = "free"
    solver = "constraint"
    prox_settings = PROX_EXACT

    def _build(self):
        p = self.params
        I1, I2 = self._links()
        j1 = self.model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "link1")
        self.model.appendBodyToJoint(j1, I1, pin.SE3.Identity())
        j2 = self.model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "link2")
        self.model.appendBodyToJoint(j2, I2, pin.SE3.Identity())
        LWA, C3 = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED, pin.ContactType.CONTACT_3D
        self.cms.append(
            pin.RigidConstraintModel(
                C3, self.model, j1, at(0, p["l1"] / 2, 0), 0, pin.SE3.Identity(), LWA
            )
        )
        self.cms.append(
            pin.RigidConstraintModel(
                C3, self.model, j2, at(0, p["l2"] / 2, 0), j1, at(0, -p["l1"] / 2, 0), LWA
            )
        )

    def _P_of(self, B1, B2) -> np.ndarray:
        P = np.zeros((12, 12))
        P[0:3, 6:9] = B1.T
        P[3:6, 0:3] = np.eye(3)
        P[6:9, 9:12] = B2.T
        P[9:12, 3:6] = np.eye(3)
        return P

    def to_engine_state(self, q, u):
        p = self.map_params
        B1, B2 = self._rotations(q)
        u = np.asarray(u, float)
        e2 = np.array([0.0, 1.0, 0.0])
        rG1 = -p["l1"] / 2 * B1 @ e2
        rG2 = -p["l1"] * B1 @ e2 - p["l2"] / 2 * B2 @ e2
        qe = np.concatenate([rG1, R_to_quat(B1), rG2, R_to_quat(B2)])
        return qe, self._P_of(B1, B2) @ u

    def from_engine_state(self, qe, ve):
        B1, B2 = quat_to_R(qe[3:7]), quat_to_R(qe[10:14])
        q = np.concatenate([angles313(B1.T), angles313(B2.T)])
        return q, self._P_of(B1, B2).T @ np.asarray(ve, float)  # P is orthogonal

    def _acc_to_reference(self, qe, ve, ae):
        out = np.empty(12)
        for k, (iq, iv) in enumerate(((0, 0), (7, 6))):
            B = quat_to_R(qe[iq + 3 : iq + 7])
            vl, w = ve[iv : iv + 3], ve[iv + 3 : iv + 6]
            out[3 * k : 3 * k + 3] = ae[iv + 3 : iv + 6]
            out[6 + 3 * k : 9 + 3 * k] = B @ (ae[iv : iv + 3] + np.cross(w, vl))
        return out

    def _multipliers(self, qe, ve, ae, lam_e):
        F_O, F_A = lam_e[0:3], lam_e[3:6]
        return np.concatenate([F_O - F_A, F_A])

    def mass_matrix(self, q):
        q, _ = self._check(q)
        qe, _ = self.to_engine_state(q, np.zeros(12))
        Me = pin.crba(self.model, self.data, qe).copy()
        Me = np.triu(Me) + np.triu(Me, 1).T
        P = self._P_of(*self._rotations(q))
        return P.T @ Me @ P

    def forcing(self, q, u, t: float = 0.0):
        return None


class DoublePendulumTree(_DoublePendulumBase):
    """Example 4 as a ball-joint tree: JointModelSpherical at O (link 1, frame n_1) and at A
    (placement (0, -l1, 0) in link 1; link 2 relative to link 1), mass centers at
    (0, -l_i/2, 0). Plain ABA; the six multipliers come from rnea's joint reactions:
    data.f[1] is the force of the ground on link 1 at O and data.f[2] the force of link 1 on
    link 2 at A, both in the joint's local frame, so F_O = B1 f[1].linear, F_A = B2 f[2].linear.
    Spherical q is the quaternion (x, y, z, w) of the child relative to the parent and v the
    relative omega in the child frame: q1 = quat(B1), q2 = quat(B1^T B2), v1 = w1,
    v2 = w2 - B2^T B1 w1. v_G and the accelerations are read from forwardKinematics."""

    variant = "tree"
    solver = "aba"
    mass_matrix_note = (
        "the reference's twelve speeds (w1, w2, v_G1, v_G2) are dependent (six "
        "point-constraint rows) and do not map one to one onto the ball-joint "
        "tree's six relative angular velocities"
    )

    def _build(self):
        p = self.params
        I1, I2 = self._links()
        j1 = self.model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "O")
        self.model.appendBodyToJoint(
            j1,
            pin.Inertia(I1.mass, np.array([0.0, -p["l1"] / 2, 0.0]), I1.inertia),
            pin.SE3.Identity(),
        )
        j2 = self.model.addJoint(j1, pin.JointModelSpherical(), at(0, -p["l1"], 0), "A")
        self.model.appendBodyToJoint(
            j2,
            pin.Inertia(I2.mass, np.array([0.0, -p["l2"] / 2, 0.0]), I2.inertia),
            pin.SE3.Identity(),
        )

    @property
    def G(self):
        """The mass centers in the joint frames, for the maps: nominal values."""
        p = self.map_params
        return (at(0, -p["l1"] / 2, 0), at(0, -p["l2"] / 2, 0))

    def to_engine_state(self, q, u):
        B1, B2 = self._rotations(q)
        u = np.asarray(u, float)
        w1, w2 = u[0:3], u[3:6]
        qe = np.concatenate([R_to_quat(B1), R_to_quat(B1.T @ B2)])
        return qe, np.concatenate([w1, w2 - B2.T @ B1 @ w1])

    def from_engine_state(self, qe, ve):
        qe, ve = np.asarray(qe, float), np.asarray(ve, float)
        B1 = quat_to_R(qe[0:4])
        B12 = quat_to_R(qe[4:8])
        B2 = B1 @ B12
        q = np.concatenate([angles313(B1.T), angles313(B2.T)])
        pin.forwardKinematics(self.model, self.data, qe, ve)
        vG1 = self._anchor_velocity(1, self.G[0])
        vG2 = self._anchor_velocity(2, self.G[1])
        w1, w2 = ve[0:3], ve[3:6] + B12.T @ ve[0:3]
        return q, np.concatenate([w1, w2, vG1, vG2])

    def _acc_to_reference(self, qe, ve, ae):
        d = self.data
        pin.forwardKinematics(self.model, d, qe, ve, ae)
        return np.concatenate(
            [
                d.a[1].angular,
                d.a[2].angular,
                self._anchor_classical_acc(1, self.G[0]),
                self._anchor_classical_acc(2, self.G[1]),
            ]
        )

    def _multipliers(self, qe, ve, ae, lam_e):
        d = self.data
        pin.forwardKinematics(self.model, d, qe)
        pin.rnea(self.model, d, qe, ve, ae)
        F_O = d.oMi[1].rotation @ d.f[1].linear
        F_A = d.oMi[2].rotation @ d.f[2].linear
        return np.concatenate([F_O - F_A, F_A])


# ======================================================================================
# Exercises 6.5-6.7: the symmetric top with Euler parameters (N3 up)


# ======================================================================================


class _TopBase(PinEngineModel):
    """Shared maps. Engine world = the reference's N, gravity (0, 0, -g). The Euler parameters
    (eps1, eps2, eps3, eps4), eps4 scalar, ARE Pinocchio's quaternion coefficients (x, y, z, w):
    the reference's R(eps) = (e4^2 - ev.ev) 1 + 2 ev ev^T + 2 e4 skew(ev) is Eigen's
    toRotationMatrix, and omega = 2 E(eps) eps' is the body-fixed (LOCAL) angular velocity
    (both checked in the tests). Inversely eps' = E^T omega / 2 on |eps| = 1, eps . eps' = 0,
    and eps'' = (E(eps')^T omega + E(eps)^T omega') / 2."""

    up = np.array([0.0, 0.0, 1.0])

    def _top_inertia(self, lever):
        p = self.params
        return pin.Inertia(p["m"], np.asarray(lever, float), np.diag([p["I"], p["I"], p["I3"]]))

    _eps_rates = staticmethod(eps_rates)

    @staticmethod
    def _eps_acc(eps, omega, omega_dot):
        return eps_ddot(eps, eps_rates(eps, omega), omega, omega_dot)


class TopEuler(_TopBase):
    """Exercises 6.5/6.6. JointModelSpherical at O, the top's mass center at (0, 0, L) in its
    frame, central inertia diag(I, I, I3). Plain ABA. The reference's single row is the
    normalization eps . eps = 1, which the engine's quaternion coordinates satisfy by
    construction: there is no engine force for it. Its multiplier is not a force and depends
    on the formulation (0 for d'Alembert and Kane, 2V - 4K for Lagrange; reference docstring),
    so multipliers is None and raw carries both textbook values computed from the engine's
    K and V ("normalization_lambda_dalembert_kane", "normalization_lambda_lagrange")."""

    nq_ref = n_ref = 4
    solver = "aba"
    mass_matrix_note = (
        "the reference's M is over the four Euler-parameter rates, tied by the "
        "normalization, which do not map one to one onto the ball joint's three "
        "angular velocity components"
    )

    def _build(self):
        j = self.model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "O")
        self.model.appendBodyToJoint(
            j, self._top_inertia([0.0, 0.0, self.params["L"]]), pin.SE3.Identity()
        )

    def to_engine_state(self, q, u):
        eps = np.asarray(q, float).reshape(4)
        return eps.copy(), 2.0 * E(eps) @ np.asarray(u, float)

    def from_engine_state(self, qe, ve):
        eps = np.asarray(qe, float).copy()
        return eps, self._eps_rates(eps, np.asarray(ve, float))

    def _acc_to_reference(self, qe, ve, ae):
        return self._eps_acc(qe, ve, ae)

    def _multipliers(self, qe, ve, ae, lam_e):
        return None

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        K, V = self._energy_engine(qe, ve)
        raw["normalization_lambda_dalembert_kane"] = 0.0
        raw["normalization_lambda_lagrange"] = 2.0 * V - 4.0 * K
        raw["multipliers_note"] = (
            "no normalization row in Pinocchio (its quaternion is unit "
            "by construction); the reference's lambda is "
            "formulation-dependent (0 for d'Alembert/Kane)"
        )
        pin.forwardKinematics(self.model, self.data, qe)
        pin.rnea(self.model, self.data, qe, ve, ae)
        raw["socket_force"] = self.data.oMi[1].rotation @ self.data.f[1].linear


class _TopCartesianBase(_TopBase):
    """Exercise 6.7: reference q = (x, eps) with x the mass center G, u = (x', eps'); rows
    x - L R e3 = 0 (+1 on x) and the normalization. (lambda1, lambda2, lambda3) = F_O, the
    socket's force on the top at O (N components). lambda4 is not a force: for the two
    formulations this model declares (d'Alembert, Kane, both with the rates as speeds), summing
    eps_k times the eps equations gives 0 = -2 L F_O . (R e3) + lambda4 (the inertia terms
    vanish because E eps = 0, the x terms do not involve eps'), so lambda4 = 2 L F_O . (R e3),
    a function of the engine's force."""

    nq_ref = n_ref = 7

    def _lambda(self, F_O, eps):
        return np.concatenate([F_O, [2.0 * self.map_params["L"] * F_O @ (quat_to_R(eps)[:, 2])]])


class TopCartesianFree(_TopCartesianBase):
    """Exercise 6.7 as one free body (FreeFlyer with its origin at G: engine q = (x, eps)
    exactly, the reference's order) held at O by a CONTACT_3D point constraint: joint1 = the
    top at (0, 0, -L), joint2 = the world at O, exact KKT (PROX_EXACT, 3 independent rows);
    contact_force = F_O. Engine v = (R^T x', omega)."""

    variant = "free"
    solver = "constraint"
    prox_settings = PROX_EXACT
    mass_matrix_note = (
        "the reference's seven speeds (x', eps') include the four Euler-parameter "
        "rates tied by the normalization and do not map one to one onto the free "
        "body's six (R^T x', omega)"
    )

    def _build(self):
        j = self.model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "top")
        self.model.appendBodyToJoint(j, self._top_inertia([0.0, 0.0, 0.0]), pin.SE3.Identity())
        self.cms.append(
            pin.RigidConstraintModel(
                pin.ContactType.CONTACT_3D,
                self.model,
                j,
                at(0, 0, -self.params["L"]),
                0,
                pin.SE3.Identity(),
                pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
            )
        )

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        R = quat_to_R(q[3:7])
        return q.copy(), np.concatenate([R.T @ u[0:3], 2.0 * E(q[3:7]) @ u[3:7]])

    def from_engine_state(self, qe, ve):
        qe, ve = np.asarray(qe, float), np.asarray(ve, float)
        R = quat_to_R(qe[3:7])
        return qe.copy(), np.concatenate([R @ ve[0:3], self._eps_rates(qe[3:7], ve[3:6])])

    def _acc_to_reference(self, qe, ve, ae):
        R = quat_to_R(qe[3:7])
        xdd = R @ (ae[0:3] + np.cross(ve[3:6], ve[0:3]))
        return np.concatenate([xdd, self._eps_acc(qe[3:7], ve[3:6], ae[3:6])])

    def _multipliers(self, qe, ve, ae, lam_e):
        return self._lambda(lam_e[0:3], qe[3:7])


class TopCartesianTree(_TopCartesianBase):
    """Exercise 6.7 with the engine's minimal model (JointModelSpherical at O, as TopEuler):
    x and x' are read from forwardKinematics, F_O from rnea (data.f[1], ground on top at O)."""

    variant = "tree"
    solver = "aba"
    mass_matrix_note = (
        "the reference's seven speeds (x', eps') are dependent (point and "
        "normalization rows) and do not map one to one onto the ball joint's "
        "three angular velocity components"
    )

    def _build(self):
        j = self.model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "O")
        self.model.appendBodyToJoint(
            j, self._top_inertia([0.0, 0.0, self.params["L"]]), pin.SE3.Identity()
        )

    @property
    def G(self):
        """The mass center in the ball joint's frame, for the maps: nominal value."""
        return at(0, 0, self.map_params["L"])

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        return q[3:7].copy(), 2.0 * E(q[3:7]) @ u[3:7]

    def from_engine_state(self, qe, ve):
        qe, ve = np.asarray(qe, float), np.asarray(ve, float)
        pin.forwardKinematics(self.model, self.data, qe, ve)
        x = self._anchor_position(1, self.G)
        xd = self._anchor_velocity(1, self.G)
        return np.concatenate([x, qe]), np.concatenate([xd, self._eps_rates(qe, ve)])

    def _acc_to_reference(self, qe, ve, ae):
        pin.forwardKinematics(self.model, self.data, qe, ve, ae)
        xdd = self._anchor_classical_acc(1, self.G)
        return np.concatenate([xdd, self._eps_acc(qe, ve, ae)])

    def _multipliers(self, qe, ve, ae, lam_e):
        pin.forwardKinematics(self.model, self.data, qe)
        pin.rnea(self.model, self.data, qe, ve, ae)
        F_O = self.data.oMi[1].rotation @ self.data.f[1].linear
        return self._lambda(F_O, qe)
