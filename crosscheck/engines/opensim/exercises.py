"""OpenSim models of Exercises 6.1, 6.2 and 6.4 (geometry as assumed in the reference's docstrings).

The reference writes these in RELAXED dependent coordinates (a body's mass center free of its
angle, tied back by two multiplier rows). OpenSim models the mechanism itself, so the reference's
multipliers are forces of the mechanism: joint reactions (``Joint.
calcReactionOnChildExpressedInGround``, Simbody's mobilizer reaction, which includes the
constraint forces) and the closure's multipliers. Each class's docstring writes the map.
"""

from __future__ import annotations

import math

import numpy as np
import opensim as osim

from crosscheck.engines.kinematics import IdentityMaps
from crosscheck.engines.opensim.engine_model import (
    OsimModel,
    custom_joint,
    lamina,
    point_body,
    vec3,
)

__all__ = ["Exercise61", "Exercise62", "Exercise64"]


def _np(v) -> np.ndarray:
    return np.array([v.get(0), v.get(1), v.get(2)], float)


def reaction(joint, state) -> tuple[np.ndarray, np.ndarray]:
    """(moment, force) the parent applies to the child through the joint, ground axes, about
    the child frame's origin (Joint.calcReactionOnChildExpressedInGround). The SpatialVec is
    held while its parts are read: SpatialVec.get(k) returns a view, and reading it from a
    temporary returned garbage (1e-213, 1e166 measured)."""
    sv = joint.calcReactionOnChildExpressedInGround(state)
    return _np(sv.get(0)), _np(sv.get(1))


def _reaction_force(joint, state) -> np.ndarray:
    return reaction(joint, state)[1]


def _spring_damper(owner, coord, k, c) -> None:
    """-k q - c q' on a coordinate (SpringGeneralizedForce, rest length 0); registered in
    owner.springs, because OpenSim's calcPotentialEnergy leaves this spring's k q^2 / 2 out
    (measured: the gap to the reference's V is exactly that term)."""
    model = owner.model
    owner.springs.append((coord, float(k)))
    f = osim.SpringGeneralizedForce(coord)
    f.setStiffness(float(k))
    f.setRestLength(0.0)
    f.setViscosity(float(c))
    model.addForce(f)


def prescribed_load(model, name, body, force=None, torque=None, in_ground=True) -> None:
    """A constant force (at the body origin) and/or torque on a body, ground or body axes."""
    f = osim.PrescribedForce(name, body)
    f.setForceIsInGlobalFrame(bool(in_ground))
    if force is not None:
        f.setForceFunctions(*(osim.Constant(float(x)) for x in force))
    if torque is not None:
        f.setTorqueFunctions(*(osim.Constant(float(x)) for x in torque))
    model.addForce(f)


class Exercise61(IdentityMaps, OsimModel):
    """Exercise 6.1 (Y up): a massless slider A on a CustomJoint along the exact ground X axis
    (x; SpringGeneralizedForce k, c on it), the block P (point mass m_p) on one along Y (y; a
    PrescribedForce (0, -F, 0) on it), the bar on a PinJoint at A (theta: its body frame's +Y is
    A -> B, so A -> B = (-sin, cos) as in the reference; mass center (0, l/2, 0), lamina inertia
    from m l^2/12), and a PointConstraint closing the loop at B between the bar's (0, l, 0) and
    the block. q_e = q_ref = (x, y, theta).

    Multipliers. The reference's (lambda1, lambda2), derived in the Pinocchio adapter's
    docstring from the bar's and block's Newton equations, are
        lambda1 = (F_Bx - F_Ax) / 2,   lambda2 = (F_Ay - F_By) / 2,
    F_A, F_B the forces on the bar at A and B (ground axes). Here F_B = lambda_s[0:2] (the
    PointConstraint applies +lambda_s to its body 1, the bar, measured with
    Constraint.calcConstraintForces) and F_A is the PinJoint's reaction on the bar
    (calcReactionOnChildExpressedInGround). raw["spring_damper_force"] = -k x - c x' equals
    F_Ax (the slider is massless)."""

    nq_ref = n_ref = 3

    def _build(self):
        p = self.params
        g = self.model.getGround()
        slider = osim.Body("slider_A", 0.0, vec3(), osim.Inertia(0.0))
        self.model.addBody(slider)
        self.model.addJoint(custom_joint("x", g, slider, translations=(("x", (1, 0, 0), 1, 0),)))
        block = point_body("block", p["m_p"])
        self.model.addBody(block)
        self.model.addJoint(custom_joint("y", g, block, translations=(("y", (0, 1, 0), 1, 0),)))
        bar = lamina("bar", p["m"], (0, p["l"] / 2, 0), p["m"] * p["l"] ** 2 / 12)
        self.model.addBody(bar)
        bar_joint = osim.PinJoint("theta", slider, vec3(), vec3(), bar, vec3(), vec3())
        bar_joint.upd_coordinates(0).setName("theta")
        self.model.addJoint(bar_joint)
        self.model.addConstraint(osim.PointConstraint(bar, vec3(0, p["l"]), block, vec3()))
        _spring_damper(self, "x", p["k"], p["c"])
        prescribed_load(self.model, "F", block, force=(0.0, -p["F"], 0.0))
        self.defaults = {"x": p["l"] * math.sin(0.4), "y": p["l"] * math.cos(0.4), "theta": 0.4}

    def end_forces(self):
        """(F_A, F_B) on the bar, ground axes (after realizeAcceleration)."""
        F_A = _reaction_force(self.joint("theta"), self.state)
        F_B = np.asarray(self.state.getMultipliers().to_numpy(), float)[0:3].copy()
        return F_A, F_B

    def _multipliers(self, lam_s):
        F_A, F_B = self.end_forces()
        return np.array([0.5 * (F_B[0] - F_A[0]), 0.5 * (F_A[1] - F_B[1])])

    def _extra_raw(self, raw):
        F_A, F_B = self.end_forces()
        raw["force_on_bar_at_A"], raw["force_on_bar_at_B"] = F_A, F_B
        qe, ve = raw["engine_q"], raw["engine_v"]
        p = self.map_params
        raw["spring_damper_force"] = float(-p["k"] * qe[0] - p["c"] * ve[0])


class Exercise62(OsimModel):
    """Exercise 6.2 (Y DOWN in the reference, Y up in the engine): the block (point mass m1) on
    a CustomJoint along ground X (x; SpringGeneralizedForce k, c and a PrescribedForce (F, 0, 0)
    on it), the bar on a PinJoint at the block's origin A (theta; mass center (0, -l/2, 0), so
    it hangs down at theta = 0 and G - A = (l/2 S, -l/2 C) in engine axes; lamina inertia from
    m2 l^2/12). Engine q = (x, theta); the reference's (x_G, y_G) = G - A with y down are read
    from the engine (Frame.findStationLocation/Velocity/AccelerationInGround of G and A),
    y flipped. Multipliers: the force of the pin A on the bar, the bar joint's reaction on its
    child in ground axes, y flipped: (lambda1, lambda2) = (F_x, -F_y)."""

    nq_ref = n_ref = 4

    def _build(self):
        p = self.params
        block = point_body("block", p["m1"])
        self.model.addBody(block)
        self.model.addJoint(
            custom_joint("x", self.model.getGround(), block, translations=(("x", (1, 0, 0), 1, 0),))
        )
        bar = lamina("bar", p["m2"], (0, -p["l"] / 2, 0), p["m2"] * p["l"] ** 2 / 12)
        self.model.addBody(bar)
        bar_joint = osim.PinJoint("theta", block, vec3(), vec3(), bar, vec3(), vec3())
        bar_joint.upd_coordinates(0).setName("theta")
        self.model.addJoint(bar_joint)
        _spring_damper(self, "x", p["k"], p["c"])
        prescribed_load(self.model, "F", block, force=(p["F"], 0.0, 0.0))
        self.block, self.bar, self.G = block, bar, vec3(0, -p["l"] / 2, 0)

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        return q[0:2].copy(), u[0:2].copy()

    def _relative(self, kind: str) -> np.ndarray:
        """G - A (position, velocity or acceleration in ground) from the engine's frames."""
        f = {
            "p": "findStationLocationInGround",
            "v": "findStationVelocityInGround",
            "a": "findStationAccelerationInGround",
        }[kind]
        return _np(getattr(self.bar, f)(self.state, self.G)) - _np(
            getattr(self.block, f)(self.state, vec3())
        )

    def from_engine_state(self, qe, ve):
        self._set_state(qe, ve)
        self.model.realizeVelocity(self.state)
        dp, dv = self._relative("p"), self._relative("v")
        return (np.array([qe[0], qe[1], dp[0], -dp[1]]), np.array([ve[0], ve[1], dv[0], -dv[1]]))

    def _acc_to_reference(self, qe, ve, ae):
        da = self._relative("a")  # state realized to acceleration by forward()
        return np.array([ae[0], ae[1], da[0], -da[1]])

    def _multipliers(self, lam_s):
        F = _reaction_force(self.joint("theta"), self.state)
        return np.array([F[0], -F[1]])


class Exercise64(OsimModel):
    """Exercise 6.4 (Z up): the disk D on a CustomJoint rotating about the exact ground Z
    (phi; inertia diag(m_d R^2/4, m_d R^2/4, m_d R^2/2); a PrescribedForce torque M_phi about
    Z), the bar on a CustomJoint rotating about the disk's exact x axis at P = (0, R, 0) (theta;
    mass center (0, 0, -l/2), inertia diag(m l^2/12, m l^2/12, 0) exactly as the reference;
    SpringGeneralizedForce k, c on theta; M_theta as a PrescribedForce pair: +M_theta about the
    bar's x axis on the bar, -M_theta about the disk's x axis on the disk, the same axis).
    Engine q = (phi, theta); (y_G, z_G) are G's disk-frame coordinates, from the hinge:
    r = P + Rx(theta) c, r' = w x (Rx c), r'' = w' x (Rx c) + w x (w x Rx c), w = (theta', 0, 0).
    Multipliers: the force of the pin on the bar in disk axes: the bar joint's reaction on its
    child (ground axes) re-expressed in the disk frame: (lambda1, lambda2) = its (y, z)."""

    nq_ref = n_ref = 4
    up = (0.0, 0.0, 1.0)

    def _build(self):
        p = self.params
        Id = p["m_d"] * p["R"] ** 2
        disk = osim.Body("disk", p["m_d"], vec3(), osim.Inertia(Id / 4, Id / 4, Id / 2, 0, 0, 0))
        self.model.addBody(disk)
        self.model.addJoint(
            custom_joint("phi", self.model.getGround(), disk, rotations=(("phi", (0, 0, 1), 1, 0),))
        )
        Ib = p["m"] * p["l"] ** 2 / 12
        bar = osim.Body("bar", p["m"], vec3(0, 0, -p["l"] / 2), osim.Inertia(Ib, Ib, 0, 0, 0, 0))
        self.model.addBody(bar)
        self.model.addJoint(
            custom_joint(
                "theta",
                disk,
                bar,
                rotations=(("theta", (1, 0, 0), 1, 0),),
                parent_offset=(0, p["R"], 0),
            )
        )
        _spring_damper(self, "theta", p["k"], p["c"])
        prescribed_load(self.model, "M_phi", disk, torque=(0, 0, p["M_phi"]))
        prescribed_load(
            self.model, "M_theta_bar", bar, torque=(p["M_theta"], 0, 0), in_ground=False
        )
        prescribed_load(
            self.model, "M_theta_disk", disk, torque=(-p["M_theta"], 0, 0), in_ground=False
        )
        self.disk = disk
        self.P = np.array([0.0, p["R"], 0.0])
        self.c = np.array([0.0, 0.0, -p["l"] / 2])

    def _G_disk(self, th, thd, thdd):
        C, S = math.cos(th), math.sin(th)
        Rc = np.array([[1, 0, 0], [0, C, -S], [0, S, C]]) @ self.c
        w, wd = np.array([thd, 0.0, 0.0]), np.array([thdd, 0.0, 0.0])
        return self.P + Rc, np.cross(w, Rc), np.cross(wd, Rc) + np.cross(w, np.cross(w, Rc))

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        return q[0:2].copy(), u[0:2].copy()

    def from_engine_state(self, qe, ve):
        r, rd, _ = self._G_disk(qe[1], ve[1], 0.0)
        return np.array([qe[0], qe[1], r[1], r[2]]), np.array([ve[0], ve[1], rd[1], rd[2]])

    def _acc_to_reference(self, qe, ve, ae):
        _, _, rdd = self._G_disk(qe[1], ve[1], ae[1])
        return np.array([ae[0], ae[1], rdd[1], rdd[2]])

    def _multipliers(self, lam_s):
        F = _reaction_force(self.joint("theta"), self.state)
        Fd = _np(
            self.model.getGround().expressVectorInAnotherFrame(self.state, vec3(*F), self.disk)
        )
        return np.array([Fd[1], Fd[2]])
