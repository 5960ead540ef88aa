"""OpenSim models of the 3-D double pendulum (Example 4, two links on BallJoints) and the top
(Exercises 6.5-6.7, one BallJoint).

Engine frame = the reference's N (N2 vertical UP, gravity (0, -g, 0)); each link's body frame is
the reference's link frame n_i (origin at its upper joint), so inertias and points carry over
as they are. OpenSim's BallJoint coordinates are body-fixed X-Y-Z Euler angles of the child in
the parent (R_FM = Rx Ry Rz, measured in tests) and its speeds the child's angular velocity
relative to the parent in PARENT axes; the maps below go through rotation matrices.
"""

from __future__ import annotations

import math

import numpy as np
import opensim as osim

from crosscheck.engines.kinematics import (
    R313,
    angles313,
    frame_bar_from_engine,
    frame_bar_to_engine,
    rotation_xyz,
    xyz_angles,
)
from crosscheck.engines.opensim.engine_model import OsimModel, custom_joint, vec3
from crosscheck.engines.opensim.exercises import prescribed_load, reaction

__all__ = ["DoublePendulum3D", "DoublePendulum3DFree", "FrameBar", "TopCartesian", "TopEuler"]


def _np(v) -> np.ndarray:
    return np.array([v.get(0), v.get(1), v.get(2)], float)


def _rotation(frame, state) -> np.ndarray:
    """Body -> ground rotation matrix of a frame (the Transform and its Rotation held while
    read: views into temporaries returned garbage elsewhere, see exercises.reaction)."""
    T = frame.getTransformInGround(state)
    R = T.R()
    return np.array([[R.get(i, j) for j in range(3)] for i in range(3)])


class DoublePendulum3D(OsimModel):
    """Example 4 as a tree: BallJoint O (ground -> link 1 at its origin) and BallJoint A (link 1's
    (0, -l1, 0) -> link 2's origin); link i's mass center at (0, -l_i/2, 0), central inertia
    diag(I_i11, I_i22, I_i33), exactly the reference's. q_e = (X-Y-Z angles of link 1 in N,
    of link 2 in link 1), u_e = (omega_1 in N axes, omega_2 - omega_1 in link-1 axes).

    Map. With B_i = R_i^T (body -> N, R_i the reference's 3-1-3 matrix): R_FM(O) = B_1,
    R_FM(A) = B_1^T B_2 = R_1 B_2; u_e = (B_1 w_1, R_1 B_2 w_2 - w_1) for the body-fixed w_i;
    the mass-center velocities follow from the angular ones (the reference's six motion rows).
    Accelerations: w_i' = R_i alpha_i (alpha_i the body's angular acceleration in ground, from
    Frame.getAccelerationInGround: d/dt of body components of omega is R_i alpha_i because
    omega x omega = 0) and the mass centers' accelerations (findStationAccelerationInGround).

    Multipliers (the reference's: lambda[3:6] = force of link 1 on link 2 at A, N axes;
    lambda[0:3] = F_O - lambda[3:6], F_O the ground's force on link 1 at O): the BallJoints'
    reactions on their children in ground axes (Joint.calcReactionOnChildExpressedInGround),
    lambda = (F_O - F_A, F_A)."""

    nq_ref, n_ref = 6, 12
    variant = "tree"

    def _build(self):
        p = self.params
        g = self.model.getGround()
        self.links = []
        parent, at = g, vec3()
        for i in (1, 2):
            link = osim.Body(
                f"link{i}",
                p[f"m{i}"],
                vec3(0, -p[f"l{i}"] / 2, 0),
                osim.Inertia(p[f"I{i}_11"], p[f"I{i}_22"], p[f"I{i}_33"], 0, 0, 0),
            )
            self.model.addBody(link)
            name = "O" if i == 1 else "A"
            joint = osim.BallJoint(name, parent, at, vec3(), link, vec3(), vec3())
            for k, ax in enumerate("xyz"):
                joint.upd_coordinates(k).setName(f"{name}_{ax}")
            self.model.addJoint(joint)
            self.links.append(link)
            parent, at = link, vec3(0, -p["l1"], 0)
        self.rho = [np.array([0.0, -p["l1"] / 2, 0.0]), np.array([0.0, -p["l2"] / 2, 0.0])]
        self.rhoA = np.array([0.0, -p["l1"], 0.0])

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        R1, R2 = R313(*q[0:3]), R313(*q[3:6])
        B1, B2 = R1.T, R2.T
        qe = np.concatenate([xyz_angles(B1), xyz_angles(R1 @ B2)])
        ve = np.concatenate([B1 @ u[0:3], R1 @ B2 @ u[3:6] - u[0:3]])
        return qe, ve

    def _rotations(self, qe):
        B1 = rotation_xyz(*qe[0:3])
        return B1, B1 @ rotation_xyz(*qe[3:6])

    def from_engine_state(self, qe, ve):
        B1, B2 = self._rotations(qe)
        w1g = ve[0:3]
        w2g = w1g + B1 @ ve[3:6]
        v1 = np.cross(w1g, B1 @ self.rho[0])
        v2 = np.cross(w1g, B1 @ self.rhoA) + np.cross(w2g, B2 @ self.rho[1])
        q = np.concatenate([angles313(B1.T), angles313(B2.T)])
        return q, np.concatenate([B1.T @ w1g, B2.T @ w2g, v1, v2])

    def _acc_to_reference(self, qe, ve, ae):
        s = self.state  # realized to acceleration by forward()
        out = []
        for link in self.links:
            R = _rotation(link, s)
            acc = link.getAccelerationInGround(s)  # held while read (see exercises.reaction)
            out.append(R.T @ _np(acc.get(0)))
        for link, rho in zip(self.links, self.rho, strict=True):
            out.append(_np(link.findStationAccelerationInGround(s, vec3(*rho))))
        return np.concatenate(out)

    def _multipliers(self, lam_s):
        F_O, F_A = (reaction(self.joint(name), self.state)[1] for name in ("O", "A"))
        return np.concatenate([F_O - F_A, F_A])


class DoublePendulum3DFree(DoublePendulum3D):
    """Example 4 in the textbook's own form: each link a free body (FreeJoint: X-Y-Z angles and
    origin position in ground; speeds omega and the origin's velocity, ground axes), held by
    PointConstraints at O (ground (0, 0, 0) - link 1's origin) and at A (link 1's (0, -l1, 0) -
    link 2's origin). Same link frames, inertias and acceleration map as the tree.

    Multipliers from state.getMultipliers(): Simbody's point-constraint multipliers are in
    ground axes and the constraint applies +lambda_s to its body 1, -lambda_s to its body 2
    (measured on slider_crank_split). Hence F_O = -lambda_O (ground is body 1 at O) and the
    force of link 1 on link 2 at A is -lambda_A (link 2 is body 2):
        lambda = (-lambda_O + lambda_A, -lambda_A)."""

    variant = "free"

    def _build(self):
        p = self.params
        g = self.model.getGround()
        self.links = []
        for i in (1, 2):
            link = osim.Body(
                f"link{i}",
                p[f"m{i}"],
                vec3(0, -p[f"l{i}"] / 2, 0),
                osim.Inertia(p[f"I{i}_11"], p[f"I{i}_22"], p[f"I{i}_33"], 0, 0, 0),
            )
            self.model.addBody(link)
            joint = osim.FreeJoint(f"free{i}", g, vec3(), vec3(), link, vec3(), vec3())
            for k, ax in enumerate(("rx", "ry", "rz", "tx", "ty", "tz")):
                joint.upd_coordinates(k).setName(f"link{i}_{ax}")
            self.model.addJoint(joint)
            self.links.append(link)
        self.model.addConstraint(osim.PointConstraint(g, vec3(), self.links[0], vec3()))
        self.model.addConstraint(
            osim.PointConstraint(self.links[0], vec3(0, -p["l1"], 0), self.links[1], vec3())
        )
        self.rho = [np.array([0.0, -p["l1"] / 2, 0.0]), np.array([0.0, -p["l2"] / 2, 0.0])]
        self.rhoA = np.array([0.0, -p["l1"], 0.0])
        self.defaults = {"link2_ty": -p["l1"]}  # hanging straight: an assembled configuration

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        B1, B2 = R313(*q[0:3]).T, R313(*q[3:6]).T
        w1g, w2g = B1 @ u[0:3], B2 @ u[3:6]
        A = B1 @ self.rhoA
        v1 = u[6:9] - np.cross(w1g, B1 @ self.rho[0])
        v2 = u[9:12] - np.cross(w2g, B2 @ self.rho[1])
        return (
            np.concatenate([xyz_angles(B1), np.zeros(3), xyz_angles(B2), A]),
            np.concatenate([w1g, v1, w2g, v2]),
        )

    def _rotations(self, qe):
        return rotation_xyz(*qe[0:3]), rotation_xyz(*qe[6:9])

    def from_engine_state(self, qe, ve):
        B1, B2 = self._rotations(qe)
        w1g, w2g = ve[0:3], ve[6:9]
        vG1 = ve[3:6] + np.cross(w1g, B1 @ self.rho[0])
        vG2 = ve[9:12] + np.cross(w2g, B2 @ self.rho[1])
        q = np.concatenate([angles313(B1.T), angles313(B2.T)])
        return q, np.concatenate([B1.T @ w1g, B2.T @ w2g, vG1, vG2])

    def _multipliers(self, lam_s):
        lam_O, lam_A = lam_s[0:3], lam_s[3:6]
        return np.concatenate([-lam_O + lam_A, -lam_A])


# ======================================================================================
# Exercises 6.5-6.7: the top on a BallJoint at O (Z up)
# ======================================================================================
def _E(e) -> np.ndarray:
    """The textbook's E(eps) (omega = 2 E eps', eps4 scalar); linear in eps."""
    e1, e2, e3, e4 = e
    return np.array([[e4, e3, -e2, -e1], [-e3, e4, e1, -e2], [e2, -e1, e4, -e3]])


def _R_eps(e) -> np.ndarray:
    """Body -> N rotation of unit Euler parameters (the reference's ``rotation``)."""
    e1, e2, e3, e4 = e
    return np.array(
        [
            [e4**2 + e1**2 - e2**2 - e3**2, 2 * (e1 * e2 - e3 * e4), 2 * (e1 * e3 + e2 * e4)],
            [2 * (e1 * e2 + e3 * e4), e4**2 - e1**2 + e2**2 - e3**2, 2 * (e2 * e3 - e1 * e4)],
            [2 * (e1 * e3 - e2 * e4), 2 * (e2 * e3 + e1 * e4), e4**2 - e1**2 - e2**2 + e3**2],
        ]
    )


def _eps_of(R) -> np.ndarray:
    """Unit Euler parameters of a rotation (Shepperd's branch choice), eps4 >= 0."""
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    k = int(np.argmax([R[0, 0], R[1, 1], R[2, 2], tr]))
    if k == 3:
        w = 0.5 * math.sqrt(1.0 + tr)
        e = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1], 0.0]) / (4 * w)
        e[3] = w
    else:
        i, j, m = k, (k + 1) % 3, (k + 2) % 3
        e = np.empty(4)
        e[i] = 0.5 * math.sqrt(1.0 + R[i, i] - R[j, j] - R[m, m])
        e[j] = (R[j, i] + R[i, j]) / (4 * e[i])
        e[m] = (R[m, i] + R[i, m]) / (4 * e[i])
        e[3] = (R[m, j] - R[j, m]) / (4 * e[i])
    return -e if e[3] < 0 else e


class _Top(OsimModel):
    """The top on a BallJoint at O = the ground origin (Z up, gravity (0, 0, -g)): body frame =
    the reference's e1, e2, e3, mass center at (0, 0, L), central inertia diag(I, I, I3).
    q_e = X-Y-Z angles of R(eps), u_e = omega in N axes = R (2 E(eps) eps')."""

    up = (0.0, 0.0, 1.0)

    def _build(self):
        p = self.params
        top = osim.Body(
            "top", p["m"], vec3(0, 0, p["L"]), osim.Inertia(p["I"], p["I"], p["I3"], 0, 0, 0)
        )
        self.model.addBody(top)
        joint = osim.BallJoint("O", self.model.getGround(), vec3(), vec3(), top, vec3(), vec3())
        for k, ax in enumerate("xyz"):
            joint.upd_coordinates(k).setName(f"O_{ax}")
        self.model.addJoint(joint)
        self.top = top

    # The engine's rotation does not know the sign of eps (eps and -eps are one rotation): the
    # maps return the branch of the last eps seen, the one mapped into the engine or the
    # previous output of a trajectory, so a round trip gives back the given eps and a
    # trajectory stays continuous (eps'' is odd in eps for a given motion, so the
    # accelerations follow the same branch).
    _branch: np.ndarray | None = None

    def _engine(self, eps, eps_dot):
        R = _R_eps(eps)
        self._branch = np.array(eps, float)
        return xyz_angles(R), R @ (2.0 * _E(eps) @ eps_dot)

    def _reference(self, qe, ve):
        """(eps, eps', omega_body, R) of an engine state, on the current branch."""
        R = rotation_xyz(*qe[0:3])
        eps = _eps_of(R)
        if self._branch is not None and eps @ self._branch < 0:
            eps = -eps
        self._branch = eps.copy()
        w = R.T @ ve
        return eps, 0.5 * _E(eps).T @ w, w, R

    def _eps_acc(self, qe, ve):
        """eps'' = (E(eps')^T omega + E(eps)^T omega') / 2, omega' in body axes from the
        engine's angular acceleration (R^T alpha)."""
        eps, eps_dot, w, R = self._reference(qe, ve)
        acc = self.top.getAccelerationInGround(self.state)  # held while read
        alpha = _np(acc.get(0))
        return 0.5 * (_E(eps_dot).T @ w + _E(eps).T @ (R.T @ alpha))

    def _socket_force(self) -> np.ndarray:
        return reaction(self.joint("O"), self.state)[1]


class TopEuler(_Top):
    """Exercises 6.5/6.6 (q = eps, u = eps'). The reference's single row is the normalization,
    which the engine's rotation satisfies by construction: no engine force maps to it, and its
    multiplier depends on the formulation (0 for d'Alembert and Kane, 2V - 4K for Lagrange),
    so multipliers is None; raw carries both textbook values from the engine's K and V and the
    socket force."""

    nq_ref = n_ref = 4
    multipliers_note = (
        "the normalization's multiplier is not a force (formulation-dependent: "
        "0 for d'Alembert and Kane, 2V - 4K for Lagrange); raw carries both"
    )

    def to_engine_state(self, q, u):
        return self._engine(np.asarray(q, float), np.asarray(u, float))

    def from_engine_state(self, qe, ve):
        eps, eps_dot, _, _ = self._reference(qe, ve)
        return eps, eps_dot

    def _acc_to_reference(self, qe, ve, ae):
        return self._eps_acc(qe, ve)

    def _multipliers(self, lam_s):
        return None

    def _extra_raw(self, raw):
        K = float(self.model.calcKineticEnergy(self.state))
        V = float(self.model.calcPotentialEnergy(self.state))
        raw["normalization_lambda_dalembert_kane"] = 0.0
        raw["normalization_lambda_lagrange"] = 2.0 * V - 4.0 * K
        raw["socket_force"] = self._socket_force()


class TopCartesian(_Top):
    """Exercise 6.7 (q = (x, eps), u = (x', eps')), the same tree: x = L R e3 and its rates
    follow from the rotation; x'' is the mass center's acceleration
    (findStationAccelerationInGround). Multipliers: (lambda1..3) = the socket's force on the top
    = the BallJoint's reaction on its child (ground = N axes); lambda4, the normalization's
    (formulation-dependent, d'Alembert and Kane only here), is 2 x . (lambda1..3) (reference
    docstring)."""

    nq_ref = n_ref = 7

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        return self._engine(q[3:7], u[3:7])

    def from_engine_state(self, qe, ve):
        eps, eps_dot, _, R = self._reference(qe, ve)
        x = self.map_params["L"] * R[:, 2]
        return np.concatenate([x, eps]), np.concatenate([np.cross(ve, x), eps_dot])

    def _acc_to_reference(self, qe, ve, ae):
        a_G = _np(
            self.top.findStationAccelerationInGround(self.state, vec3(0, 0, self.map_params["L"]))
        )
        return np.concatenate([a_G, self._eps_acc(qe, ve)])

    def _multipliers(self, lam_s):
        F = self._socket_force()
        x = _np(self.top.findStationLocationInGround(self.state, vec3(0, 0, self.map_params["L"])))
        return np.concatenate([F, [2.0 * x @ F]])


# ======================================================================================
# Example 3: the rotating frame and bar (no gravity)
# ======================================================================================
class FrameBar(OsimModel):
    """Example 3. A massless frame F on a CustomJoint rotating about the exact ground Z (phi),
    the bar on a CustomJoint rotating about F's exact y axis (the arm n2) at (0, d, 0) in F
    (theta), its mass center at the joint origin with central inertia diag(I1, I2, I3) along
    e1, e2 = n2, e3 (the reference's R = rot_z(phi) rot_y(theta)). No gravity. M_phi: a
    PrescribedForce torque on F about Z; M_theta: +M_theta about the bar's y axis on the bar,
    -M_theta about F's y axis (the same axis n2) on F.

    Speeds: omega = phi' k + theta' e2 = (-S phi', theta', C phi') (body axes) and inversely
    theta' = omega2, phi' = -S omega1 + C omega3 (exact on omega1 C + omega3 S = 0). u' = the
    bar's body-fixed angular acceleration, R^T alpha (Frame.getAccelerationInGround).

    Multiplier: the n1 component of the ground's bearing moment on F about O (reference
    docstring): the phi joint's reaction moment on its child F at O (ground axes), dotted with
    n1 = (cos phi, sin phi, 0)."""

    nq_ref, n_ref = 2, 3
    up = (0.0, 0.0, 1.0)

    def _build(self):
        p = self.params
        frame = osim.Body("F", 0.0, vec3(), osim.Inertia(0.0))
        self.model.addBody(frame)
        self.model.addJoint(
            custom_joint(
                "phi", self.model.getGround(), frame, rotations=(("phi", (0, 0, 1), 1, 0),)
            )
        )
        bar = osim.Body("bar", p["m"], vec3(), osim.Inertia(p["I1"], p["I2"], p["I3"], 0, 0, 0))
        self.model.addBody(bar)
        self.model.addJoint(
            custom_joint(
                "theta",
                frame,
                bar,
                rotations=(("theta", (0, 1, 0), 1, 0),),
                parent_offset=(0, p["d"], 0),
            )
        )
        prescribed_load(self.model, "M_phi", frame, torque=(0, 0, p["M_phi"]))
        prescribed_load(
            self.model, "M_theta_bar", bar, torque=(0, p["M_theta"], 0), in_ground=False
        )
        prescribed_load(
            self.model, "M_theta_F", frame, torque=(0, -p["M_theta"], 0), in_ground=False
        )
        self.bar = bar

    def to_engine_state(self, q, u):
        return frame_bar_to_engine(q, u)

    def from_engine_state(self, qe, ve):
        return frame_bar_from_engine(qe, ve)

    def _acc_to_reference(self, qe, ve, ae):
        s = self.state
        R = _rotation(self.bar, s)
        acc = self.bar.getAccelerationInGround(s)  # held while read
        return R.T @ _np(acc.get(0))

    def _multipliers(self, lam_s):
        phi = float(self._read(self.state.getQ())[0])
        M = reaction(self.joint("phi"), self.state)[0]
        return np.array([M @ np.array([math.cos(phi), math.sin(phi), 0.0])])
