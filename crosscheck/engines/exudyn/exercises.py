"""Exudyn models of Exercises 6.1 and 6.2 (planar mechanisms with a spring and a damper; the
geometry as the reference's docstrings assume it). Springs and dampers are Exudyn connectors
(ObjectConnectorCoordinateSpringDamper, ObjectConnectorCartesianSpringDamper), loads are
Exudyn loads; the reference's frame is the engine world.
"""

from __future__ import annotations

import math

import numpy as np
from exudyn.itemInterface import (
    LoadCoordinate,
    MarkerBodyRigid,
    ObjectConnectorCartesianSpringDamper,
    ObjectConnectorCoordinate,
    ObjectConnectorCoordinateSpringDamper,
    ObjectJointPrismatic2D,
)

from crosscheck.engines.exudyn import items
from crosscheck.engines.exudyn.engine_model import ExudynModel

__all__ = ["Exercise61", "Exercise62", "Exercise64"]


class Exercise62(ExudynModel):
    """Exercise 6.2 (Y DOWN, gravity +g Y, as the reference). Block: NodePoint2D + mass point
    m1 held at y = 0 by a coordinate constraint; spring k and damper c: a coordinate
    spring-damper between a ground coordinate and the block's x; F: a LoadCoordinate on x.
    Bar: rigid body (m2, m2 l^2/12) hinged (ObjectJointRevolute2D, markers (block, bar)) at
    its point (0, -l/2) in body axes, so as in Example 1(a) the body angle is phi = -theta.
    q_e = (x, y_block, X_G, Y_G, phi); the reference's (x, theta, x_G, y_G) =
    (x, -phi, X_G - x, Y_G - y_block). Multipliers (the force of the pin A on the bar): the
    hinge's force on marker 1's body (the bar) is -lam_A, so (lambda1, lambda2) = -lam_A."""

    nq_ref = n_ref = 4

    def _build(self):
        p = self.params
        self.gravity = (0.0, p["g"], 0.0)
        block_node, block = items.point_mass_2d(self, p["m1"])
        _, bar = items.rigid_body_2d(self, p["m2"], p["m2"] * p["l"] ** 2 / 12)
        self.hinge = items.hinge_2d(
            self, items.point(self, block), items.point(self, bar, 0.0, -p["l"] / 2)
        )
        self.mbs.AddObject(
            ObjectConnectorCoordinate(
                markerNumbers=[
                    items.ground_coordinate(self),
                    items.coordinate_marker(self, block_node, 1),
                ]
            )
        )
        x_marker = items.coordinate_marker(self, block_node, 0)
        self.mbs.AddObject(
            ObjectConnectorCoordinateSpringDamper(
                markerNumbers=[items.ground_coordinate(self), x_marker],
                stiffness=p["k"],
                damping=p["c"],
            )
        )
        if p["F"] != 0.0:
            self.mbs.AddLoad(LoadCoordinate(markerNumber=x_marker, load=p["F"]))

    def _spring_potential(self, qe):
        return 0.5 * self.params["k"] * qe[0] ** 2

    def to_engine_state(self, q, u):
        x, th, xg, yg = (float(v) for v in q)
        xd, thd, xgd, ygd = (float(v) for v in u)
        return np.array([x, 0.0, x + xg, yg, -th]), np.array([xd, 0.0, xd + xgd, ygd, -thd])

    def from_engine_state(self, qe, ve):
        return (
            np.array([qe[0], -qe[4], qe[2] - qe[0], qe[3] - qe[1]]),
            np.array([ve[0], -ve[4], ve[2] - ve[0], ve[3] - ve[1]]),
        )

    def _acc_to_reference(self, qe, ve, ae):
        return np.array([ae[0], -ae[4], ae[2] - ae[0], ae[3] - ae[1]])

    def _multipliers(self, qe, ve, ae, lam_e):
        ae_hinge = list(self.mbs.systemData.GetObjectLTGAE(self.hinge))
        return -np.asarray(lam_e)[ae_hinge]

    def _position_rows(self, qe, t):  # hinge A (bar point (0, -l/2) at the block), y_block
        h = self.params["l"] / 2
        return np.array(
            [qe[2] + h * math.sin(qe[4]) - qe[0], qe[3] - h * math.cos(qe[4]) - qe[1], qe[1]]
        )


class Exercise61(ExudynModel):
    """Exercise 6.1 (Y up, gravity -g Y). Bar: rigid body (m, m l^2/12) whose body x axis
    runs from B to A (body angle phi = theta - pi/2, A at local (l/2, 0), B at (-l/2, 0)).
    End A: ObjectJointPrismatic2D with markers (the bar's point A, the ground origin): it holds
    (p_1 - p_0) . n = 0 with n = normalMarker1 = Y in marker 1's frame, so the ground must be
    marker 1 for the guide's normal to stay vertical (constrainRotation off: the bar turns),
    and a Cartesian spring-damper
    (k, c along X only) between the ground origin and A: the massless slider of the figure
    becomes its two forces on the bar. End B: the block P (mass point m_p) hinged to the bar
    at B, held at x = 0 by a coordinate constraint; F pushes it down (LoadCoordinate -F on its
    y). q_e = (X_G, Y_G, phi, x_P, y_P); the reference's (x, y, theta) = (x_A, y_P,
    phi + pi/2) with x_A = X_G + (l/2) cos(phi).

    Multipliers. As the reference's docstring shows, its (lambda1, lambda2) are fixed by the
    forces F_A, F_B on the bar at A and B (world axes): lambda1 = (F_Bx - F_Ax)/2,
    lambda2 = (F_Ay - F_By)/2. Here F_A = (-k x - c x', N_A), N_A the prismatic joint's
    normal force on the bar (+lam_P: the bar is marker 0; its first AE coordinate), and
    F_B = +lam_B (the B hinge's
    markers are (bar, block): its force on marker 0's body is +lam_B)."""

    nq_ref = n_ref = 3

    def _build(self):
        p = self.params
        self.gravity = (0.0, -p["g"], 0.0)
        g0 = items.ground(self)
        _, bar = items.rigid_body_2d(self, p["m"], p["m"] * p["l"] ** 2 / 12)
        block_node, block = items.point_mass_2d(self, p["m_p"])
        h = p["l"] / 2
        at_a = items.point(self, bar, h)
        rigid_o = self.mbs.AddMarker(MarkerBodyRigid(bodyNumber=g0, localPosition=[0, 0, 0]))
        rigid_a = self.mbs.AddMarker(MarkerBodyRigid(bodyNumber=bar, localPosition=[h, 0, 0]))
        self.slide = self.mbs.AddObject(
            ObjectJointPrismatic2D(
                markerNumbers=[rigid_a, rigid_o],
                axisMarker0=[1.0, 0.0, 0.0],
                normalMarker1=[0.0, 1.0, 0.0],
                constrainRotation=False,
            )
        )
        self.mbs.AddObject(
            ObjectConnectorCartesianSpringDamper(
                markerNumbers=[items.point(self, g0), at_a],
                stiffness=[p["k"], 0.0, 0.0],
                damping=[p["c"], 0.0, 0.0],
            )
        )
        self.hinge_B = items.hinge_2d(self, items.point(self, bar, -h), items.point(self, block))
        self.mbs.AddObject(
            ObjectConnectorCoordinate(
                markerNumbers=[
                    items.ground_coordinate(self),
                    items.coordinate_marker(self, block_node, 0),
                ]
            )
        )
        if p["F"] != 0.0:
            self.mbs.AddLoad(
                LoadCoordinate(
                    markerNumber=items.coordinate_marker(self, block_node, 1), load=-p["F"]
                )
            )

    def _spring_potential(self, qe):
        x_a = qe[0] + 0.5 * self.params["l"] * math.cos(qe[2])
        return 0.5 * self.params["k"] * x_a**2

    def to_engine_state(self, q, u):
        x, y, th = (float(v) for v in q)
        xd, yd, thd = (float(v) for v in u)
        return (
            np.array([x / 2, y / 2, th - math.pi / 2, 0.0, y]),
            np.array([xd / 2, yd / 2, thd, 0.0, yd]),
        )

    def from_engine_state(self, qe, ve):
        h = self.map_params["l"] / 2
        s, c = math.sin(qe[2]), math.cos(qe[2])
        return (
            np.array([qe[0] + h * c, qe[4], qe[2] + math.pi / 2]),
            np.array([ve[0] - h * s * ve[2], ve[4], ve[2]]),
        )

    def _acc_to_reference(self, qe, ve, ae):
        h = self.map_params["l"] / 2
        s, c = math.sin(qe[2]), math.cos(qe[2])
        return np.array([ae[0] - h * (s * ae[2] + c * ve[2] ** 2), ae[4], ae[2]])

    def _end_forces(self, qe, ve, lam_e):
        sd, lam = self.mbs.systemData, np.asarray(lam_e)
        n_a = lam[list(sd.GetObjectLTGAE(self.slide))]
        F_B = lam[list(sd.GetObjectLTGAE(self.hinge_B))]
        q, u = self.from_engine_state(qe, ve)
        F_A = np.array([-self.map_params["k"] * q[0] - self.map_params["c"] * u[0], n_a[0]])
        return F_A, F_B

    def _multipliers(self, qe, ve, ae, lam_e):
        F_A, F_B = self._end_forces(qe, ve, lam_e)
        return np.array([0.5 * (F_B[0] - F_A[0]), 0.5 * (F_A[1] - F_B[1])])

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        raw["force_on_bar_at_A"], raw["force_on_bar_at_B"] = self._end_forces(qe, ve, lam_e)

    def _position_rows(self, qe, t):
        h = self.params["l"] / 2
        e = np.array([math.cos(qe[2]), math.sin(qe[2])])
        a, b = qe[0:2] + h * e, qe[0:2] - h * e
        return np.concatenate([[a[1]], b - qe[3:5], [qe[3]]])


def _rot_x(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# joint frame whose z axis is the body's x axis (columns: joint axes in body components)
_JOINT_Z_ALONG_X = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


class Exercise64(ExudynModel):
    """Exercise 6.4 (Z up, gravity (0, 0, -g)). Disk D: Euler-parameter body at O (inertia
    diag(m_d R^2/4, m_d R^2/4, m_d R^2/2)) on an ObjectJointRevoluteZ about the world Z.
    Bar B: Euler-parameter body (inertia diag(m l^2/12, m l^2/12, 0): the reference's zero
    axial inertia; the pin keeps the KKT matrix regular) on an ObjectJointRevoluteZ at the pin
    P = disk point (0, R, 0) = bar point (0, 0, l/2), both markers' joint z axis along the
    bodies' x axes (marker localHT rotation _JOINT_Z_ALONG_X); the bar's frame is the disk's
    turned by Rx(theta). Spring k and damper c: an ObjectConnectorTorsionalSpringDamper on the
    same two frames; M_theta: body-fixed torques +M_theta x on the bar and -M_theta x on the
    disk; M_phi: a torque about Z on the disk.
    q_e = (0, p_D, r_G, p_B) with p_D = EP(Rz(phi)), p_B = EP(Rz(phi) Rx(theta)), r_G =
    Rz(phi) (0, y_G, z_G). Back: phi and theta from A_D and A_D^T A_B, (y_G, z_G) = A_D^T r_G;
    rates from omega_D = G p_D' (its z is phi'), omega_B = G p_B' (its x is theta'),
    r_d' = A_D^T r_G' - omega x r_d; accelerations likewise with the transport terms
    r_d'' = A_D^T r_G'' - alpha x r_d - 2 omega x r_d' - omega x (omega x r_d).
    Multipliers (force of the pin on the bar in disk axes y, z): -A_D^T F, F the pin joint's
    force components (its first three AE coordinates, world axes, acting +F on marker 0's body
    (the disk) and -F on the bar); raw["pin_force_momentum"] recomputes it from the bar's
    momentum balance m (a_G - g) in disk axes."""

    angle_indices = (0, 1)
    nq_ref = n_ref = 4

    def _build(self):
        from exudyn.itemInterface import (
            LoadTorqueVector,
            ObjectConnectorTorsionalSpringDamper,
            ObjectJointRevoluteZ,
        )

        from crosscheck.engines.exudyn.spatial import rigid_body_ep

        p = self.params
        self.gravity = (0.0, 0.0, -p["g"])
        g0 = items.ground(self)
        Id, Ib = p["m_d"] * p["R"] ** 2, p["m"] * p["l"] ** 2 / 12
        _, disk = rigid_body_ep(self, p["m_d"], (Id / 4, Id / 4, Id / 2))
        _, bar = rigid_body_ep(self, p["m"], (Ib, Ib, 0.0))
        mbs = self.mbs

        def frame(body, pos, rot=None):
            return items.rigid_frame(self, body, pos, rot)

        self.axis = mbs.AddObject(
            ObjectJointRevoluteZ(markerNumbers=[frame(g0, [0, 0, 0]), frame(disk, [0, 0, 0])])
        )
        pin_d = frame(disk, [0, p["R"], 0], _JOINT_Z_ALONG_X)
        pin_b = frame(bar, [0, 0, p["l"] / 2], _JOINT_Z_ALONG_X)
        self.pin = mbs.AddObject(ObjectJointRevoluteZ(markerNumbers=[pin_d, pin_b]))
        mbs.AddObject(
            ObjectConnectorTorsionalSpringDamper(
                markerNumbers=[pin_d, pin_b], stiffness=p["k"], damping=p["c"]
            )
        )
        at_disk, at_bar = frame(disk, [0, 0, 0]), frame(bar, [0, 0, 0])
        if p["M_phi"] != 0.0:
            mbs.AddLoad(LoadTorqueVector(markerNumber=at_disk, loadVector=[0, 0, p["M_phi"]]))
        if p["M_theta"] != 0.0:
            mbs.AddLoad(
                LoadTorqueVector(
                    markerNumber=at_bar, loadVector=[p["M_theta"], 0, 0], bodyFixed=True
                )
            )
            mbs.AddLoad(
                LoadTorqueVector(
                    markerNumber=at_disk, loadVector=[-p["M_theta"], 0, 0], bodyFixed=True
                )
            )

    def _spring_potential(self, qe):
        q, _ = self.from_engine_state(qe, np.zeros(14))
        return 0.5 * self.params["k"] * q[1] ** 2

    def to_engine_state(self, q, u):
        from exudyn.rigidBodyUtilities import EulerParameters2GLocal as G
        from exudyn.rigidBodyUtilities import RotationMatrix2EulerParameters as ep_of

        phi, th, yg, zg = (float(v) for v in q)
        phid, thd, ygd, zgd = (float(v) for v in u)
        Ad, Ab = _rot_z(phi), _rot_z(phi) @ _rot_x(th)
        pd, pb = np.asarray(ep_of(Ad)), np.asarray(ep_of(Ab))
        pd, pb = pd / np.linalg.norm(pd), pb / np.linalg.norm(pb)
        r_d, w = np.array([0.0, yg, zg]), np.array([0.0, 0.0, phid])
        v = Ad @ (np.cross(w, r_d) + np.array([0.0, ygd, zgd]))
        wb = np.array([thd, phid * math.sin(th), phid * math.cos(th)])
        return (
            np.concatenate([[0.0, 0.0, 0.0], pd, Ad @ r_d, pb]),
            np.concatenate([[0.0, 0.0, 0.0], G(pd).T @ w / 4, v, G(pb).T @ wb / 4]),
        )

    def _frames(self, qe):
        from exudyn.rigidBodyUtilities import EulerParameters2RotationMatrix as A

        return A(qe[3:7]), A(qe[10:14])

    def from_engine_state(self, qe, ve):
        from exudyn.rigidBodyUtilities import EulerParameters2GLocal as G

        Ad, Ab = self._frames(qe)
        rel = Ad.T @ Ab
        phi, th = math.atan2(Ad[1, 0], Ad[0, 0]), math.atan2(rel[2, 1], rel[1, 1])
        w = G(qe[3:7]) @ ve[3:7]
        r_d = Ad.T @ qe[7:10]
        rd_t = Ad.T @ ve[7:10] - np.cross(w, r_d)
        return (
            np.array([phi, th, r_d[1], r_d[2]]),
            np.array([w[2], (G(qe[10:14]) @ ve[10:14])[0], rd_t[1], rd_t[2]]),
        )

    def _acc_to_reference(self, qe, ve, ae):
        from exudyn.rigidBodyUtilities import EulerParameters2GLocal as G

        Ad, _ = self._frames(qe)
        w, alpha = G(qe[3:7]) @ ve[3:7], G(qe[3:7]) @ ae[3:7]
        r_d = Ad.T @ qe[7:10]
        rd_t = Ad.T @ ve[7:10] - np.cross(w, r_d)
        rd_tt = (
            Ad.T @ ae[7:10]
            - np.cross(alpha, r_d)
            - 2 * np.cross(w, rd_t)
            - np.cross(w, np.cross(w, r_d))
        )
        return np.array([alpha[2], (G(qe[10:14]) @ ae[10:14])[0], rd_tt[1], rd_tt[2]])

    def _multipliers(self, qe, ve, ae, lam_e):
        Ad, _ = self._frames(qe)
        F = np.asarray(lam_e)[list(self.mbs.systemData.GetObjectLTGAE(self.pin))][0:3]
        f = -Ad.T @ F
        return np.array([f[1], f[2]])

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        Ad, _ = self._frames(qe)
        # the engine's own momentum balance (its mass and gravity): a check of the engine's
        # pin force against its accelerations, not a map
        m, g = self.params["m"], np.asarray(self.gravity)
        raw["pin_force_momentum"] = (Ad.T @ (m * (np.asarray(ae[7:10]) - g)))[1:3]

    def _position_rows(self, qe, t):
        Ad, Ab = self._frames(qe)
        p = self.params
        pin = Ad @ np.array([0.0, p["R"], 0.0]) - qe[7:10] - Ab @ np.array([0.0, 0.0, p["l"] / 2])
        rel = Ad.T @ Ab  # a rotation about x: its x column is (1, 0, 0)
        return np.concatenate(
            [
                qe[0:3],
                [Ad[2, 0], Ad[2, 1]],
                pin,
                rel[1:3, 0],
                [qe[3:7] @ qe[3:7] - 1, qe[10:14] @ qe[10:14] - 1],
            ]
        )
