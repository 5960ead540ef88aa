"""MuJoCo models (and their MJCF) of the 3-D examples: the double pendulum (Example 4)
and the symmetric top with Euler parameters (Exercises 6.5-6.7)."""

from __future__ import annotations

import mujoco
import numpy as np

from crosscheck.engines.kinematics import R313, E, angles313, eps_ddot
from crosscheck.engines.mujoco.engine_model import (
    MjEngineModel,
    R_to_quat,
    document,
    num,
    quat_to_R,
    vec,
)


def _xml_double_pendulum(p, variant="free", **kw) -> str:
    l1, l2, m1, m2 = p["l1"], p["l2"], p["m1"], p["m2"]
    I1 = vec(p["I1_11"], p["I1_22"], p["I1_33"])
    I2 = vec(p["I2_11"], p["I2_22"], p["I2_33"])
    if variant == "tree":
        bodies = f"""      <body name="link1">
        <joint name="O" type="ball"/>
        <inertial pos="{vec(0, -l1 / 2, 0)}" mass="{num(m1)}" diaginertia="{I1}"/>
        <geom type="capsule" fromto="0 0 0 0 {num(-l1)} 0" size="0.02"/>
        <body name="link2" pos="{vec(0, -l1, 0)}">
          <joint name="A" type="ball"/>
          <inertial pos="{vec(0, -l2 / 2, 0)}" mass="{num(m2)}" diaginertia="{I2}"/>
          <geom type="capsule" fromto="0 0 0 0 {num(-l2)} 0" size="0.02"/>
        </body>
      </body>
"""
        eq = ""
    else:
        bodies = f"""      <body name="link1" pos="{vec(0, -l1 / 2, 0)}">
        <freejoint name="link1"/>
        <inertial pos="0 0 0" mass="{num(m1)}" diaginertia="{I1}"/>
        <geom type="capsule" fromto="0 {num(l1 / 2)} 0 0 {num(-l1 / 2)} 0" size="0.02"/>
        <site name="O_link1" pos="{vec(0, l1 / 2, 0)}"/>
        <site name="A_link1" pos="{vec(0, -l1 / 2, 0)}"/>
      </body>
      <body name="link2" pos="{vec(0, -l1 - l2 / 2, 0)}">
        <freejoint name="link2"/>
        <inertial pos="0 0 0" mass="{num(m2)}" diaginertia="{I2}"/>
        <geom type="capsule" fromto="0 {num(l2 / 2)} 0 0 {num(-l2 / 2)} 0" size="0.02"/>
        <site name="A_link2" pos="{vec(0, l2 / 2, 0)}"/>
      </body>
"""
        eq = (
            '    <connect name="O" site1="O_link1" site2="origin"/>\n'
            '    <connect name="A" site1="A_link2" site2="A_link1"/>\n'
        )
    return document(
        f"double_pendulum_3d_{variant}",
        (0, -p["g"], 0),
        bodies,
        eq,
        note="Example 4: N2 = +Y up, links hang along -n_i2 (body -Y)",
        wrap=variant == "tree",
        **kw,
    )


def _xml_top(p, variant="euler", **kw) -> str:
    m, L, I, I3 = p["m"], p["L"], p["I"], p["I3"]
    if variant == "euler":
        bodies = f"""      <body name="top">
        <joint name="O" type="ball"/>
        <inertial pos="{vec(0, 0, L)}" mass="{num(m)}" diaginertia="{vec(I, I, I3)}"/>
        <geom type="cylinder" fromto="0 0 0 0 0 {num(L)}" size="0.04"/>
      </body>
"""
        eq = ""
    else:
        bodies = f"""      <body name="top" pos="{vec(0, 0, L)}">
        <freejoint name="top"/>
        <inertial pos="0 0 0" mass="{num(m)}" diaginertia="{vec(I, I, I3)}"/>
        <geom type="cylinder" fromto="0 0 {num(-L)} 0 0 0" size="0.04"/>
        <site name="O_top" pos="{vec(0, 0, -L)}"/>
      </body>
"""
        # body-based (world side inferred at qpos0, where the top stands upright with O at the
        # origin): the site-based form crashes Pinocchio 4.1's MJCF parser (segfault)
        eq = f'    <connect name="O" body1="top" anchor="{vec(0, 0, -L)}"/>\n'
    return document(
        f"top_{variant}",
        (0, 0, -p["g"]),
        bodies,
        eq,
        note="Exercises 6.5-6.7: Z up; quaternion wxyz = (eps4, eps1, eps2, eps3)",
        wrap=variant == "euler",
        **kw,
    )


# ======================================================================================
# Example 4: 3-D double pendulum


# ======================================================================================


class _DoublePendulumBase(MjEngineModel):
    nq_ref, n_ref = 6, 12

    def _body_rotations(self, q):
        """Body -> world rotations Q_i = R_i^T of the textbook's R_i (N -> n_i)."""
        q = np.asarray(q, float)
        return R313(*q[0:3]).T, R313(*q[3:6]).T

    def _speeds(self, Q1, Q2, w1b, w2b):
        """Consistent v_G1, v_G2 (world) from the body-fixed omegas."""
        l1, l2 = self.map_params["l1"], self.map_params["l2"]
        w1, w2 = Q1 @ w1b, Q2 @ w2b
        rG1 = Q1 @ np.array([0.0, -l1 / 2, 0.0])
        rA = Q1 @ np.array([0.0, -l1, 0.0])
        rG2A = Q2 @ np.array([0.0, -l2 / 2, 0.0])
        return np.cross(w1, rG1), np.cross(w1, rA) + np.cross(w2, rG2A)


class DoublePendulumFree(_DoublePendulumBase):
    """Example 4 as the textbook writes it: two free bodies and two point constraints.

    Each link is a free body whose frame is at its mass center G_i with axes n_i (the link
    hangs along -n_i2). MuJoCo's free joint: qpos = [G_i (world), quaternion wxyz of Q_i = R_i^T],
    qvel = [v_G (world), omega (body)], so qvel is a permutation of the reference's speeds
    (w1, w2, v1, v2) and qacc[0:3] is the classical world acceleration of G_i: P is a
    permutation and M maps exactly.

    Connects: "O": site1 = link 1's O, site2 = the world origin, so efc_force[0:3] = F_O, the
    ground's force on link 1 at O; "A": site1 = link 2's A, site2 = link 1's A, so
    efc_force[3:6] = F_A, the force of link 1 on link 2 at A (world = N components). The
    reference's multipliers are lambda[3:6] = F_A and lambda[0:3] = F_O - F_A."""

    variant = "free"
    _P = np.zeros((12, 12))
    for i, j in enumerate((6, 7, 8, 0, 1, 2, 9, 10, 11, 3, 4, 5)):
        _P[i, j] = 1.0  # engine speed i = reference speed j

    def _xml(self, **kw):
        return _xml_double_pendulum(self.params, "free", **kw)

    def to_engine_state(self, q, u):
        Q1, Q2 = self._body_rotations(q)
        l1, l2 = self.map_params["l1"], self.map_params["l2"]
        G1 = Q1 @ np.array([0.0, -l1 / 2, 0.0])
        G2 = Q1 @ np.array([0.0, -l1, 0.0]) + Q2 @ np.array([0.0, -l2 / 2, 0.0])
        qe = np.concatenate([G1, R_to_quat(Q1), G2, R_to_quat(Q2)])
        return qe, self._P @ np.asarray(u, float)

    def from_engine_state(self, qe, ve):
        q = []
        for k in (3, 10):
            q += list(angles313(quat_to_R(qe[k : k + 4]).T))
        return np.array(q), self._P.T @ np.asarray(ve, float)

    def _acc_to_reference(self, qe, ve, ae):
        return self._P.T @ np.asarray(ae, float)

    def _multipliers(self, qe, ve, ae, f):
        FO, FA = np.asarray(f[0:3]), np.asarray(f[3:6])
        return np.concatenate([FO - FA, FA])


class DoublePendulumTree(_DoublePendulumBase):
    """Example 4 as a ball-joint tree: ball at O (link 1 relative to the world), ball at A
    (link 2 relative to link 1); body frames at O and A with axes n_i, mass centers at
    (0, -l_i/2, 0). qpos = [quat(Q1), quat(Q1^T Q2)] (wxyz); qvel = [omega1 (link-1 frame),
    omega2 - omega1 in link-2 components]. The reference's dependent v_G follow from the
    kinematics; u' from qacc: alpha1 = Q1 a1, alpha2 = alpha1 + Q2 a2 + omega1 x (Q2 v2)
    (world), omega_i' (body) = Q_i^T alpha_i, a_G by the rigid-body formula.

    Multipliers (no constraint rows: exact, no softness): after mj_rnePostConstraint,
    cfrc_int[b][3:6] is the force of the parent on body b (world): F_O = cfrc_int[link1],
    F_A = cfrc_int[link2], lambda = [F_O - F_A, F_A]."""

    variant = "tree"
    mass_matrix_note = (
        "the reference's twelve speeds (w1, w2, v_G1, v_G2) are dependent (six "
        "point-constraint rows) and do not map one to one onto the ball-joint "
        "tree's six relative angular velocities"
    )

    def _xml(self, **kw):
        return _xml_double_pendulum(self.params, "tree", **kw)

    def _post_build(self):
        self.b1 = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_BODY, "link1")
        self.b2 = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_BODY, "link2")

    def to_engine_state(self, q, u):
        Q1, Q2 = self._body_rotations(q)
        u = np.asarray(u, float)
        w1b, w2b = u[0:3], u[3:6]
        qe = np.concatenate([R_to_quat(Q1), R_to_quat(Q1.T @ Q2)])
        ve = np.concatenate([w1b, w2b - Q2.T @ Q1 @ w1b])
        return qe, ve

    def _engine_rotations(self, qe):
        Q1 = quat_to_R(qe[0:4])
        return Q1, Q1 @ quat_to_R(qe[4:8])

    def from_engine_state(self, qe, ve):
        Q1, Q2 = self._engine_rotations(qe)
        w1b = np.asarray(ve[0:3], float)
        w2b = np.asarray(ve[3:6], float) + Q2.T @ Q1 @ w1b
        v1, v2 = self._speeds(Q1, Q2, w1b, w2b)
        q = np.concatenate([angles313(Q1.T), angles313(Q2.T)])
        return q, np.concatenate([w1b, w2b, v1, v2])

    def _acc_to_reference(self, qe, ve, ae):
        Q1, Q2 = self._engine_rotations(qe)
        l1, l2 = self.map_params["l1"], self.map_params["l2"]
        ve, ae = np.asarray(ve, float), np.asarray(ae, float)
        w1 = Q1 @ ve[0:3]
        w2r = Q2 @ ve[3:6]
        w2 = w1 + w2r
        al1 = Q1 @ ae[0:3]
        al2 = al1 + Q2 @ ae[3:6] + np.cross(w1, w2r)
        rG1 = Q1 @ np.array([0.0, -l1 / 2, 0.0])
        rA = Q1 @ np.array([0.0, -l1, 0.0])
        rG2A = Q2 @ np.array([0.0, -l2 / 2, 0.0])
        aG1 = np.cross(al1, rG1) + np.cross(w1, np.cross(w1, rG1))
        aA = np.cross(al1, rA) + np.cross(w1, np.cross(w1, rA))
        aG2 = aA + np.cross(al2, rG2A) + np.cross(w2, np.cross(w2, rG2A))
        return np.concatenate([Q1.T @ al1, Q2.T @ al2, aG1, aG2])

    def _extra_raw(self, raw):
        mujoco.mj_rnePostConstraint(self.m, self.d)
        self._F = (self.d.cfrc_int[self.b1, 3:6].copy(), self.d.cfrc_int[self.b2, 3:6].copy())

    def _multipliers(self, qe, ve, ae, f):
        FO, FA = self._F
        return np.concatenate([FO - FA, FA])


# ======================================================================================
# Exercises 6.5-6.7: the top with Euler parameters


# ======================================================================================


class _TopBase(MjEngineModel):
    """Euler parameters eps = (eps1, eps2, eps3, eps4), eps4 scalar, R(eps) the standard
    quaternion rotation (body -> inertial), omega_body = 2 E eps' (reference docstring; this is
    q* x q' for q = eps4 + eps1 i + eps2 j + eps3 k): MuJoCo's wxyz quaternion is
    (eps4, eps1, eps2, eps3) with the same rotation direction (checked in the tests through
    xmat). eps' = E^T omega / 2 on the manifold, and
    eps'' = (E'^T omega + E^T omega') / 2 with E' = E(eps')."""

    @staticmethod
    def _quat(eps):
        e = np.asarray(eps, float)
        q = np.array([e[3], e[0], e[1], e[2]])
        return q / np.linalg.norm(q)

    @staticmethod
    def _eps(quat):
        q = np.asarray(quat, float)
        q = q / np.linalg.norm(q)
        return np.array([q[1], q[2], q[3], q[0]])

    _eps_ddot = staticmethod(eps_ddot)


class TopEuler(_TopBase):
    """Exercises 6.5/6.6: a ball joint at O (the body frame at O with axes e_i; G at (0, 0, L)).
    qpos = quaternion, qvel = omega (body) = 2 E eps'. The reference's normalization multiplier
    has no counterpart (a ball joint carries no normalization force, and the reference's value
    is formulation-dependent: 0 for d'Alembert/Kane, 2V - 4K for Lagrange), so multipliers is
    None; raw["socket_force"] is the force of the socket on the top (cfrc_int, world)."""

    nq_ref = n_ref = 4
    mass_matrix_note = (
        "the reference's M is over the four Euler-parameter rates, tied by the "
        "normalization, which do not map one to one onto the ball joint's three "
        "angular velocity components"
    )

    def _xml(self, **kw):
        return _xml_top(self.params, "euler", **kw)

    def _post_build(self):
        self.top = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_BODY, "top")

    def to_engine_state(self, q, u):
        return self._quat(q), 2.0 * E(q) @ np.asarray(u, float)

    def from_engine_state(self, qe, ve):
        eps = self._eps(qe)
        return eps, 0.5 * E(eps).T @ np.asarray(ve, float)

    def _acc_to_reference(self, qe, ve, ae):
        eps, eps_dot = self.from_engine_state(qe, ve)
        return self._eps_ddot(eps, eps_dot, np.asarray(ve, float), np.asarray(ae, float))

    def _multipliers(self, qe, ve, ae, f):
        return None

    def _extra_raw(self, raw):
        mujoco.mj_rnePostConstraint(self.m, self.d)
        raw["socket_force"] = self.d.cfrc_int[self.top, 3:6].copy()
        raw["multipliers_note"] = (
            "no normalization row in MuJoCo; the reference's lambda is "
            "formulation-dependent (0 for d'Alembert/Kane)"
        )


class TopCartesian(_TopBase):
    """Exercise 6.7: the top as a free body (frame at G, axes e_i; qpos = [G, quat], qvel =
    [G', omega body]) held at O by a `connect` (site1 = the top's O at (0, 0, -L), site2 = the
    world origin): efc_force[0:3] = the force of the socket on the top at O = (lambda1..3).

    lambda4 (normalization) has no MuJoCo row. For d'Alembert and Kane (the formulations of this
    model) it is fixed by the other three: the eps-equations' partial velocities 2 E_k are
    orthogonal to eps (E eps = 0), so summing eps_k times equation k leaves
    0 = lambda_O . (-L sum_k eps_k d(R e3)/d eps_k) + lambda4 eps.eps, and R e3 is homogeneous
    of degree 2: lambda4 = 2 L lambda_O . (R e3). It is returned from the engine's lambda_O by
    that identity (not an independent engine output; raw["lambda4_from_identity"] = True)."""

    nq_ref = n_ref = 7
    mass_matrix_note = (
        "the reference's seven speeds (x', eps') include the four Euler-parameter "
        "rates tied by the normalization and do not map one to one onto the free "
        "joint's six (x', omega)"
    )

    def _xml(self, **kw):
        return _xml_top(self.params, "cartesian", **kw)

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        return (
            np.concatenate([q[0:3], self._quat(q[3:7])]),
            np.concatenate([u[0:3], 2.0 * E(q[3:7]) @ u[3:7]]),
        )

    def from_engine_state(self, qe, ve):
        eps = self._eps(qe[3:7])
        return (
            np.concatenate([qe[0:3], eps]),
            np.concatenate([ve[0:3], 0.5 * E(eps).T @ np.asarray(ve[3:6], float)]),
        )

    def _acc_to_reference(self, qe, ve, ae):
        q, u = self.from_engine_state(qe, ve)
        ae = np.asarray(ae, float)
        return np.concatenate(
            [ae[0:3], self._eps_ddot(q[3:7], u[3:7], np.asarray(ve[3:6]), ae[3:6])]
        )

    def _multipliers(self, qe, ve, ae, f):
        lam_O = np.asarray(f[0:3], float)
        e3 = quat_to_R(qe[3:7])[:, 2]
        return np.concatenate([lam_O, [2.0 * self.map_params["L"] * float(lam_O @ e3)]])

    def _extra_raw(self, raw):
        raw["lambda4_from_identity"] = True
