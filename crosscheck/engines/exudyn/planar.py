"""Exudyn models of Example 1 (the pendulum) and Example 2 / Note 2 (the slider-crank).

Each engine model is the mechanism in Exudyn's redundant coordinates (point masses and planar
rigid bodies held by joints), never the reference's equations: Exudyn assembles M, the forces
and the constraint Jacobians from its own objects. The engine world is the reference frame
(Example 1: Y DOWN, gravity +g Y; Example 2: Y up, gravity -g Y).
"""

from __future__ import annotations

import math

import numpy as np
from exudyn.itemInterface import (
    LoadTorqueVector,
    MarkerBodyRigid,
    ObjectConnectorCoordinate,
    ObjectConnectorDistance,
)

from crosscheck.engines.exudyn import items
from crosscheck.engines.exudyn.engine_model import ExudynModel

__all__ = ["PendulumAngle", "PendulumXY", "SliderCrank", "SliderCrankFree", "SliderCrankSplit"]


class PendulumXY(ExudynModel):
    """Example 1(b). NodePoint2D + ObjectMassPoint2D (the bob), ObjectConnectorDistance from a
    ground point at the origin, distance L. Engine q = (x, y) = the reference's (Y down in
    both). Multiplier: the distance connector's lam is the rod tension T (its force on the bob
    is -lam along the unit vector pivot -> bob), so the reference's lambda = -T/L = -lam / L."""

    nq_ref = n_ref = 2

    def _build(self):
        p = self.params
        self.gravity = (0.0, p["g"], 0.0)
        g0 = items.ground(self)
        _, bob = items.point_mass_2d(self, p["m"])
        self.mbs.AddObject(
            ObjectConnectorDistance(
                markerNumbers=[items.point(self, g0), items.point(self, bob)], distance=p["L"]
            )
        )

    def to_engine_state(self, q, u):
        return np.array(q, float), np.array(u, float)

    def from_engine_state(self, qe, ve):
        return np.array(qe, float), np.array(ve, float)

    def _acc_to_reference(self, qe, ve, ae):
        return np.array(ae, float)

    def _multipliers(self, qe, ve, ae, lam_e):
        return np.array([-lam_e[0] / self.map_params["L"]])

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        raw["rod_tension"] = float(lam_e[0])

    def _position_rows(self, qe, t):
        return np.array([np.hypot(qe[0], qe[1]) - self.params["L"]])


class PendulumAngle(ExudynModel):
    """Example 1(a). One NodeRigidBody2D + ObjectRigidBody2D: mass m at the bob, inertia 0
    about it (the bob is a point; the hinge makes the KKT matrix regular), held by an
    ObjectJointRevolute2D between the ground origin and the body point (0, -L) in body axes.
    Y down: the bob at (L sin theta, L cos theta) makes the body angle phi = -theta, so
    q_e = (L sin theta, L cos theta, -theta), u_e = (L cos theta, -L sin theta, -1) theta'.
    The reference has no multipliers; raw["rod_tension"] is the hinge force on the body
    (-lam, see items.hinge_2d) along bob -> pivot."""

    nq_ref = n_ref = 1

    def _build(self):
        p = self.params
        self.gravity = (0.0, p["g"], 0.0)
        g0 = items.ground(self)
        _, self.body = items.rigid_body_2d(self, p["m"], 0.0)
        self.hinge = items.hinge_2d(
            self, items.point(self, g0), items.point(self, self.body, 0.0, -p["L"])
        )

    def to_engine_state(self, q, u):
        L, th, w = self.map_params["L"], float(q[0]), float(u[0])
        s, c = math.sin(th), math.cos(th)
        return np.array([L * s, L * c, -th]), np.array([L * c * w, -L * s * w, -w])

    def from_engine_state(self, qe, ve):
        return np.array([-qe[2]]), np.array([-ve[2]])

    def _acc_to_reference(self, qe, ve, ae):
        return np.array([-ae[2]])

    def _position_rows(self, qe, t):  # the pivot point of the body at the origin
        L = self.params["L"]
        return np.array([qe[0] + L * math.sin(qe[2]), qe[1] - L * math.cos(qe[2])])

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        to_pivot = -np.asarray(qe[:2]) / np.hypot(qe[0], qe[1])
        raw["rod_tension"] = float(-lam_e[:2] @ to_pivot)


class _SliderCrankBase(ExudynModel):
    """Crank: rigid body (G1 at r1 e1, I_G1, angle theta1), hinged to the ground at A = origin
    (its point (-r1, 0)); rod: rigid body (mass centre G2, I_G2, angle psi), hinged to the crank
    at B; slider: a point mass m3 hinged to the rod at C. The crank torque T is a
    LoadTorqueVector on the crank. Engine q_e = (x_G1, y_G1, theta1, x_G2, y_G2, psi, x_C, y_C),
    14 - 6 = 2 degrees of freedom before the guide."""

    nq_ref = n_ref = 2
    guide = False
    # the rod's axis as the engine body's x axis: +1 from B to C (Example 2's theta2),
    # -1 from C to B (Exercise 6.3's theta2 = Example 2's + pi)
    rod_direction = 1.0

    def _rod_b_to_g(self, p) -> float:
        """Distance B -> G2 along B -> C (Example 2's r2) with the parameter values p."""
        return p["r2"]

    def _build(self):
        p = self.params
        self.gravity = (0.0, -p["g"], 0.0)
        g0 = items.ground(self)
        _, crank = items.rigid_body_2d(self, p["m1"], p["I_G1"])
        _, rod = items.rigid_body_2d(self, p["m2"], p["I_G2"])
        slider_node, slider = items.point_mass_2d(self, p["m3"])
        r1, l1, l2, b = p["r1"], p["l1"], p["l2"], self._rod_b_to_g(p)
        d = self.rod_direction
        self.hinge_A = items.hinge_2d(self, items.point(self, g0), items.point(self, crank, -r1))
        self.hinge_B = items.hinge_2d(
            self, items.point(self, crank, l1 - r1), items.point(self, rod, -d * b)
        )
        self.hinge_C = items.hinge_2d(
            self, items.point(self, rod, d * (l2 - b)), items.point(self, slider)
        )
        if self.guide:  # y_C = 0: ground coordinate (marker 0) and the slider's y (marker 1)
            self.mbs.AddObject(
                ObjectConnectorCoordinate(
                    markerNumbers=[
                        items.ground_coordinate(self),
                        items.coordinate_marker(self, slider_node, 1),
                    ]
                )
            )
        if p["T"] != 0.0:
            self.mbs.AddLoad(
                LoadTorqueVector(
                    markerNumber=self.mbs.AddMarker(MarkerBodyRigid(bodyNumber=crank)),
                    loadVector=[0.0, 0.0, p["T"]],
                )
            )

    def _engine_from_angles(self, th1, w1, th2, w2, psi):
        """Engine state from Example 2's crank and rod angles (rod angle B -> C) and the rod
        body's angle psi (th2 or th2 + pi, passed as the reference holds it: no round-off)."""
        p = self.map_params
        r1, l1, l2, b = p["r1"], p["l1"], p["l2"], self._rod_b_to_g(p)
        e1, e2 = np.array([math.cos(th1), math.sin(th1)]), np.array([math.cos(th2), math.sin(th2)])
        n1, n2 = np.array([-e1[1], e1[0]]), np.array([-e2[1], e2[0]])
        qe = np.concatenate([r1 * e1, [th1], l1 * e1 + b * e2, [psi], l1 * e1 + l2 * e2])
        ve = np.concatenate(
            [r1 * w1 * n1, [w1], l1 * w1 * n1 + b * w2 * n2, [w2], l1 * w1 * n1 + l2 * w2 * n2]
        )
        return qe, ve

    def _position_rows(self, qe, t):
        """Hinge mismatches at A, B, C (world axes) and, with the guide, y_C."""
        p = self.params
        r1, l1, l2, b, d = p["r1"], p["l1"], p["l2"], self._rod_b_to_g(p), self.rod_direction
        e1 = np.array([math.cos(qe[2]), math.sin(qe[2])])
        ep = np.array([math.cos(qe[5]), math.sin(qe[5])])
        g1, g2, c = qe[0:2], qe[3:5], qe[6:8]
        rows = [g1 - r1 * e1, g1 + (l1 - r1) * e1 - (g2 - d * b * ep), g2 + d * (l2 - b) * ep - c]
        if self.guide:
            rows.append(qe[7:8])
        return np.concatenate(rows)


class SliderCrankFree(_SliderCrankBase):
    """Example 2(a) (no guide). q_ref = (theta1, theta2) = (q_e[2], q_e[5]); no multipliers."""

    def to_engine_state(self, q, u):
        return self._engine_from_angles(q[0], u[0], q[1], u[1], q[1])

    def from_engine_state(self, qe, ve):
        return np.array([qe[2], qe[5]]), np.array([ve[2], ve[5]])

    def _acc_to_reference(self, qe, ve, ae):
        return np.array([ae[2], ae[5]])


class SliderCrank(SliderCrankFree):
    """Example 2(b): Example 2(a) plus ObjectConnectorCoordinate y_C = 0 (marker 0 a ground
    coordinate, marker 1 the slider's y). Its lam (the last AE coordinate) acts on y_C as -lam,
    so the guide's vertical force on the slider is -lam. The reference lumps m3 at C and its
    lambda is that same guide force: lambda = -lam_guide."""

    guide = True

    def _multipliers(self, qe, ve, ae, lam_e):
        return np.array([-lam_e[-1]])

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        raw["hinge_forces_on_marker0"] = np.array(lam_e[:6])


class SliderCrankSplit(_SliderCrankBase):
    """Note 2 / Exercise 6.3: the same engine mechanism with the guide, the rod's body axis
    from C to B (psi = the reference's theta2) and G2 at r2 from C. q_ref = (theta1, x, theta2)
    = (q_e[2], q_e[6], q_e[5]). Multipliers (the force of the rod on the crank at B): the B
    hinge's markers are (crank, rod), so its force on the crank is +lam_B = (lam_e[2], lam_e[3])."""

    nq_ref = n_ref = 3
    guide = True
    rod_direction = -1.0

    def _rod_b_to_g(self, p):
        return p["l2"] - p["r2"]

    def to_engine_state(self, q, u):
        # Example 2's rod angle B -> C is theta2 - pi; x follows from the angles
        return self._engine_from_angles(q[0], u[0], q[2] - math.pi, u[2], q[2])

    def from_engine_state(self, qe, ve):
        return np.array([qe[2], qe[6], qe[5]]), np.array([ve[2], ve[6], ve[5]])

    def _acc_to_reference(self, qe, ve, ae):
        return np.array([ae[2], ae[6], ae[5]])

    def _multipliers(self, qe, ve, ae, lam_e):
        return np.array([lam_e[2], lam_e[3]])
