"""MuJoCo models (and their MJCF) of the planar examples: the pendulum (Example 1), the
slider-cranks (Example 2, Note 2 / Exercise 6.3), the frame and bar (Example 3)."""

from __future__ import annotations

import math

import mujoco
import numpy as np

from crosscheck.engines.kinematics import IdentityMaps, frame_bar_from_engine, frame_bar_to_engine
from crosscheck.engines.mujoco.engine_model import LIGHT, MjEngineModel, document, lamina, num, vec


def _xml_pendulum_angle(p, **kw) -> str:
    m, L, g = p["m"], p["L"], p["g"]
    eps_m, eps_I = LIGHT * m, LIGHT * m * L * L
    bodies = f"""      <body name="rod">
        <joint name="theta" type="hinge" axis="0 0 -1"/>
        <inertial pos="0 0 0" mass="{num(eps_m)}" diaginertia="{vec(eps_I, eps_I, eps_I)}"/>
        <geom type="capsule" fromto="0 0 0 0 {num(L)} 0" size="0.005"/>
        <body name="bob" pos="0 {num(L)} 0">
          <inertial pos="0 0 0" mass="{num(m)}" diaginertia="0 0 0"/>
          <geom type="sphere" size="0.03"/>
        </body>
      </body>
"""
    return document(
        "pendulum_angle",
        (0, g, 0),
        bodies,
        note="Example 1(a): Y DOWN (gravity +Y); theta from +Y, hinge about -Z "
        "so the bob is at L (sin theta, cos theta); light rod (1e-12)",
        **kw,
    )


def _xml_pendulum_xy(p, **kw) -> str:
    m, L, g = p["m"], p["L"], p["g"]
    eps_m, eps_I = LIGHT * m, LIGHT * m * L * L
    bodies = f"""      <body name="bob">
        <joint name="x" type="slide" axis="1 0 0"/>
        <joint name="y" type="slide" axis="0 1 0"/>
        <inertial pos="0 0 0" mass="{num(m)}" diaginertia="{vec(eps_I, eps_I, eps_I)}"/>
        <geom type="sphere" size="0.03"/>
        <site name="bob_center" pos="0 0 0"/>
      </body>
      <body name="rod">
        <joint name="rod_angle" type="hinge" axis="0 0 -1"/>
        <inertial pos="0 0 0" mass="{num(eps_m)}" diaginertia="{vec(eps_I, eps_I, eps_I)}"/>
        <geom type="capsule" fromto="0 0 0 0 {num(L)} 0" size="0.005"/>
        <site name="rod_tip" pos="0 {num(L)} 0"/>
      </body>
"""
    eq = '    <connect name="rod" site1="bob_center" site2="rod_tip"/>\n'
    return document(
        "pendulum_xy",
        (0, g, 0),
        bodies,
        eq,
        note="Example 1(b): Y DOWN; bob on slides x, y; the distance constraint "
        "is a light rod (hinge at the origin) connected to the bob",
        **kw,
    )


def _slider_crank_bodies(p, variant: str) -> tuple[str, str]:
    l1, l2, r1, r2 = p["l1"], p["l2"], p["r1"], p["r2"]
    m1, m2, m3 = p["m1"], p["m2"], p["m3"]
    I3 = LIGHT * m3 * l2 * l2  # slider on a slide: never rotates
    crank = f"""      <body name="crank">
        <joint name="theta1" type="hinge" axis="0 0 1"/>
        <inertial pos="{vec(r1, 0, 0)}" mass="{num(m1)}" diaginertia="{lamina(p["I_G1"])}"/>
        <geom type="capsule" fromto="0 0 0 {num(l1)} 0 0" size="0.01"/>
        <site name="B_crank" pos="{vec(l1, 0, 0)}"/>
"""
    if variant == "split":  # Note 2 / 6.3: rod hinged to the slider at C, theta2 from C to B
        bodies = (
            crank
            + f"""      </body>
      <body name="slider">
        <joint name="x" type="slide" axis="1 0 0"/>
        <inertial pos="0 0 0" mass="{num(m3)}" diaginertia="{vec(I3, I3, I3)}"/>
        <geom type="box" size="0.04 0.02 0.02"/>
        <body name="rod">
          <joint name="theta2" type="hinge" axis="0 0 1"/>
          <inertial pos="{vec(r2, 0, 0)}" mass="{num(m2)}" diaginertia="{lamina(p["I_G2"])}"/>
          <geom type="capsule" fromto="0 0 0 {num(l2)} 0 0" size="0.01"/>
          <site name="B_rod" pos="{vec(l2, 0, 0)}"/>
        </body>
      </body>
"""
        )
        eq = '    <connect name="B" site1="B_crank" site2="B_rod"/>\n'
        return bodies, eq
    rod_open = f"""        <body name="rod" pos="{vec(l1, 0, 0)}">
          <joint name="phi2" type="hinge" axis="0 0 1"/>
          <inertial pos="{vec(r2, 0, 0)}" mass="{num(m2)}" diaginertia="{lamina(p["I_G2"])}"/>
          <geom type="capsule" fromto="0 0 0 {num(l2)} 0 0" size="0.01"/>
          <site name="C_rod" pos="{vec(l2, 0, 0)}"/>
"""
    if variant == "free":  # Example 2(a): the end mass rides on the rod at C
        bodies = (
            crank
            + rod_open
            + f"""          <body name="slider" pos="{vec(l2, 0, 0)}">
            <inertial pos="0 0 0" mass="{num(m3)}" diaginertia="0 0 0"/>
            <geom type="box" size="0.04 0.02 0.02"/>
          </body>
        </body>
      </body>
"""
        )
        return bodies, ""
    bodies = (
        crank
        + rod_open
        + f"""        </body>
      </body>
      <body name="slider">
        <joint name="x" type="slide" axis="1 0 0"/>
        <inertial pos="0 0 0" mass="{num(m3)}" diaginertia="{vec(I3, I3, I3)}"/>
        <geom type="box" size="0.04 0.02 0.02"/>
        <site name="C_slider" pos="0 0 0"/>
      </body>
"""
    )
    eq = '    <connect name="C" site1="C_rod" site2="C_slider"/>\n'
    return bodies, eq


def _xml_slider_crank(p, variant="closed", **kw) -> str:
    bodies, eq = _slider_crank_bodies(p, variant)
    name = {"closed": "slider_crank", "split": "slider_crank_split", "free": "slider_crank_free"}[
        variant
    ]
    return document(
        name,
        (0, -p["g"], 0),
        bodies,
        eq,
        note="Examples 2 / Note 2: X right, Y UP, hinges about +Z; the torque T "
        "is applied by the adapter as qfrc_applied on theta1",
        **kw,
    )


def _xml_frame_bar(p, **kw) -> str:
    m, d = p["m"], p["d"]
    eps_m, eps_I = LIGHT * m, LIGHT * m * d * d
    bodies = f"""      <body name="F">
        <joint name="phi" type="hinge" axis="0 0 1"/>
        <inertial pos="0 0 0" mass="{num(eps_m)}" diaginertia="{vec(eps_I, eps_I, eps_I)}"/>
        <geom type="capsule" fromto="0 0 0 0 {num(d)} 0" size="0.005"/>
        <body name="bar" pos="{vec(0, d, 0)}">
          <joint name="theta" type="hinge" axis="0 1 0"/>
          <inertial pos="0 0 0" mass="{num(m)}" diaginertia="{vec(p["I1"], p["I2"], p["I3"])}"/>
          <geom type="box" size="0.25 0.02 0.01"/>
        </body>
      </body>
"""
    return document(
        "frame_bar",
        (0, 0, 0),
        bodies,
        note="Example 3: k = +Z; light frame F (1e-12) turning by phi about k, "
        "bar turning by theta about the arm n2 = F's +Y; no gravity",
        **kw,
    )


# ======================================================================================
# Example 1: pendulum


# ======================================================================================


class PendulumAngle(IdentityMaps, MjEngineModel):
    """Example 1(a). Engine: a light rod (1e-12 m L^2) on a hinge about -Z at the origin, the
    bob (mass m, zero inertia) welded at (0, L, 0) of the rod. World = reference frame (Y DOWN,
    gravity +g Y), so qpos = theta and qvel = theta' exactly.

    raw["rod_tension"]: the rod's force on the bob is cfrc_int[bob][3:6] (after
    mj_rnePostConstraint: the force of the parent on the body, world frame); the tension pulls
    the bob toward the pivot, F = -T r/L, so T = -F . r/|r|, and raw["lambda_addendum"] = -T/L
    is the multiplier of Example 1(b) at the same state (Addendum)."""

    nq_ref = n_ref = 1
    light_bodies = ("rod",)
    _P = np.eye(1)

    def _xml(self, **kw):
        return _xml_pendulum_angle(self.params, **kw)

    def _post_build(self):
        self.bob = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_BODY, "bob")

    def _extra_raw(self, raw):
        mujoco.mj_rnePostConstraint(self.m, self.d)
        F = self.d.cfrc_int[self.bob, 3:6].copy()
        r = self.d.xipos[self.bob].copy()
        T = -float(F @ r) / float(np.linalg.norm(r))
        raw["rod_force_on_bob"] = F
        raw["rod_tension"] = T
        raw["lambda_addendum"] = -T / self.params["L"]


class PendulumXY(MjEngineModel):
    """Example 1(b): the bob on slides x, y (qpos[0:2] = (x, y), the reference's coordinates
    exactly) held at distance L from the origin.

    Why not a tendon equality: MuJoCo's tendon equality row has no J-dot v term (efc_aref = 0
    at a consistent state), so its tension misses m v^2 / L whenever the bob moves. Here the
    distance constraint is a LIGHT ROD instead: a body with mass and inertia 1e-12 (times m and
    m L^2) at the origin, on a hinge about -Z, whose tip site is `connect`ed to the bob. The
    connect rows carry J-dot v, so every quantity is comparable at any v:
    - accelerations (x'', y'') = qacc[0:2]: raw (soft) and de-regularized; the rod's inertia
      biases the tangential acceleration by I_rod/(m L^2) = 1e-12 relative;
    - lambda: the connect force on the bob (site1 = its center) is F = efc_force[0:3]; the
      reference's generalized constraint force is A^T lambda = lambda (x, y), so
      lambda = F . r / |r|^2 = -T / L (T the rod tension, Addendum);
    - energy (the rod's 1e-12 energy subtracted), M and f: the bob's block of the engine's M
      and qfrc_smooth (the rod's dof is not in the reference; it does not couple in M).
    Why this stays accurate although M has a 1e-12 pivot: MuJoCo's efc_R comes from efc_diagA,
    the body_invweight0 approximation, which is zero for the rod (its mass center is on the
    hinge), so R is isotropic ((1-d)/d / m) and the raw answer has the plain 1e-4 softness; the
    rigid recovery solves the KKT system (well conditioned as I_rod -> 0), never J M^-1 J^T.
    (With the `diagexact` flag the rod's huge exact diag(A) would make R huge and the raw answer
    useless: do not set it.)
    Engine state: (x, y, rod angle) with rod angle = atan2(x, y), its rate (y x' - x y')/|r|^2."""

    nq_ref = n_ref = 2
    light_bodies = ("rod",)
    _P = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])  # the bob's block; rod dof not mapped

    def _xml(self, **kw):
        return _xml_pendulum_xy(self.params, **kw)

    def to_engine_state(self, q, u):
        x, y = (float(v) for v in q)
        xd, yd = (float(v) for v in u)
        r2 = x * x + y * y
        return (np.array([x, y, math.atan2(x, y)]), np.array([xd, yd, (y * xd - x * yd) / r2]))

    def from_engine_state(self, qe, ve):
        return np.array(qe[:2], float), np.array(ve[:2], float)

    def _acc_to_reference(self, qe, ve, ae):
        return np.array(ae[:2], float)

    def _multipliers(self, qe, ve, ae, f):
        r = np.array([qe[0], qe[1], 0.0])
        return np.array([float(f[0:3] @ r) / float(r @ r)])

    def _extra_raw(self, raw):
        raw["rod_tension"] = -raw.get("rigid_multipliers", [np.nan])[0] * self.map_params["L"]


# ======================================================================================
# Example 2 and Note 2 / Exercise 6.3: slider-crank


# ======================================================================================


class _SliderCrankBase(MjEngineModel):
    def _applied(self):
        a = np.zeros(self.m.nv)
        a[0] = self.params["T"]  # theta1 is dof 0 in every variant
        return a


class SliderCrankFree(_SliderCrankBase):
    """Example 2(a): crank hinge theta1 (about +Z at A), rod hinge phi2 = theta2 - theta1
    (relative, at B), the end mass m3 welded to the rod at C (zero inertia: a point mass).
    q_e = P q_ref with P = [[1, 0], [-1, 1]]; M and f map as P^T M P, P^T f. No constraints."""

    nq_ref = n_ref = 2
    _P = np.array([[1.0, 0.0], [-1.0, 1.0]])

    def _xml(self, **kw):
        return _xml_slider_crank(self.params, "free", **kw)

    def to_engine_state(self, q, u):
        q = np.asarray(q, float)
        u = np.asarray(u, float)
        return self._P @ q, self._P @ u

    def from_engine_state(self, qe, ve):
        return (np.array([qe[0], qe[0] + qe[1]], float), np.array([ve[0], ve[0] + ve[1]], float))

    def _acc_to_reference(self, qe, ve, ae):
        return np.array([ae[0], ae[0] + ae[1]], float)


class SliderCrank(_SliderCrankBase):
    """Example 2(b): engine (theta1, phi2 = theta2 - theta1, x): crank and rod as in 2(a); the
    slider is its own body (mass m3) on a slide along X (qpos x = world x of C); the rod's end
    C is `connect`ed to it (site1 = rod's C, site2 = slider). Reference (theta1, theta2) ->
    engine: phi2 = theta2 - theta1, x = l1 C1 + l2 C2, x' = -l1 S1 theta1' - l2 S2 theta2'.

    Multiplier: the textbook lambda is the vertical force of the guide on C. efc_force[0:3] is
    the force of the slider on the rod at C (world); the slider's own balance, m3 a_C = F_guide
    + m3 g_vec - efc_force, with a_C,y = 0 on the guide, gives
        lambda = F_guide,y = efc_force[1] - m3 g_vec,y = efc_force[1] + m3 g
    (m3 and g_vec read from the MuJoCo model). raw["guide_force_cfrc"] is the same force read
    independently from cfrc_int[slider][4] (the slide joint's reaction, mj_rnePostConstraint).
    M is not mapped (None): the reference's m3 is a particle of the two-link system whose
    vertical motion the guide removes only through lambda, the engine's slider never moves
    vertically; the two kinetic energies agree on the constraint manifold only."""

    nq_ref = n_ref = 2
    mass_matrix_note = (
        "the engine's coordinates (theta1, phi2, x) do not map one to one onto "
        "the reference's (theta1, theta2): x follows from the loop closure, and "
        "the reference's M carries the vertical motion of m3 that the engine's "
        "guide removes"
    )

    def _xml(self, **kw):
        return _xml_slider_crank(self.params, "closed", **kw)

    def _post_build(self):
        self.slider = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_BODY, "slider")

    def to_engine_state(self, q, u):
        th1, th2 = (float(v) for v in q)
        w1, w2 = (float(v) for v in u)
        l1, l2 = self.map_params["l1"], self.map_params["l2"]
        x = l1 * math.cos(th1) + l2 * math.cos(th2)
        xd = -l1 * math.sin(th1) * w1 - l2 * math.sin(th2) * w2
        return np.array([th1, th2 - th1, x]), np.array([w1, w2 - w1, xd])

    def from_engine_state(self, qe, ve):
        return (np.array([qe[0], qe[0] + qe[1]], float), np.array([ve[0], ve[0] + ve[1]], float))

    def _acc_to_reference(self, qe, ve, ae):
        return np.array([ae[0], ae[0] + ae[1]], float)

    def _multipliers(self, qe, ve, ae, f):
        # the guide's force N = f_y + m3 g (Y up), with the nominal m3 and g: a map, not physics
        return np.array([f[1] + self.map_params["m3"] * self.map_params["g"]])

    def _extra_raw(self, raw):
        mujoco.mj_rnePostConstraint(self.m, self.d)
        raw["guide_force_cfrc"] = float(self.d.cfrc_int[self.slider, 4])


class SliderCrankSplit(IdentityMaps, _SliderCrankBase):
    """Note 2 / Exercise 6.3: engine dofs (theta1, x, theta2) = the reference's coordinates
    exactly (P = I): crank hinge at A; slider on a slide along X; rod hinged to the slider at C
    with its axis from C to B (theta2 from C to B, r2 = |C G2|). The crank's B and the rod's B
    are `connect`ed with site1 on the CRANK, so efc_pos = B_crank - B_rod = (f1, f2, 0), the
    reference's rows, and efc_force[0:2] is the force of the rod on the crank at B =
    (lambda1, lambda2) directly. The third (out-of-plane) row is identically zero (lstsq)."""

    nq_ref = n_ref = 3
    _P = np.eye(3)

    def _xml(self, **kw):
        return _xml_slider_crank(self.params, "split", **kw)

    def _multipliers(self, qe, ve, ae, f):
        return np.array(f[0:2], float)


# ======================================================================================
# Example 3: rotating light frame and bar


# ======================================================================================


class FrameBar(MjEngineModel):
    """Example 3: hinge phi about +Z at O carrying the light frame F (1e-12 relative mass and
    inertia), hinge theta about F's +Y (the arm n2) at (0, d, 0) carrying the bar with its mass
    center on the joint and principal inertias (I1, I2, I3) along the joint frame's axes, so
    the bar's rotation is rot_z(phi) rot_y(theta) as in the reference. qfrc_applied =
    (M_phi, M_theta). No gravity.

    Speeds: omega (bar components) = (-S phi', theta', C phi'); inversely theta' = omega2,
    phi' = -S omega1 + C omega3 (exact on the constraint omega1 C + omega3 S = 0). u' = the bar's
    body-fixed angular acceleration Q^T (phi'' k + theta'' n2 + phi' k x theta' n2).
    Multiplier: lambda = n1 component of the moment about O of the ground's bearing on F:
    cfrc_int[F] (mj_rnePostConstraint) is that wrench at the subtree mass center c (world), so
    the moment about O is tau_c + c x f."""

    nq_ref, n_ref = 2, 3
    light_bodies = ("F",)
    mass_matrix_note = (
        "the reference's three body-fixed angular velocity components are "
        "dependent speeds (tied by omega1 C + omega3 S = 0) and do not map one "
        "to one onto the engine's two joint rates (phi', theta')"
    )

    def _xml(self, **kw):
        return _xml_frame_bar(self.params, **kw)

    def _post_build(self):
        self.F = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_BODY, "F")

    def _applied(self):
        return np.array([self.params["M_phi"], self.params["M_theta"]])

    def to_engine_state(self, q, u):
        return frame_bar_to_engine(q, u)

    def from_engine_state(self, qe, ve):
        return frame_bar_from_engine(qe, ve)

    def _acc_to_reference(self, qe, ve, ae):
        phi, th = float(qe[0]), float(qe[1])
        k = np.array([0.0, 0.0, 1.0])
        n2 = np.array([-math.sin(phi), math.cos(phi), 0.0])
        alpha = ae[0] * k + ae[1] * n2 + ve[0] * ve[1] * np.cross(k, n2)
        c, s, cp, sp_ = math.cos(th), math.sin(th), math.cos(phi), math.sin(phi)
        Q = np.array([[cp, -sp_, 0], [sp_, cp, 0], [0, 0, 1]]) @ np.array(
            [[c, 0, s], [0, 1, 0], [-s, 0, c]]
        )
        return Q.T @ alpha

    def _extra_raw(self, raw):
        d = self.d
        mujoco.mj_rnePostConstraint(self.m, d)
        c = d.subtree_com[self.m.body_rootid[self.F]].copy()
        tau, f = d.cfrc_int[self.F, 0:3].copy(), d.cfrc_int[self.F, 3:6].copy()
        self._tau_O = tau + np.cross(c, f)
        raw["bearing_moment_O"] = self._tau_O.copy()

    def _multipliers(self, qe, ve, ae, f):
        phi = float(qe[0])
        n1 = np.array([math.cos(phi), math.sin(phi), 0.0])
        return np.array([float(self._tau_O @ n1)])
