"""OpenSim models of the planar reference models: the pendulum (Example 1) and the slider-cranks
(Example 2, Note 2 / Exercise 6.3).

Engine frame: X right, Y UP, gravity (0, -g, 0), hinges about +Z (OpenSim's PinJoint axis is the
joint frame's Z). Example 1 is written with Y DOWN in the reference: its maps flip y. Bars get
the planar-lamina inertia (common.lamina); point masses have no rotational inertia.
"""

from __future__ import annotations

import math

import numpy as np
import opensim as osim

from crosscheck.engines.kinematics import IdentityMaps, LinearMaps
from crosscheck.engines.opensim.engine_model import (
    OsimModel,
    custom_joint,
    lamina,
    point_body,
    vec3,
)

__all__ = [
    "MovingSupport",
    "PendulumAngle",
    "PendulumXY",
    "SliderCrank",
    "SliderCrankFree",
    "SliderCrankSplit",
]


def _pin(name, parent, at, child, child_at=(0, 0, 0)) -> osim.PinJoint:
    """A PinJoint (about +Z) whose coordinate is named like the joint."""
    j = osim.PinJoint(name, parent, vec3(*at), vec3(), child, vec3(*child_at), vec3())
    j.upd_coordinates(0).setName(name)
    return j


def _torque(model, name, body, T) -> None:
    """A constant torque T about +Z on a body (PrescribedForce, ground axes)."""
    f = osim.PrescribedForce(name, body)
    f.setTorqueFunctions(osim.Constant(0.0), osim.Constant(0.0), osim.Constant(float(T)))
    model.addForce(f)


class PendulumAngle(IdentityMaps, OsimModel):
    """Example 1(a). PinJoint at the ground origin; the bob (point mass m) sits L below the
    joint at theta = 0 (child frame at (0, L, 0) in the bob's frame), so the engine angle is
    the reference's theta and the bob is at (L sin, -L cos) = (x_ref, -y_ref). No constraints."""

    nq_ref = n_ref = 1

    def _build(self):
        p = self.params
        bob = point_body("bob", p["m"])
        self.model.addBody(bob)
        self.model.addJoint(_pin("theta", self.model.getGround(), (0, 0, 0), bob, (0, p["L"], 0)))


class PendulumXY(LinearMaps, OsimModel):
    """Example 1(b). The bob on a CustomJoint with two translations along the exact ground X and
    Y axes (coordinates x_e, y_e); y_ref = -y_e. The rod is a ConstantDistanceConstraint between
    the ground origin and the bob (length L).

    Multiplier map. Simbody's rod row is |p| - L = 0 (its G row is p^T / |p|) and its force on
    the bob is -G^T lambda_s, so lambda_s is the rod TENSION (measured: 15.26 N at the reference's
    initial state, where T = -lambda L = 15.26 N). The reference's row (x^2 + y^2 - L^2)/2 has
    A = p^T (the same function of p in either y sign), hence

        lambda_ref = -lambda_s / |p|       (|p| = L on the manifold; the engine's |p| is used).
    """

    nq_ref = n_ref = 2
    _P = _Pinv = np.diag([1.0, -1.0])  # P P = I

    def _build(self):
        p = self.params
        bob = point_body("bob", p["m"])
        self.model.addBody(bob)
        self.model.addJoint(
            custom_joint(
                "xy",
                self.model.getGround(),
                bob,
                translations=(("x", (1, 0, 0), 1.0, 0.0), ("y", (0, 1, 0), 1.0, 0.0)),
            )
        )
        self.model.addConstraint(
            osim.ConstantDistanceConstraint(
                self.model.getGround(), vec3(), bob, vec3(), float(p["L"])
            )
        )
        self.defaults = {"y": -p["L"]}  # an assembled configuration for initSystem

    def _multipliers(self, lam_s):
        qe = self._read(self.state.getQ())
        return np.array([-lam_s[0] / math.hypot(qe[0], qe[1])])

    def _extra_raw(self, raw):
        raw["rod_tension"] = float(raw["engine_multipliers"][0])


class _SliderCrankBase(OsimModel):
    """Crank (theta1) on a PinJoint at A = ground origin, its mass center at (r1, 0, 0)."""

    def _crank(self):
        p = self.params
        crank = lamina("crank", p["m1"], (p["r1"], 0, 0), p["I_G1"])
        self.model.addBody(crank)
        self.model.addJoint(_pin("theta1", self.model.getGround(), (0, 0, 0), crank))
        _torque(self.model, "T", crank, p["T"])
        return crank


class _TwoLink(LinearMaps, _SliderCrankBase):
    """Crank and rod (hinged at B = (l1, 0, 0) of the crank; its coordinate phi2 = theta2 -
    theta1) with the end mass m3 a point body welded to the rod at C = (l2, 0, 0): it does not
    turn, so a WeldJoint (no coordinate) carries it exactly. q_e = P q_ref."""

    nq_ref = n_ref = 2
    _P = np.array([[1.0, 0.0], [-1.0, 1.0]])
    _Pinv = np.array([[1.0, 0.0], [1.0, 1.0]])

    def _build(self):
        p = self.params
        crank = self._crank()
        rod = lamina("rod", p["m2"], (p["r2"], 0, 0), p["I_G2"])
        self.model.addBody(rod)
        self.model.addJoint(_pin("phi2", crank, (p["l1"], 0, 0), rod))
        slider = point_body("slider", p["m3"])
        self.model.addBody(slider)
        self.model.addJoint(osim.WeldJoint("C", rod, vec3(p["l2"]), vec3(), slider, vec3(), vec3()))
        self.rod, self.slider = rod, slider


class SliderCrankFree(_TwoLink):
    """Example 2(a): the two-link chain of _TwoLink, no constraint."""


class SliderCrank(_TwoLink):
    """Example 2(b): _TwoLink plus a PointOnLineConstraint holding the slider body's origin (C)
    on the ground X axis (line through the origin along (1, 0, 0)).

    Multiplier map. Simbody's point-on-line rows are the follower point's offsets along two unit
    normals of the line that Simbody picks from its direction: for (1, 0, 0) the first row is
    the out-of-plane one (identically satisfied in planar motion, multiplier 0) and the second
    is along +Y, with lambda_s[1] the force the line applies to the slider along +Y (measured:
    lambda_s = (0, 1.9498) where the reference's lambda = 1.9498; the tests check the sign
    against Constraint.calcConstraintForces). The reference's lambda is the vertical force of
    the guide on C:

        lambda_ref = lambda_s[1].
    """

    def _build(self):
        super()._build()
        self.model.addConstraint(
            osim.PointOnLineConstraint(
                self.model.getGround(), vec3(1, 0, 0), vec3(), self.slider, vec3()
            )
        )
        th2 = math.asin(-self.params["l1"] * math.sin(0.5) / self.params["l2"])
        self.defaults = {"theta1": 0.5, "phi2": th2 - 0.5}

    def _multipliers(self, lam_s):
        return np.array([lam_s[1]])


class SliderCrankSplit(IdentityMaps, _SliderCrankBase):
    """Note 2 / Exercise 6.3: crank (theta1); the slider (point mass m3) on a CustomJoint
    translating along the exact ground X axis (x); the rod on a PinJoint at the slider's
    origin C (theta2, its x axis from C to B, mass center (r2, 0, 0)). q_e = q_ref. The
    joint at B is a PointConstraint between the crank's (l1, 0, 0) and the rod's (l2, 0, 0)
    (3 rows; the z row is identically satisfied, multiplier 0).

    Multiplier map. Simbody's ball multipliers are in ground axes: the constraint applies
    +lambda_s to the crank (body 1) at B and -lambda_s to the rod (body 2), measured against
    Constraint.calcConstraintForces (which returns G^T lambda, the NEGATED applied forces:
    -lambda_s on the crank). The
    reference's (lambda1, lambda2) is the force of the rod on the crank at B:

        (lambda1, lambda2) = (lambda_s[0], lambda_s[1]).
    """

    nq_ref = n_ref = 3

    def _build(self):
        p = self.params
        crank = self._crank()
        slider = point_body("slider", p["m3"])
        self.model.addBody(slider)
        self.model.addJoint(
            custom_joint(
                "x", self.model.getGround(), slider, translations=(("x", (1, 0, 0), 1.0, 0.0),)
            )
        )
        rod = lamina("rod", p["m2"], (p["r2"], 0, 0), p["I_G2"])
        self.model.addBody(rod)
        self.model.addJoint(_pin("theta2", slider, (0, 0, 0), rod))
        self.model.addConstraint(osim.PointConstraint(crank, vec3(p["l1"]), rod, vec3(p["l2"])))
        th2 = math.asin(-p["l1"] * math.sin(0.5) / p["l2"])
        self.defaults = {
            "theta1": 0.5,
            "x": p["l1"] * math.cos(0.5) + p["l2"] * math.cos(th2),
            "theta2": th2 + math.pi,
        }

    def _multipliers(self, lam_s):
        return np.array([lam_s[0], lam_s[1]])


class MovingSupport(PendulumXY):
    """Supplement (rheonomic): Example 1(b) with the support moving x_s(t) = a sin(Omega t).
    The bob on the CustomJoint of PendulumXY (x_e, y_e = -y_ref); the support a 1 kg point
    body (massless, Simbody returned NaN: M is singular in x_s; its mass does not change the
    bob's motion or the rod force, its motion being prescribed, only the multiplier that
    drives it) on a CustomJoint along the exact ground X whose coordinate x_s is PRESCRIBED
    (Coordinate.setPrescribedFunction(Sine(a, Omega, 0, 0))); the rod a
    ConstantDistanceConstraint between the support and the bob. The engine state is
    (x_e, y_e) and, in Simbody's state, x_s(t), x_s'(t) filled in from t when it is set.

    Multipliers: Simbody adds one row for the prescribed coordinate, FIRST (its multiplier is
    the force that drives the support, not a reference row), then the rod's (slot 1, checked in
    the tests against the rod's force from calcConstraintForces); as in PendulumXY,
    lambda_ref = -lambda_rod / |p - p_s|.
    """

    rod_index = 1  # the rod's slot among Simbody's multipliers
    SUPPORT_MASS = 1.0  # kg; any positive value (see above); its K is removed from energy()

    def _energy_of(self, state):
        """The bob's K and V: OpenSim's K minus the support's m_s x_s'^2 / 2 (the reference has
        no support body; the support moves on Y = 0, so it adds nothing to V)."""
        K, V = super()._energy_of(state)
        xsd = self.model.getCoordinateSet().get("x_s").getSpeedValue(state)
        return K - 0.5 * self.SUPPORT_MASS * xsd**2, V

    def _build(self):
        super()._build()
        p = self.params
        self.model.getConstraintSet().clearAndDestroy()
        support = point_body("support", self.SUPPORT_MASS)
        self.model.addBody(support)
        self.model.addJoint(
            custom_joint(
                "xs", self.model.getGround(), support, translations=(("x_s", (1, 0, 0), 1.0, 0.0),)
            )
        )
        bob = self.model.getBodySet().get("bob")
        self.model.addConstraint(
            osim.ConstantDistanceConstraint(support, vec3(), bob, vec3(), float(p["L"]))
        )
        self.model.finalizeFromProperties()
        xs = self.model.getCoordinateSet().get("x_s")
        xs.setPrescribedFunction(osim.Sine(float(p["a"]), float(p["Omega"]), 0.0, 0.0))
        xs.setDefaultIsPrescribed(True)

    def _support(self, t, p):
        """The support's x_s and x_s' at time t with the parameter values p."""
        a, W = p["a"], p["Omega"]
        return a * math.sin(W * t), a * W * math.cos(W * t)

    def _set_state_on(self, state, qe, ve, t) -> None:
        if len(qe) == 2:
            xs, xsd = self._support(t, self.params)  # the engine's prescribed motion
            qe, ve = np.append(qe, xs), np.append(ve, xsd)
        super()._set_state_on(state, qe, ve, t)

    def to_engine_state(self, q, u):
        return self._P @ np.asarray(q, float), self._P @ np.asarray(u, float)

    def from_engine_state(self, qe, ve):
        return self._P @ np.asarray(qe, float)[:2], self._P @ np.asarray(ve, float)[:2]

    def _acc_to_reference(self, qe, ve, ae):
        return self._P @ np.asarray(ae, float)[:2]

    def _multipliers(self, lam_s):
        qe = self._read(self.state.getQ())
        xs, _ = self._support(self.state.getTime(), self.map_params)
        return np.array([-lam_s[self.rod_index] / math.hypot(qe[0] - xs, qe[1])])

    def _extra_raw(self, raw):
        raw["rod_tension"] = float(raw["engine_multipliers"][self.rod_index])
