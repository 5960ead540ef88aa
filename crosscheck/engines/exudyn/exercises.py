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

from . import items
from .base import ExudynModel

__all__ = ["Exercise61", "Exercise62"]


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
        self.hinge = items.hinge_2d(self, items.point(self, block),
                                    items.point(self, bar, 0.0, -p["l"] / 2))
        self.mbs.AddObject(ObjectConnectorCoordinate(markerNumbers=[
            items.ground_coordinate(self), items.coordinate_marker(self, block_node, 1)]))
        x_marker = items.coordinate_marker(self, block_node, 0)
        self.mbs.AddObject(ObjectConnectorCoordinateSpringDamper(
            markerNumbers=[items.ground_coordinate(self), x_marker], stiffness=p["k"],
            damping=p["c"]))
        if p["F"] != 0.0:
            self.mbs.AddLoad(LoadCoordinate(markerNumber=x_marker, load=p["F"]))

    def _spring_potential(self, qe):
        return 0.5 * self.params["k"] * qe[0] ** 2

    def to_engine_state(self, q, u):
        x, th, xg, yg = (float(v) for v in q)
        xd, thd, xgd, ygd = (float(v) for v in u)
        return np.array([x, 0.0, x + xg, yg, -th]), np.array([xd, 0.0, xd + xgd, ygd, -thd])

    def from_engine_state(self, qe, ve):
        return (np.array([qe[0], -qe[4], qe[2] - qe[0], qe[3] - qe[1]]),
                np.array([ve[0], -ve[4], ve[2] - ve[0], ve[3] - ve[1]]))

    def _acc_to_reference(self, qe, ve, ae):
        return np.array([ae[0], -ae[4], ae[2] - ae[0], ae[3] - ae[1]])

    def _multipliers(self, qe, ve, ae, lam_e):
        ae_hinge = list(self.mbs.systemData.GetObjectLTGAE(self.hinge))
        return -np.asarray(lam_e)[ae_hinge]

    def _position_rows(self, qe, t):  # hinge A (bar point (0, -l/2) at the block), y_block
        h = self.params["l"] / 2
        return np.array([qe[2] + h * math.sin(qe[4]) - qe[0],
                         qe[3] - h * math.cos(qe[4]) - qe[1], qe[1]])


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
        self.slide = self.mbs.AddObject(ObjectJointPrismatic2D(
            markerNumbers=[rigid_a, rigid_o], axisMarker0=[1.0, 0.0, 0.0],
            normalMarker1=[0.0, 1.0, 0.0], constrainRotation=False))
        self.mbs.AddObject(ObjectConnectorCartesianSpringDamper(
            markerNumbers=[items.point(self, g0), at_a], stiffness=[p["k"], 0.0, 0.0],
            damping=[p["c"], 0.0, 0.0]))
        self.hinge_B = items.hinge_2d(self, items.point(self, bar, -h), items.point(self, block))
        self.mbs.AddObject(ObjectConnectorCoordinate(markerNumbers=[
            items.ground_coordinate(self), items.coordinate_marker(self, block_node, 0)]))
        if p["F"] != 0.0:
            self.mbs.AddLoad(LoadCoordinate(
                markerNumber=items.coordinate_marker(self, block_node, 1), load=-p["F"]))

    def _spring_potential(self, qe):
        x_a = qe[0] + 0.5 * self.params["l"] * math.cos(qe[2])
        return 0.5 * self.params["k"] * x_a ** 2

    def to_engine_state(self, q, u):
        x, y, th = (float(v) for v in q)
        xd, yd, thd = (float(v) for v in u)
        return (np.array([x / 2, y / 2, th - math.pi / 2, 0.0, y]),
                np.array([xd / 2, yd / 2, thd, 0.0, yd]))

    def from_engine_state(self, qe, ve):
        h = self.params["l"] / 2
        s, c = math.sin(qe[2]), math.cos(qe[2])
        return (np.array([qe[0] + h * c, qe[4], qe[2] + math.pi / 2]),
                np.array([ve[0] - h * s * ve[2], ve[4], ve[2]]))

    def _acc_to_reference(self, qe, ve, ae):
        h = self.params["l"] / 2
        s, c = math.sin(qe[2]), math.cos(qe[2])
        return np.array([ae[0] - h * (s * ae[2] + c * ve[2] ** 2), ae[4], ae[2]])

    def _end_forces(self, qe, ve, lam_e):
        sd, lam = self.mbs.systemData, np.asarray(lam_e)
        n_a = lam[list(sd.GetObjectLTGAE(self.slide))]
        F_B = lam[list(sd.GetObjectLTGAE(self.hinge_B))]
        q, u = self.from_engine_state(qe, ve)
        F_A = np.array([-self.params["k"] * q[0] - self.params["c"] * u[0], n_a[0]])
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
