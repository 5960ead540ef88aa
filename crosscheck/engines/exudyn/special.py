"""Exudyn models of the supplements: the knife edge (nonholonomic) and the pendulum on a moving
support (rheonomic).

What Exudyn's one-state answer leaves out, measured (tests/test_engine_exudyn.py keeps both
measurements): its initial-acceleration solve (base.py) builds the right-hand side of the
constraint rows from (C_q q')_q q' alone. A velocity-level row (velocityLevel=True) gets no
velocity term at all (the knife edge at its sampled states: lam = 0 and the sled's
accelerations those of a free body, off by O(1)), and an explicit time dependence (C_tt,
2 (C_q)_t q': offsetUserFunction of a coordinate constraint) is dropped (the moving support:
the support's acceleration comes out 0 instead of -a Omega^2 sin(Omega t)). The models below
give the same solve rows whose (C_q q')_q q' IS the missing term:

- the knife edge's row is declared as a position-level row whose Jacobian is the Pfaffian row
  J(q) (the row's value is J(q) q', never used by the one-state solve), so (J q')_q q' is the
  row's full acceleration form; the trajectories use a separate system with the honest
  velocity-level row (velocityLevel=True);
- the moving support's time enters through a clock coordinate tau (a unit point mass on a 1-D
  node held at tau = t by a coordinate constraint with offsetUserFunction t, tau' = 1), and the
  support's prescribed x_s = a sin(Omega tau) is a position-level user row in (x_s, tau), so
  its (C_q q')_q q' contains a Omega^2 sin(Omega tau) tau'^2: every explicit time term.
"""

from __future__ import annotations

import math

import numpy as np
from exudyn.itemInterface import (
    LoadForceVector,
    LoadTorqueVector,
    MarkerBodyRigid,
    MarkerNodeCoordinates,
    Node1D,
    NodePointGround,
    ObjectConnectorCoordinate,
    ObjectConnectorCoordinateVector,
    ObjectConnectorDistance,
    ObjectMass1D,
)

from crosscheck.engines.exudyn import items
from crosscheck.engines.exudyn.engine_model import ExudynModel

__all__ = ["KnifeEdge", "MovingSupport"]


class KnifeEdge(ExudynModel):
    """Supplement (nonholonomic). One NodeRigidBody2D + ObjectRigidBody2D at the mass centre G
    (mass m, inertia I_G, angle phi = theta), no gravity (horizontal plane). P: a body-fixed
    LoadForceVector (P, 0) at C = local (-a, 0); T: a LoadTorqueVector. The no-side-slip row
    in engine coordinates (n = (-sin phi, cos phi); v_C = v_G - a phi' n):
        J(q_e) v_e = -sin(phi) x_G' + cos(phi) y_G' - a phi' = 0,
    an ObjectConnectorCoordinateVector with Python constraint and Jacobian user functions on
    the body's node coordinates (see the module docstring for the level it is declared at).
    State map: q_e = (x + a cos th, y + a sin th, th), v_e = (x' - a sin th th',
    y' + a cos th th', th'). Multiplier: the row's generalized force -J^T lam equals that of a
    lateral force F n at C (F J^T: moment of F n at C about G is -a F), so the reference's
    lambda (the ground's lateral force on the blade along n) is -lam."""

    nq_ref = n_ref = 3

    def _build(self):
        p = self.params
        a = p["a"]
        node, body = items.rigid_body_2d(self, p["m"], p["I_G"])
        m0 = self.mbs.AddMarker(
            MarkerNodeCoordinates(
                nodeNumber=self.mbs.AddNode(NodePointGround(referenceCoordinates=[0.0, 0.0, 0.0]))
            )
        )  # no coordinates
        m1 = self.mbs.AddMarker(MarkerNodeCoordinates(nodeNumber=node))

        def row(mbs, t, item, q, q_t, velocity_level):
            s, c = math.sin(q[2]), math.cos(q[2])
            return [-s * q_t[0] + c * q_t[1] - a * q_t[2]]

        def jacobian(mbs, t, item, q, q_t, velocity_level):
            return np.array([[-math.sin(q[2]), math.cos(q[2]), -a]])

        self.mbs.AddObject(
            ObjectConnectorCoordinateVector(
                markerNumbers=[m0, m1],
                scalingMarker0=np.zeros((1, 1)),
                velocityLevel=self.simulation,
                constraintUserFunction=row,
                jacobianUserFunction=jacobian,
            )
        )
        if p["P"] != 0.0:
            at_c = self.mbs.AddMarker(MarkerBodyRigid(bodyNumber=body, localPosition=[-a, 0, 0]))
            self.mbs.AddLoad(
                LoadForceVector(markerNumber=at_c, loadVector=[p["P"], 0.0, 0.0], bodyFixed=True)
            )
        if p["T"] != 0.0:
            self.mbs.AddLoad(
                LoadTorqueVector(
                    markerNumber=self.mbs.AddMarker(MarkerBodyRigid(bodyNumber=body)),
                    loadVector=[0.0, 0.0, p["T"]],
                )
            )

    def to_engine_state(self, q, u):
        a = self.map_params["a"]
        x, y, th = (float(v) for v in q)
        xd, yd, w = (float(v) for v in u)
        s, c = math.sin(th), math.cos(th)
        return np.array([x + a * c, y + a * s, th]), np.array([xd - a * s * w, yd + a * c * w, w])

    def from_engine_state(self, qe, ve):
        a = self.map_params["a"]
        s, c = math.sin(qe[2]), math.cos(qe[2])
        return (
            np.array([qe[0] - a * c, qe[1] - a * s, qe[2]]),
            np.array([ve[0] + a * s * ve[2], ve[1] - a * c * ve[2], ve[2]]),
        )

    def _acc_to_reference(self, qe, ve, ae):
        a = self.map_params["a"]
        s, c = math.sin(qe[2]), math.cos(qe[2])
        w2 = ve[2] ** 2
        return np.array([ae[0] + a * (c * w2 + s * ae[2]), ae[1] + a * (s * w2 - c * ae[2]), ae[2]])

    def _multipliers(self, qe, ve, ae, lam_e):
        return np.array([-lam_e[0]])

    def velocity_violation(self, qe, ve, t: float = 0.0) -> float:
        a = self.params["a"]
        return abs(-math.sin(qe[2]) * ve[0] + math.cos(qe[2]) * ve[1] - a * ve[2])


class MovingSupport(ExudynModel):
    """Supplement (rheonomic). Engine: the bob (NodePoint2D + ObjectMassPoint2D, mass m,
    gravity +g Y: Y down as the reference), a support point mass (mass m, no gravity; its
    mass only loads its own constraints), the clock tau (Node1D + ObjectMass1D, mass 1). Rows,
    in AE order: the distance connector support-bob (L); y_s = 0 (coordinate constraint);
    x_s - a sin(Omega tau) = 0 (ObjectConnectorCoordinateVector, user functions, on (x_s, y_s,
    tau)); tau - t = 0 (coordinate constraint, offsetUserFunction t). Engine q_e = (x, y, x_s,
    y_s, tau), v_e = (x', y', a Omega cos(Omega t), 0, 1) at the state's time t. Multiplier:
    the distance connector's lam is the tension T, lambda = -T/L = -lam_0/L as in
    Example 1(b). Energy: the bob's only (the support and the clock are not in the
    reference)."""

    nq_ref = n_ref = 2
    rheonomic = True
    energy_dofs = (0, 1)

    def _build(self):
        p = self.params
        a, om = p["a"], p["Omega"]
        self.gravity = (0.0, p["g"], 0.0)
        _, bob = items.point_mass_2d(self, p["m"])
        self.gravity, saved = (0.0, 0.0, 0.0), self.gravity  # the support carries no weight
        s_node, support = items.point_mass_2d(self, p["m"])
        self.masses.pop()  # not part of the reference's energy
        self.gravity = saved
        clock = self.mbs.AddNode(Node1D(referenceCoordinates=[0.0]))
        self.mbs.AddObject(ObjectMass1D(mass=1.0, nodeNumber=clock))
        self.mbs.AddObject(
            ObjectConnectorDistance(
                markerNumbers=[items.point(self, support), items.point(self, bob)], distance=p["L"]
            )
        )
        self.mbs.AddObject(
            ObjectConnectorCoordinate(
                markerNumbers=[
                    items.ground_coordinate(self),
                    items.coordinate_marker(self, s_node, 1),
                ]
            )
        )
        m0 = self.mbs.AddMarker(MarkerNodeCoordinates(nodeNumber=s_node))
        m1 = self.mbs.AddMarker(MarkerNodeCoordinates(nodeNumber=clock))

        def row(mbs, t, item, q, q_t, velocity_level):  # q = (x_s, y_s, tau)
            if velocity_level:  # the index-2 solver asks for the row's time derivative
                return [q_t[0] - a * om * math.cos(om * q[2]) * q_t[2]]
            return [q[0] - a * math.sin(om * q[2])]

        def jacobian(mbs, t, item, q, q_t, velocity_level):
            return np.array([[1.0, 0.0, -a * om * math.cos(om * q[2])]])

        self.mbs.AddObject(
            ObjectConnectorCoordinateVector(
                markerNumbers=[m0, m1],
                scalingMarker0=np.zeros((1, 1)),
                constraintUserFunction=row,
                jacobianUserFunction=jacobian,
            )
        )
        self.mbs.AddObject(
            ObjectConnectorCoordinate(
                markerNumbers=[
                    items.ground_coordinate(self),
                    items.coordinate_marker(self, clock, 0),
                ],
                offsetUserFunction=lambda mbs, t, item, offset: t,
                offsetUserFunction_t=lambda mbs, t, item, offset: 1.0,
            )
        )

    def _support(self, t, p):
        """The support's x_s and x_s' at time t with the parameter values p."""
        a, om = p["a"], p["Omega"]
        return a * math.sin(om * t), a * om * math.cos(om * t)

    def to_engine_state(self, q, u):
        xs, xsd = self._support(self.time, self.map_params)
        return (np.array([q[0], q[1], xs, 0.0, self.time]), np.array([u[0], u[1], xsd, 0.0, 1.0]))

    def from_engine_state(self, qe, ve):
        return np.array(qe[:2], float), np.array(ve[:2], float)

    def _acc_to_reference(self, qe, ve, ae):
        return np.array(ae[:2], float)

    def _multipliers(self, qe, ve, ae, lam_e):
        return np.array([-lam_e[0] / self.map_params["L"]])

    def _extra_raw(self, qe, ve, ae, lam_e, raw):
        raw["rod_tension"] = float(lam_e[0])
        raw["support_acceleration"] = float(ae[2])

    def _position_rows(self, qe, t):
        xs, _ = self._support(qe[4], self.params)
        return np.array(
            [
                np.hypot(qe[0] - qe[2], qe[1] - qe[3]) - self.params["L"],
                qe[3],
                qe[2] - xs,
                qe[4] - t,
            ]
        )
