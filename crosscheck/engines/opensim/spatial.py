"""OpenSim model of the 3-D double pendulum (Example 4): two links on BallJoints.

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

from .common import OsimModel, vec3

__all__ = ["DoublePendulum3D"]


def _np(v) -> np.ndarray:
    return np.array([v.get(0), v.get(1), v.get(2)], float)


def _R313(a, b, c) -> np.ndarray:
    """The textbook's 3-1-3 matrix (N components -> body components), Example 4."""
    C1, S1, C2, S2, C3, S3 = (math.cos(a), math.sin(a), math.cos(b), math.sin(b),
                              math.cos(c), math.sin(c))
    return np.array([[C1 * C3 - S1 * C2 * S3, S1 * C3 + C1 * C2 * S3, S2 * S3],
                     [-C1 * S3 - S1 * C2 * C3, -S1 * S3 + C1 * C2 * C3, S2 * C3],
                     [S1 * S2, -C1 * S2, C2]])


def _angles313(Rnb) -> np.ndarray:
    """3-1-3 angles of an N -> body matrix, branch theta2 in [0, pi] (the reference's sampler
    keeps theta2 in [0.3, pi - 0.3])."""
    b = math.acos(max(-1.0, min(1.0, Rnb[2, 2])))
    return np.array([math.atan2(Rnb[2, 0], -Rnb[2, 1]), b, math.atan2(Rnb[0, 2], Rnb[1, 2])])


def _xyz(R) -> np.ndarray:
    """Body-fixed X-Y-Z angles (x, y, z) with R = Rx(x) Ry(y) Rz(z)."""
    y = math.asin(max(-1.0, min(1.0, R[0, 2])))
    return np.array([math.atan2(-R[1, 2], R[2, 2]), y, math.atan2(-R[0, 1], R[0, 0])])


def _Rxyz(x, y, z) -> np.ndarray:
    cx, sx, cy, sy, cz, sz = (math.cos(x), math.sin(x), math.cos(y), math.sin(y),
                              math.cos(z), math.sin(z))
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rx @ Ry @ Rz


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

    def _build(self):
        p = self.params
        g = self.model.getGround()
        self.links, self.joints = [], []
        parent, at = g, vec3()
        for i in (1, 2):
            link = osim.Body(f"link{i}", p[f"m{i}"], vec3(0, -p[f"l{i}"] / 2, 0),
                             osim.Inertia(p[f"I{i}_11"], p[f"I{i}_22"], p[f"I{i}_33"], 0, 0, 0))
            self.model.addBody(link)
            name = "O" if i == 1 else "A"
            joint = osim.BallJoint(name, parent, at, vec3(), link, vec3(), vec3())
            for k, ax in enumerate("xyz"):
                joint.upd_coordinates(k).setName(f"{name}_{ax}")
            self.model.addJoint(joint)
            self.links.append(link)
            self.joints.append(joint)
            parent, at = link, vec3(0, -p["l1"], 0)
        self.rho = [np.array([0.0, -p["l1"] / 2, 0.0]), np.array([0.0, -p["l2"] / 2, 0.0])]
        self.rhoA = np.array([0.0, -p["l1"], 0.0])

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        R1, R2 = _R313(*q[0:3]), _R313(*q[3:6])
        B1, B2 = R1.T, R2.T
        qe = np.concatenate([_xyz(B1), _xyz(R1 @ B2)])
        ve = np.concatenate([B1 @ u[0:3], R1 @ B2 @ u[3:6] - u[0:3]])
        return qe, ve

    def _rotations(self, qe):
        B1 = _Rxyz(*qe[0:3])
        return B1, B1 @ _Rxyz(*qe[3:6])

    def from_engine_state(self, qe, ve):
        B1, B2 = self._rotations(qe)
        w1g = ve[0:3]
        w2g = w1g + B1 @ ve[3:6]
        v1 = np.cross(w1g, B1 @ self.rho[0])
        v2 = np.cross(w1g, B1 @ self.rhoA) + np.cross(w2g, B2 @ self.rho[1])
        q = np.concatenate([_angles313(B1.T), _angles313(B2.T)])
        return q, np.concatenate([B1.T @ w1g, B2.T @ w2g, v1, v2])

    def _acc_to_reference(self, qe, ve, ae):
        s = self.state  # realized to acceleration by forward()
        out = []
        for link in self.links:
            R = np.array([[link.getTransformInGround(s).R().get(i, j) for j in range(3)]
                          for i in range(3)])
            out.append(R.T @ _np(link.getAccelerationInGround(s).get(0)))
        for link, rho in zip(self.links, self.rho):
            out.append(_np(link.findStationAccelerationInGround(s, vec3(*rho))))
        return np.concatenate(out)

    def _multipliers(self, lam_s):
        F_O, F_A = (_np(j.calcReactionOnChildExpressedInGround(self.state).get(1))
                    for j in self.joints)
        return np.concatenate([F_O - F_A, F_A])
