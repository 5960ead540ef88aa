"""Exudyn models of the 3-D examples: Example 4 (double pendulum) and Exercise 6.7 (the top in
mass-centre coordinates and Euler parameters).

Rigid bodies are NodeRigidBodyEP nodes (q = position of the mass centre, then Euler parameters
p = (p0, p1, p2, p3), scalar FIRST; Exudyn adds the normalization row p.p - 1 = 0 as one AE
coordinate of the node) with ObjectRigidBody (mass, central inertia, mass centre at the node).
Exudyn's rotation A(p) maps body to world components; its local angular velocity is
omega_b = G(p) p' with G = exudyn.rigidBodyUtilities.EulerParameters2GLocal (the factor 2
inside), so p' = G^T omega_b / 4 on |p| = 1 (G G^T = 4 I) and omega_b' = G(p) p'' (the
identity G(p') p' = 0). Ball joints are ObjectJointSpherical (3 AE coordinates, world axes;
the force on marker 1's body is -lam, on marker 0's +lam: verified against the reference's
multipliers in tests/test_engine_exudyn.py).
"""

from __future__ import annotations

import math

import numpy as np
from exudyn.itemInterface import NodeRigidBodyEP, ObjectJointSpherical, ObjectRigidBody
from exudyn.rigidBodyUtilities import (
    EulerParameters2GLocal,
    EulerParameters2RotationMatrix,
    RotationMatrix2EulerParameters,
)

from crosscheck.engines.exudyn import items
from crosscheck.engines.exudyn.engine_model import ExudynModel
from crosscheck.engines.kinematics import R313, angles313

__all__ = ["DoublePendulum3D", "FrameBar", "TopCartesian", "TopEuler"]


def rigid_body_ep(model, mass: float, inertia_diag) -> tuple[int, int]:
    """NodeRigidBodyEP (reference: the origin, Euler parameters (1, 0, 0, 0)) and an
    ObjectRigidBody with the principal central inertias along the body axes, gravity on."""
    n = model.mbs.AddNode(NodeRigidBodyEP(referenceCoordinates=[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]))
    Ixx, Iyy, Izz = (float(v) for v in inertia_diag)
    b = model.mbs.AddObject(
        ObjectRigidBody(mass=mass, inertia=[Ixx, Iyy, Izz, 0.0, 0.0, 0.0], nodeNumber=n)
    )
    items._gravity(model, b)
    model.masses.append((n, b, mass))
    return n, b


class DoublePendulum3D(ExudynModel):
    """Example 4 (N2 up, gravity (0, -g, 0)). Two EP rigid bodies whose body axes are the
    links' n_i axes (A_i = R_i^T, R_i the textbook's 3-1-3 matrix), principal inertias
    (I_i11, I_i22, I_i33); ObjectJointSpherical at O (ground, link 1 at (0, l1/2, 0)) and at A
    (link 1 at (0, -l1/2, 0), link 2 at (0, l2/2, 0)). Engine q_e = (r_G1, p_1, r_G2, p_2).
    State map: p_i from R_i^T, p_i' = G^T omega_i / 4; r_G from the joints (the reference's
    v_G components are the node velocities). Accelerations: (omega_1', omega_2') =
    (G p_1'', G p_2''), (a_G1, a_G2) = the nodes' position accelerations.
    Multipliers: link 2 gets -lam_A at A, so the reference's lambda[3:6] (force of link 1 on
    link 2) = -lam_A; link 1 gets -lam_O from the ground, and lambda[0:3] = F_O -
    lambda[3:6] = -lam_O + lam_A."""

    angle_indices = (0, 2, 3, 5)
    nq_ref = 6
    n_ref = 12

    def _build(self):
        p = self.params
        self.gravity = (0.0, -p["g"], 0.0)
        g0 = items.ground(self)
        _, b1 = rigid_body_ep(self, p["m1"], (p["I1_11"], p["I1_22"], p["I1_33"]))
        _, b2 = rigid_body_ep(self, p["m2"], (p["I2_11"], p["I2_22"], p["I2_33"]))
        l1, l2 = p["l1"], p["l2"]
        self.joint_O = self.mbs.AddObject(
            ObjectJointSpherical(
                markerNumbers=[items.point(self, g0), items.point(self, b1, 0.0, l1 / 2)]
            )
        )
        self.joint_A = self.mbs.AddObject(
            ObjectJointSpherical(
                markerNumbers=[
                    items.point(self, b1, 0.0, -l1 / 2),
                    items.point(self, b2, 0.0, l2 / 2),
                ]
            )
        )

    def _ae(self, lam_e, obj) -> np.ndarray:
        return np.asarray(lam_e)[list(self.mbs.systemData.GetObjectLTGAE(obj))]

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        qe, ve = [], []
        for i in range(2):
            ep = np.asarray(RotationMatrix2EulerParameters(R313(*q[3 * i : 3 * i + 3]).T))
            ep = ep / np.linalg.norm(ep)
            G = EulerParameters2GLocal(ep)
            qe.append((None, ep))
            ve.append((u[6 + 3 * i : 9 + 3 * i], G.T @ u[3 * i : 3 * i + 3] / 4))
        l1, l2 = self.map_params["l1"], self.map_params["l2"]
        A1 = EulerParameters2RotationMatrix(qe[0][1])
        A2 = EulerParameters2RotationMatrix(qe[1][1])
        r1 = A1 @ np.array([0.0, -l1 / 2, 0.0])
        r2 = A1 @ np.array([0.0, -l1, 0.0]) + A2 @ np.array([0.0, -l2 / 2, 0.0])
        return (
            np.concatenate([r1, qe[0][1], r2, qe[1][1]]),
            np.concatenate([ve[0][0], ve[0][1], ve[1][0], ve[1][1]]),
        )

    def from_engine_state(self, qe, ve):
        qe, ve = np.asarray(qe, float), np.asarray(ve, float)
        angles, omegas = [], []
        for i in (0, 7):
            ep = qe[i + 3 : i + 7]
            angles.append(angles313(EulerParameters2RotationMatrix(ep).T))
            omegas.append(EulerParameters2GLocal(ep) @ ve[i + 3 : i + 7])
        return (np.concatenate(angles), np.concatenate([omegas[0], omegas[1], ve[0:3], ve[7:10]]))

    def _acc_to_reference(self, qe, ve, ae):
        w1 = EulerParameters2GLocal(qe[3:7]) @ ae[3:7]
        w2 = EulerParameters2GLocal(qe[10:14]) @ ae[10:14]
        return np.concatenate([w1, w2, ae[0:3], ae[7:10]])

    def _multipliers(self, qe, ve, ae, lam_e):
        lo, la = self._ae(lam_e, self.joint_O), self._ae(lam_e, self.joint_A)
        return np.concatenate([-lo + la, -la])

    def _position_rows(self, qe, t):
        l1, l2 = self.params["l1"], self.params["l2"]
        A1 = EulerParameters2RotationMatrix(qe[3:7])
        A2 = EulerParameters2RotationMatrix(qe[10:14])
        O = qe[0:3] + A1 @ np.array([0.0, l1 / 2, 0.0])
        gap = (
            qe[0:3]
            + A1 @ np.array([0.0, -l1 / 2, 0.0])
            - qe[7:10]
            - A2 @ np.array([0.0, l2 / 2, 0.0])
        )
        return np.concatenate([O, gap, [qe[3:7] @ qe[3:7] - 1, qe[10:14] @ qe[10:14] - 1]])


class TopCartesian(ExudynModel):
    """Exercise 6.7 (Z up, gravity (0, 0, -g)). One EP rigid body (mass m, principal inertias
    (I, I, I3) along e1, e2, e3), an ObjectJointSpherical between the ground origin O (marker
    0) and the body point (0, 0, -L) (marker 1). The reference's coordinates ARE the engine's:
    x = the node position, eps = (p1, p2, p3, p0) (the textbook's eps4 is the scalar part; its
    R(eps) is Exudyn's A(p)), so q_e = (x, eps4, eps1, eps2, eps3) and the same for rates and
    accelerations. Multipliers: the socket's force on the top is -lam_O, the reference's
    (lambda1, lambda2, lambda3) = F_O. lambda4 belongs to the normalization row and depends on
    the formulation (the reference's d'Alembert/Kane value is 2 x . F_O): Exudyn's own
    normalization multiplier (the node's AE coordinate, raw["normalization_multiplier"]) is a
    different formulation's, measured ~1e-17 (Exudyn's Euler-parameter equations keep the
    normalization force out, as Exercise 6.6's lambda = 0), so lambda4 is reported as the
    d'Alembert value from Exudyn's socket force, 2 x . F_O, as the Pinocchio adapter does."""

    nq_ref = n_ref = 7

    def _build(self):
        p = self.params
        self.gravity = (0.0, 0.0, -p["g"])
        g0 = items.ground(self)
        self.node, body = rigid_body_ep(self, p["m"], (p["I"], p["I"], p["I3"]))
        self.joint = self.mbs.AddObject(
            ObjectJointSpherical(
                markerNumbers=[items.point(self, g0), items.point(self, body, 0.0, 0.0, -p["L"])]
            )
        )

    _PERM = (0, 1, 2, 6, 3, 4, 5)  # reference index of each engine coordinate

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        perm = list(self._PERM)
        return q[perm], u[perm]

    def from_engine_state(self, qe, ve):
        inv = np.argsort(self._PERM)
        return np.asarray(qe, float)[inv], np.asarray(ve, float)[inv]

    def _acc_to_reference(self, qe, ve, ae):
        return np.asarray(ae, float)[np.argsort(self._PERM)]

    def _multipliers(self, qe, ve, ae, lam_e):
        sd = self.mbs.systemData
        F_O = -np.asarray(lam_e)[list(sd.GetObjectLTGAE(self.joint))]
        return np.concatenate([F_O, [2.0 * float(np.asarray(qe[0:3]) @ F_O)]])

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        ae_node = list(self.mbs.systemData.GetNodeLTGAE(self.node))
        raw["normalization_multiplier"] = float(np.asarray(lam_e)[ae_node][0])

    def _position_rows(self, qe, t):
        A = EulerParameters2RotationMatrix(qe[3:7])
        tip = qe[0:3] + A @ np.array([0.0, 0.0, -self.params["L"]])
        return np.concatenate([tip, [qe[3:7] @ qe[3:7] - 1]])


class TopEuler(TopCartesian):
    """Exercises 6.5/6.6: the engine model of Exercise 6.7 (the same top, socket and axes)
    with the reference's four Euler parameters as its coordinates: eps = (p1, p2, p3, p0),
    the mass centre x = L A(p) e3 and x' = A (omega_b x L e3) (omega_b = G p') follow.
    Accelerations: eps'' = (p1'', p2'', p3'', p0''). Multiplier: only the normalization row,
    whose value depends on the formulation (d'Alembert/Kane: 0, Exercise 6.6; Lagrange:
    2V - 4K). Exudyn's own normalization multiplier lam_n is mapped as -2 lam_n (the force
    -2 p lam_n of a row p.p - 1 = 0 onto the reference's eps lambda); measured ~1e-17, it
    agrees with the d'Alembert value 0, the reference's primary formulation. raw["socket_force"]
    is F_O = -lam_O."""

    nq_ref = n_ref = 4

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        ep, ep_t = q[[3, 0, 1, 2]], u[[3, 0, 1, 2]]
        A = EulerParameters2RotationMatrix(ep)
        lever = np.array([0.0, 0.0, self.map_params["L"]])
        omega = EulerParameters2GLocal(ep) @ ep_t
        return (np.concatenate([A @ lever, ep]), np.concatenate([A @ np.cross(omega, lever), ep_t]))

    def from_engine_state(self, qe, ve):
        return np.asarray(qe, float)[[4, 5, 6, 3]], np.asarray(ve, float)[[4, 5, 6, 3]]

    def _acc_to_reference(self, qe, ve, ae):
        return np.asarray(ae, float)[[4, 5, 6, 3]]

    def _multipliers(self, qe, ve, ae, lam_e):
        ae_node = list(self.mbs.systemData.GetNodeLTGAE(self.node))
        return np.array([-2.0 * float(np.asarray(lam_e)[ae_node][0])])

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        sd = self.mbs.systemData
        raw["socket_force"] = -np.asarray(lam_e)[list(sd.GetObjectLTGAE(self.joint))]


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


# a joint frame whose z axis is the body's y axis (columns: joint axes in body components)
_JOINT_Z_ALONG_Y = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


class FrameBar(ExudynModel):
    """Example 3 (k = Z up, no gravity). The light frame F: an Euler-parameter body at O with
    zero mass and inertia (its rotation about k is carried by the bar through the arm hinge,
    which keeps the KKT matrix regular), on an ObjectJointRevoluteZ about k at O (markers:
    ground, F). The bar B: Euler-parameter body at G (principal inertias I1, I2, I3 along
    e1, e2, e3), hinged to F by an ObjectJointRevoluteZ whose joint z axis is F's and B's
    y axis (n2 = e2), at F's point (0, d, 0) and B's mass centre. M_phi: a torque about k on
    F; M_theta: body-fixed torques +M_theta e2 on B and -M_theta n2 on F.
    q_e = (0, p_F, r_G, p_B) with p_F = EP(Rz(phi)), p_B = EP(Rz(phi) Ry(theta)),
    r_G = d n2. Speeds: the reference's omega = G(p_B) p_B' (bar components);
    phi' = -omega1 sin(theta) + omega3 cos(theta) (F's local z rate). Accelerations:
    omega' = G(p_B) p_B''.
    Multiplier: the reference's lambda is the n1 component of the moment of the ground's
    bearing on F about O. The bearing joint's five AE coordinates are its force (3) and the
    multipliers of its two rotation rows; the second row measures F's tilt about its own x
    axis n1 (a small rotation about n1 changes it at unit rate), so with the joint's force on
    marker 1's body (F) being -lam, lambda = -lam[4]. Measured, not assumed:
    raw["lambda_newton_euler"] recomputes it as m d a_G . k + (I alpha + omega x I omega) . n1
    from Exudyn's own accelerations (the reference's formula) and the test compares the two.
    Energy: the bar's only (F is massless)."""

    angle_indices = (0, 1)
    nq_ref = 2
    n_ref = 3

    def _build(self):
        from exudyn.itemInterface import (
            LoadTorqueVector,
            ObjectJointRevoluteZ,
        )

        p = self.params
        g0 = items.ground(self)
        _, frame_body = rigid_body_ep(self, 0.0, (0.0, 0.0, 0.0))
        self.masses.pop()  # massless: no potential, no kinetic energy
        _, bar = rigid_body_ep(self, p["m"], (p["I1"], p["I2"], p["I3"]))
        mbs = self.mbs

        def frame(body, pos, rot=None):
            return items.rigid_frame(self, body, pos, rot)

        self.bearing = mbs.AddObject(
            ObjectJointRevoluteZ(markerNumbers=[frame(g0, [0, 0, 0]), frame(frame_body, [0, 0, 0])])
        )
        mbs.AddObject(
            ObjectJointRevoluteZ(
                markerNumbers=[
                    frame(frame_body, [0, p["d"], 0], _JOINT_Z_ALONG_Y),
                    frame(bar, [0, 0, 0], _JOINT_Z_ALONG_Y),
                ]
            )
        )
        at_f, at_b = frame(frame_body, [0, 0, 0]), frame(bar, [0, 0, 0])
        if p["M_phi"] != 0.0:
            mbs.AddLoad(LoadTorqueVector(markerNumber=at_f, loadVector=[0, 0, p["M_phi"]]))
        if p["M_theta"] != 0.0:
            mbs.AddLoad(
                LoadTorqueVector(markerNumber=at_b, loadVector=[0, p["M_theta"], 0], bodyFixed=True)
            )
            mbs.AddLoad(
                LoadTorqueVector(
                    markerNumber=at_f, loadVector=[0, -p["M_theta"], 0], bodyFixed=True
                )
            )

    def to_engine_state(self, q, u):
        phi, th = (float(v) for v in q)
        w = np.asarray(u, float)
        phid = -w[0] * math.sin(th) + w[2] * math.cos(th)
        Af, Ab = _rz(phi), _rz(phi) @ _ry(th)
        pf, pb = (np.asarray(RotationMatrix2EulerParameters(A)) for A in (Af, Ab))
        pf, pb = pf / np.linalg.norm(pf), pb / np.linalg.norm(pb)
        d = self.map_params["d"]
        r = Af @ np.array([0.0, d, 0.0])
        v = Af @ np.array([-d * phid, 0.0, 0.0])
        wf = np.array([0.0, 0.0, phid])
        return (
            np.concatenate([[0.0, 0.0, 0.0], pf, r, pb]),
            np.concatenate(
                [
                    [0.0, 0.0, 0.0],
                    EulerParameters2GLocal(pf).T @ wf / 4,
                    v,
                    EulerParameters2GLocal(pb).T @ w / 4,
                ]
            ),
        )

    def from_engine_state(self, qe, ve):
        Af = EulerParameters2RotationMatrix(qe[3:7])
        rel = Af.T @ EulerParameters2RotationMatrix(qe[10:14])
        phi, th = math.atan2(Af[1, 0], Af[0, 0]), math.atan2(rel[0, 2], rel[0, 0])
        return np.array([phi, th]), EulerParameters2GLocal(qe[10:14]) @ np.asarray(ve[10:14])

    def _acc_to_reference(self, qe, ve, ae):
        return EulerParameters2GLocal(qe[10:14]) @ np.asarray(ae[10:14])

    def _multipliers(self, qe, ve, ae, lam_e):
        lam = np.asarray(lam_e)[list(self.mbs.systemData.GetObjectLTGAE(self.bearing))]
        return np.array([-lam[4]])

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        p = self.map_params
        Ab = EulerParameters2RotationMatrix(qe[10:14])
        w = EulerParameters2GLocal(qe[10:14]) @ np.asarray(ve[10:14])
        alpha = EulerParameters2GLocal(qe[10:14]) @ np.asarray(ae[10:14])
        inertia = np.array([p["I1"], p["I2"], p["I3"]])
        n1_b = Ab.T @ EulerParameters2RotationMatrix(qe[3:7])[:, 0]
        euler = inertia * alpha + np.cross(w, inertia * w)
        raw["lambda_newton_euler"] = float(p["m"] * p["d"] * ae[9] + euler @ n1_b)

    def _position_rows(self, qe, t):
        Af = EulerParameters2RotationMatrix(qe[3:7])
        Ab = EulerParameters2RotationMatrix(qe[10:14])
        arm = Af @ np.array([0.0, self.params["d"], 0.0]) - qe[7:10]
        return np.concatenate(
            [
                qe[0:3],
                Af[2, 0:2],
                arm,
                [
                    Ab[:, 1] @ Af[:, 0],
                    Ab[:, 1] @ Af[:, 2],
                    qe[3:7] @ qe[3:7] - 1,
                    qe[10:14] @ qe[10:14] - 1,
                ],
            ]
        )
