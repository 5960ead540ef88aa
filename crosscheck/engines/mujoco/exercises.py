"""MuJoCo models (and their MJCF) of Exercises 6.1, 6.2 and 6.4 (geometry as assumed
in the reference's docstrings)."""

from __future__ import annotations

import math

import mujoco
import numpy as np

from crosscheck.engines.mujoco.engine_model import LIGHT, MjEngineModel, document, lamina, num, vec

_SQRT_HALF = math.sqrt(0.5)


def _xml_exercise_6_1(p, **kw) -> str:
    m, m_p, l, k, c = p["m"], p["m_p"], p["l"], p["k"], p["c"]
    eps_m, eps_I = LIGHT * m, LIGHT * m * l * l
    eps_P = LIGHT * m_p * l * l  # the block only translates: its inertia is never excited
    bodies = f"""      <body name="A">
        <joint name="x" type="slide" axis="1 0 0"
               stiffness="{num(k)}" damping="{num(c)}" springref="0"/>
        <inertial pos="0 0 0" mass="{num(eps_m)}" diaginertia="{vec(eps_I, eps_I, eps_I)}"/>
        <geom type="box" size="0.03 0.015 0.015"/>
        <body name="bar">
          <joint name="theta" type="hinge" axis="0 0 1"/>
          <inertial pos="{vec(0, l / 2, 0)}" quat="{vec(_SQRT_HALF, 0, 0, -_SQRT_HALF)}"
                    mass="{num(m)}" diaginertia="{lamina(m * l * l / 12)}"/>
          <geom type="capsule" fromto="0 0 0 0 {num(l)} 0" size="0.01"/>
          <site name="B_bar" pos="{vec(0, l, 0)}"/>
        </body>
      </body>
      <body name="block">
        <joint name="y" type="slide" axis="0 1 0"/>
        <inertial pos="0 0 0" mass="{num(m_p)}" diaginertia="{vec(eps_P, eps_P, eps_P)}"/>
        <geom type="box" size="0.03 0.03 0.03"/>
        <site name="B_block" pos="0 0 0"/>
      </body>
"""
    eq = '    <connect name="B" site1="B_bar" site2="B_block"/>\n'
    return document(
        "exercise_6_1",
        (0, -p["g"], 0),
        bodies,
        eq,
        note="Exercise 6.1 (assumed geometry, reference docstring): Y UP; light "
        "slider A on slide x (spring k, springref 0, damper c: joint "
        "stiffness/damping), bar hinged at A about +Z (hinge angle = theta, "
        "from +Y), block P on slide y; bar end B connected to P; F on y is "
        "qfrc_applied",
        **kw,
    )


def _xml_exercise_6_2(p, **kw) -> str:
    m1, m2, l, k, c = p["m1"], p["m2"], p["l"], p["k"], p["c"]
    eps_B = LIGHT * m1 * l * l  # the block only translates: its inertia is never excited
    bodies = f"""      <body name="block">
        <joint name="x" type="slide" axis="1 0 0"
               stiffness="{num(k)}" damping="{num(c)}" springref="0"/>
        <inertial pos="0 0 0" mass="{num(m1)}" diaginertia="{vec(eps_B, eps_B, eps_B)}"/>
        <geom type="box" size="0.06 0.03 0.03"/>
        <body name="bar">
          <joint name="theta" type="hinge" axis="0 0 -1"/>
          <inertial pos="{vec(0, l / 2, 0)}" quat="{vec(_SQRT_HALF, 0, 0, _SQRT_HALF)}"
                    mass="{num(m2)}" diaginertia="{lamina(m2 * l * l / 12)}"/>
          <geom type="capsule" fromto="0 0 0 0 {num(l)} 0" size="0.01"/>
        </body>
      </body>
"""
    return document(
        "exercise_6_2",
        (0, p["g"], 0),
        bodies,
        note="Exercise 6.2 (assumed geometry, reference docstring): Y DOWN "
        "(gravity +Y); block on slide x (spring k, springref 0, damper c: "
        "joint stiffness/damping; F as qfrc_applied), bar hinged at A about "
        "-Z (hinge angle = theta, from the downward vertical)",
        **kw,
    )


def _xml_exercise_6_4(p, **kw) -> str:
    m_d, R, m, l, k, c = p["m_d"], p["R"], p["m"], p["l"], p["k"], p["c"]
    I_d = m_d * R * R
    I_b = m * l * l / 12
    eps_ax = LIGHT * m * l * l  # MuJoCo rejects the slender bar's zero axial inertia
    bodies = f"""      <body name="disk">
        <joint name="phi" type="hinge" axis="0 0 1"/>
        <inertial pos="0 0 0" mass="{num(m_d)}" diaginertia="{vec(I_d / 4, I_d / 4, I_d / 2)}"/>
        <geom type="cylinder" fromto="0 0 -0.01 0 0 0.01" size="{num(R)}"/>
        <body name="bar" pos="{vec(0, R, 0)}">
          <joint name="theta" type="hinge" axis="1 0 0"
                 stiffness="{num(k)}" damping="{num(c)}" springref="0"/>
          <inertial pos="{vec(0, 0, -l / 2)}" mass="{num(m)}"
                    diaginertia="{vec(I_b, I_b, eps_ax)}"/>
          <geom type="capsule" fromto="0 0 0 0 0 {num(-l)}" size="0.01"/>
        </body>
      </body>
"""
    return document(
        "exercise_6_4",
        (0, 0, -p["g"]),
        bodies,
        note="Exercise 6.4 (assumed geometry, reference docstring): Z UP; disk "
        "hinge phi about +Z at O, bar hinge theta about the disk's +X at "
        "P = (0, R, 0) (torsional spring k, springref 0, damper c: joint "
        "stiffness/damping); motor torques as qfrc_applied; the bar's axial "
        "inertia is 1e-12 m l^2 (MuJoCo rejects 0)",
        **kw,
    )


# ======================================================================================
# Exercises 6.1, 6.2, 6.4 (geometry as assumed in the reference's docstrings)


# ======================================================================================


def _hinge_point(axis, c, angle, rate, acc):
    """Position, velocity and classical acceleration of the point c (in the child body's frame)
    of a body turning by `angle` about the unit `axis` through its frame origin, the parent
    frame fixed: r = Rot(axis, angle) c, v = w x r, a = w' x r + w x (w x r)."""
    k = np.asarray(axis, float)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    R = np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)
    r = R @ np.asarray(c, float)
    kr = K @ r  # k x r (np.cross costs ~20 us a call)
    return r, rate * kr, acc * kr + rate * rate * (K @ kr)


class _ExerciseBase(MjEngineModel):
    """Loads: joint stiffness/damping for the springs and dampers (qfrc_passive = -k (q -
    springref) - c q', springref 0 = the reference's unstretched position; d.energy[0] includes
    the joint springs' potential 1/2 k (q - springref)^2, checked against the reference's V,
    which holds k x^2/2 or k theta^2/2), constant forces/torques as qfrc_applied. MuJoCo's Euler
    integrator treats joint damping implicitly (mj_step only; mj_forward's qacc is explicit).
    mass_matrix/forcing are None: the reference's M is that of its relaxed dependent
    coordinates (the bar's mass-center coordinates free of the bar angle), which no engine
    model of the mechanism has."""

    _loads: tuple[tuple[str, str, float], ...] = ()  # (joint, parameter, sign) -> qfrc_applied
    mass_matrix_note = (
        "the reference's M belongs to its relaxed dependent coordinates (the "
        "bar's mass-center coordinates free of the bar angle), which no engine "
        "model of the mechanism has"
    )

    def _dof(self, joint: str) -> int:
        return int(self.m.jnt_dofadr[mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_JOINT, joint)])

    def _body(self, body: str) -> int:
        return mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_BODY, body)

    def _applied(self):
        a = np.zeros(self.m.nv)
        for joint, param, sign in self._loads:
            a[self._dof(joint)] += sign * self.params[param]
        return a


class Exercise61(_ExerciseBase):
    """Exercise 6.1 (Y up, gravity -g Y): light slider A (1e-12 m) on slide x with the spring
    and damper, the bar on a hinge at A about +Z whose angle IS theta (bar along the body's +Y,
    so B = A + l (-S, C)), the block P (m_p) on its own slide y, the bar's end B `connect`ed to
    P (site1 = the bar's B, so efc_force[0:3] = F_B, the force of the block on the bar at B,
    world; the z row is identically zero); F pushes P down: qfrc_applied = -F on y.
    Engine q = (x, theta, y) is a permutation of the reference's (x, y, theta).

    Multipliers. The reference's (lambda1, lambda2) are generalized forces of its relaxed
    coordinates (G = (x/2, y/2), theta free), yet they map onto the mechanism's forces: with
    F_A, F_B the forces on the bar at A and B, the bar's Newton equation m (x''/2) = F_Ax +
    F_Bx, the massless slider's F_Ax = -k x - c x', the block's m_p y'' = -F_By - m_p g - F and
    the reference's rows give
        lambda1 = (F_Bx - F_Ax) / 2,   lambda2 = (F_Ay - F_By) / 2,
    and these satisfy its theta row too (the moment of F_A, F_B about G is
    l (-lambda1 C + lambda2 S)). F_B is the engine's constraint force; F_A = m a_G - m g_vec -
    F_B from the bar's momentum balance with the engine's accelerations (affine in (qacc, f),
    so the soft answer, its rigid recovery and the impedance prediction all map).
    raw["pin_A_force_cfrc"] is F_A read independently from cfrc_int[bar] (the slider's force on
    the bar through the hinge, mj_rnePostConstraint), raw["spring_damper_force"] the
    qfrc_passive of x (= F_Ax up to the light slider's 1e-12 inertia)."""

    nq_ref = n_ref = 3
    light_bodies = ("A",)
    _loads = (("y", "F", -1.0),)

    def _xml(self, **kw):
        return _xml_exercise_6_1(self.params, **kw)

    def _post_build(self):
        self.bar = self._body("bar")
        self.jx = self._dof("x")
        self.j_th = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_JOINT, "theta")

    def to_engine_state(self, q, u):
        x, y, th = (float(v) for v in q)
        xd, yd, thd = (float(v) for v in u)
        return np.array([x, th, y]), np.array([xd, thd, yd])

    def from_engine_state(self, qe, ve):
        return (np.array([qe[0], qe[2], qe[1]], float), np.array([ve[0], ve[2], ve[1]], float))

    def _acc_to_reference(self, qe, ve, ae):
        return np.array([ae[0], ae[2], ae[1]], float)

    def _force_at_A(self, qe, ve, ae, F_B):
        m = self.m
        _, _, a_rel = _hinge_point(
            m.jnt_axis[self.j_th], m.body_ipos[self.bar], float(qe[1]), float(ve[1]), float(ae[1])
        )
        a_G = np.array([ae[0], 0.0, 0.0]) + a_rel
        mb = m.body_mass[self.bar]
        return mb * a_G - mb * m.opt.gravity - np.asarray(F_B, float)

    def _multipliers(self, qe, ve, ae, f):
        F_B = np.asarray(f[0:3], float)
        F_A = self._force_at_A(qe, ve, ae, F_B)
        return np.array([0.5 * (F_B[0] - F_A[0]), 0.5 * (F_A[1] - F_B[1])])

    def _extra_raw(self, raw):
        d = self.d
        mujoco.mj_rnePostConstraint(self.m, d)
        raw["pin_A_force_cfrc"] = d.cfrc_int[self.bar, 3:6].copy()
        raw["pin_A_force"] = self._force_at_A(d.qpos, d.qvel, d.qacc, d.efc_force[0:3])
        raw["spring_damper_force"] = float(d.qfrc_passive[self.jx])
        raw["force_of_block_on_bar_at_B"] = d.efc_force[0:3].copy()


class _HingedBarMaps:
    """Engine state (two hinge angles and rates) to the reference's (the angles plus two
    coordinates of the bar's mass center G, ``_g_axes`` of the point ``_G`` returns), shared
    by Exercises 6.2 and 6.4."""

    _g_axes: tuple[int, int]

    def to_engine_state(self, q, u):
        q, u = np.asarray(q, float), np.asarray(u, float)
        return q[0:2].copy(), u[0:2].copy()

    def from_engine_state(self, qe, ve):
        i, j = self._g_axes
        r, v, _ = self._G(float(qe[1]), float(ve[1]), 0.0)
        return (
            np.array([qe[0], qe[1], r[i], r[j]], float),
            np.array([ve[0], ve[1], v[i], v[j]], float),
        )

    def _acc_to_reference(self, qe, ve, ae):
        i, j = self._g_axes
        _, _, a = self._G(float(qe[1]), float(ve[1]), float(ae[1]))
        return np.array([ae[0], ae[1], a[i], a[j]], float)


class Exercise62(_HingedBarMaps, _ExerciseBase):
    """Exercise 6.2 in the reference's own axes (Y DOWN, gravity +g Y): the block (m1) on slide
    x with the spring and damper (F as qfrc_applied on x), the bar on a hinge at A about -Z
    whose angle IS theta (bar along the body's +Y = down at theta = 0, G - A = (l/2)(S, C)).
    No constraint rows (a tree): plain mj_forward, exact. Engine q = (x, theta); the
    reference's dependent (x_G, y_G) = G - A, their rates and accelerations from the engine's
    hinge geometry (jnt_axis, body_ipos). Multipliers: the force of the pin A on the bar =
    cfrc_int[bar][3:6] (mj_rnePostConstraint: the parent's force on the body, world = the
    reference's axes), (lambda1, lambda2) = its (X, Y-down) components."""

    nq_ref = n_ref = 4
    _loads = (("x", "F", 1.0),)

    def _xml(self, **kw):
        return _xml_exercise_6_2(self.params, **kw)

    def _post_build(self):
        self.bar = self._body("bar")
        self.j_th = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_JOINT, "theta")

    def _G(self, th, thd, thdd):
        return _hinge_point(self.m.jnt_axis[self.j_th], self.m.body_ipos[self.bar], th, thd, thdd)

    _g_axes = (0, 1)  # (x_G, y_G): G in the plane of the hinge axes

    def _extra_raw(self, raw):
        mujoco.mj_rnePostConstraint(self.m, self.d)
        self._F = self.d.cfrc_int[self.bar, 3:6].copy()
        raw["pin_force_on_bar"] = self._F.copy()

    def _multipliers(self, qe, ve, ae, f):
        return self._F[0:2].copy()


class Exercise64(_HingedBarMaps, _ExerciseBase):
    """Exercise 6.4 (Z up, gravity -g Z): the disk (inertia diag(m_d R^2/4, m_d R^2/4,
    m_d R^2/2)) on a hinge about +Z at O (phi; M_phi as qfrc_applied), the bar on a hinge
    about the disk's +X at P = (0, R, 0) (theta; the torsional spring k and damper c as joint
    stiffness/damping, M_theta as qfrc_applied: all act between D and B), its mass center at
    (0, 0, -l/2) in the bar frame, whose rotation rot_z(phi) rot_x(theta) is the reference's.
    The bar's axial inertia is 1e-12 m l^2 instead of 0 (MuJoCo rejects a moving body with a
    zero principal inertia): it biases the answer by ~1e-12 relative and its kinetic energy,
    1/2 I_ax (omega . e3)^2, is subtracted in energy(). No constraint rows: plain mj_forward.
    Engine q = (phi, theta); (y_G, z_G) = G in disk axes from the hinge geometry (body_pos,
    jnt_axis, body_ipos). Multipliers: cfrc_int[bar][3:6] (the disk's force on the bar at the
    pin, world) in disk axes, R_disk^T F: (lambda1, lambda2) = its (y, z) components."""

    nq_ref = n_ref = 4
    _loads = (("phi", "M_phi", 1.0), ("theta", "M_theta", 1.0))

    def _xml(self, **kw):
        return _xml_exercise_6_4(self.params, **kw)

    def _post_build(self):
        self.disk, self.bar = self._body("disk"), self._body("bar")
        self.j_th = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_JOINT, "theta")

    def _G(self, th, thd, thdd):
        r, v, a = _hinge_point(
            self.m.jnt_axis[self.j_th], self.m.body_ipos[self.bar], th, thd, thdd
        )
        return self.m.body_pos[self.bar] + r, v, a

    _g_axes = (1, 2)  # (y_G, z_G): G in disk axes

    def _extra_raw(self, raw):
        d = self.d
        mujoco.mj_rnePostConstraint(self.m, d)
        F = d.cfrc_int[self.bar, 3:6].copy()
        self._F_disk = d.xmat[self.disk].reshape(3, 3).T @ F
        raw["pin_force_on_bar_world"] = F
        raw["pin_force_on_bar_disk_axes"] = self._F_disk.copy()

    def _multipliers(self, qe, ve, ae, f):
        return self._F_disk[1:3].copy()

    def _energy_after_forward(self, m, d):
        K, V = super()._energy_after_forward(m, d)
        w = np.zeros(6)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, self.bar, w, 1)  # inertial axes
        return K - 0.5 * float(m.body_inertia[self.bar, 2]) * float(w[2]) ** 2, V
