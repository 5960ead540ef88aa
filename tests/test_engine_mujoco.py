"""What only the MuJoCo adapter does, with the real MuJoCo 4.0 (no mocks).

What every engine does (state maps both ways, the judged answer and energy, M and f against
the reference, the fingerprint, the nominal maps, faults seen, the timing hook, refusals) is
tests/test_engine_contract.py. Here: that the maps put MuJoCo's bodies where the reference's
are, its soft answer against the impedance it is built with, the sign and frame of every
constraint force on poses done by hand, the MJCF files, its own integrators, and why the
models are built as they are (a light rod, not a tendon equality).

Tolerances (one per quantity, with the reason):
- TOL_RIGID = 1e-9: the de-regularized answer f + A^-1 R f and its accelerations.
  Measured floor 1e-11 to 2e-10 of the force scale: MuJoCo's own soft solve stops that far from
  the exact soft solution at d = 0.9999 (1e-14 at d = 0.9: it scales with 1/(1 - d)), the
  recovery passes it on 1:1, and states projected to ~1e-13 add MuJoCo's stabilization K r.
- slack of the soft bounds: TOL_RIGID x max(max|ref|, SCALE), SCALE the same quantity's
  magnitude at the model's initial state: a multiplier passing through zero (a slack pendulum
  rod) has no relative precision of its own, only one relative to the forces the model carries.
- raw soft answer: within the bound derived from the impedance, eps |G A^-1 D|_inf |f|_inf with
  eps = (1 - d)/d (module docstring), and equal to the predicted error vector to PRED_REL.
- TOL_MAP = 1e-12: state maps are plain arithmetic (angles, quaternions) on O(1) numbers.
- TOL_KIN = 1e-12: engine mass-center positions/velocities/rotations vs the reference's r_G,
  v_G, R, omega (forward kinematics, round-off only).
- TOL_MASS = 1e-11: M projected onto the manifold against MuJoCo's; the light bodies (1e-12
  relative inertia) bias M by 1e-12.
"""

from __future__ import annotations

import math
from functools import cache

import mujoco
import numpy as np
import pytest
import sympy as sp

from crosscheck.engines.mujoco.adapter import MJCF_DIR, SOLIMP, MujocoAdapter, mjcf, write_mjcf
from reference.models import get
from reference.numeric.model import NumericModel
from tests.support import QUICK_MODELS, max_abs, representative, scaled_error, states

TOL_RIGID = 1e-9
TOL_MAP = 1e-12
TOL_KIN = 1e-12
TOL_MASS = 1e-11
PRED_REL = 1e-3  # |actual raw error - predicted| / |predicted|: floor 1e-9 / 1e-4 = 1e-5
EPS_SOFT = (1 - SOLIMP[0]) / SOLIMP[0]  # (1 - d)/d = 1.0001e-4

CASES = [
    ("pendulum_angle", None),
    ("pendulum_xy", None),
    ("slider_crank", None),
    ("slider_crank_split", None),
    ("slider_crank_free", None),
    ("double_pendulum_3d", "free"),
    ("double_pendulum_3d", "tree"),
    ("top_euler", None),
    ("top_cartesian", None),
    ("frame_bar", None),
    ("exercise_6_1", None),
    ("exercise_6_2", None),
    ("exercise_6_4", None),
]
SOME_CASES = representative(CASES, QUICK_MODELS, key=lambda c: c[0])
# the engine models with soft rows (connect equalities): the others are trees, exact
SOFT_CASES = representative(
    [
        ("pendulum_xy", None),
        ("slider_crank", None),
        ("slider_crank_split", None),
        ("double_pendulum_3d", "free"),
        ("top_cartesian", None),
        ("exercise_6_1", None),
    ],
    QUICK_MODELS,
    key=lambda c: c[0],
)

ADAPTER = MujocoAdapter()


@cache
def reference(name: str, formulation: str | None = None) -> NumericModel:
    return NumericModel(get(name), formulation)


@cache
def engine(name: str, variant: str | None):
    return ADAPTER.build(name, None, variant)


@cache
def scales(name: str, formulation: str | None = None) -> tuple[float, float]:
    """(|u'|, |lambda|) of the reference at the model's initial state."""
    nm = reference(name, formulation)
    fw = nm.forward(nm.model.initial_q, nm.model.initial_u)
    return max_abs(fw.accelerations), max_abs(fw.multipliers)


# ---- the reference's kinematics, for an independent check of the state map -------------------
@cache
def body_kinematics(name: str):
    """Lambdified (r_G, v_G in inertial components, R, omega body) of every reference body."""
    mdl = get(name)
    nm = reference(name)
    subs = {p.symbol: nm.params[p.name] for p in mdl.parameters}
    args = list(mdl.coordinates) + list(mdl.speeds)
    out = {}
    for b in mdl.bodies:
        r = b.r_G.xreplace(subs)
        v = b.v_G.xreplace(subs)
        R = b.R.xreplace(subs) if b.R is not None else None
        if b.v_frame == "body":
            v = R * v
        w = b.omega.xreplace(subs) if b.R is not None else None
        out[b.name] = tuple(
            sp.lambdify(args, e, "numpy") if e is not None else None for e in (r, v, R, w)
        )
    return out


def engine_body_state(em, body: str, q, u):
    m, d = em.m, em.d
    qe, ve = em.to_engine_state(q, u)
    d.qpos[:], d.qvel[:] = qe, ve
    mujoco.mj_forward(m, d)
    b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, body)
    world = np.zeros(6)
    local = np.zeros(6)
    mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, b, world, 0)
    mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, b, local, 1)
    return d.xipos[b].copy(), world[3:].copy(), d.ximat[b].reshape(3, 3).copy(), local[:3].copy()


# ======================================================================================
# state maps
# ======================================================================================
@pytest.mark.parametrize("name,variant", SOME_CASES)
def test_the_maps_put_mujocos_bodies_where_the_references_are(name, variant):
    """engine -> reference -> engine is the identity (qpos and qvel as MuJoCo holds them,
    quaternions with their sign), and the engine's mass centers, their velocities, the body
    rotations and angular velocities equal the reference's r_G, v_G, R, omega: the map is the
    right one, not only self-consistent (the reference -> engine -> reference round trip is
    the contract's)."""
    em = engine(name, variant)
    kin = body_kinematics(name)
    for q, u in states(reference(name), 12, seed=1):
        qe, ve = em.to_engine_state(q, u)
        qe2, ve2 = em.to_engine_state(*em.from_engine_state(qe, ve))
        assert max_abs(np.asarray(qe2) - qe) <= TOL_MAP * (1 + max_abs(qe)), (name, qe, qe2)
        assert max_abs(np.asarray(ve2) - ve) <= TOL_MAP * (1 + max_abs(ve)), (name, ve, ve2)
        args = list(q) + list(u)
        for body, (r_f, v_f, R_f, w_f) in kin.items():
            r_e, v_e, R_e, w_e = engine_body_state(em, body, q, u)
            r_r = np.asarray(r_f(*args), float).ravel()
            v_r = np.asarray(v_f(*args), float).ravel()
            assert max_abs(r_e - r_r) <= TOL_KIN * (1 + max_abs(r_r)), (name, body, r_e, r_r)
            assert max_abs(v_e - v_r) <= TOL_KIN * (1 + max_abs(v_r)), (name, body, v_e, v_r)
            if R_f is not None:
                R_r = np.asarray(R_f(*args), float)
                w_r = np.asarray(w_f(*args), float).ravel()
                assert max_abs(R_e - R_r) <= TOL_KIN, (name, body, R_e, R_r)
                assert max_abs(w_e - w_r) <= TOL_KIN * (1 + max_abs(w_r)), (name, body, w_r)


# ======================================================================================
# the soft answer at consistent states
# ======================================================================================
@pytest.mark.parametrize("name,variant", SOFT_CASES)
def test_soft_answer_is_the_impedance_prediction(name, variant):
    """Where MuJoCo's rows are soft (its connect equalities), at 15 consistent states: the
    impedance is solimp's d on every row and R = (1 - d)/d diag(A) as documented; the raw
    answer lies within the bound derived from eps = (1 - d)/d and equals the error predicted
    from the impedance alone; the soft model holds on MuJoCo's output, the recovered answer is
    rigid, and aref is -J-dot v (the connect rows carry J-dot v). The recovered answer itself
    is the contract's (RIGID_RECOVERY)."""
    nm, em = reference(name), engine(name, variant)
    s_acc, s_lam = scales(name)
    for q, u in states(reference(name), 15, seed=2):
        ref, fw = nm.forward(q, u), em.forward(q, u)
        raw = fw.raw
        assert fw.soft and "impedance" in raw
        assert np.allclose(raw["impedance"], SOLIMP[0], rtol=0, atol=1e-15)
        assert raw["R_model_rel_mismatch"] <= 1e-12
        e_lam = fw.multipliers - ref.multipliers
        e_acc = fw.accelerations - ref.accelerations
        slack_l = TOL_RIGID * max(max_abs(ref.multipliers), s_lam)
        slack_a = TOL_RIGID * max(max_abs(ref.accelerations), s_acc)
        # within the bound derived from eps = (1 - d)/d ...
        assert max_abs(e_lam) <= raw["raw_multiplier_error_bound"] + slack_l
        assert max_abs(e_acc) <= raw["raw_acceleration_error_bound"] + slack_a
        # ... and equal to the error predicted from the impedance alone
        p_lam, p_acc = raw["predicted_multiplier_error"], raw["predicted_acceleration_error"]
        assert max_abs(e_lam - p_lam) <= PRED_REL * max_abs(p_lam) + slack_l, (e_lam, p_lam)
        assert max_abs(e_acc - p_acc) <= PRED_REL * max_abs(p_acc) + slack_a, (e_acc, p_acc)
        # the soft model holds on MuJoCo's output (its solver's 1e-15 tolerance, amplified by
        # 1/R), the recovered answer is rigid
        assert raw["soft_model_residual"] <= 1e-9 * (1 + max_abs(raw["engine_accelerations"]))
        assert raw["rigid_residual"] <= 1e-9 * (1 + max_abs(raw["rigid_engine_accelerations"]))
        # at a consistent state MuJoCo's aref is -J-dot v (the connect rows carry J-dot v)
        assert raw["aref_plus_jdot_v"] <= 1e-8 * (1 + max_abs(raw["rigid_engine_accelerations"]))


def test_raw_error_is_the_impedance_prediction():
    """Hand check of the soft model on the (x, y) pendulum: the radial connect row is
    decoupled and R is isotropic (the light rod's invweight0 is 0), so f = d f_rigid exactly:
    lambda_raw / lambda = d = 0.9999 (a relative error (1-d) ~ 1e-4), the tangential
    acceleration is untouched, and the bound eps |A^-1 D| equals eps."""
    nm, em = reference("pendulum_xy"), engine("pendulum_xy", None)
    for q, u in states(reference("pendulum_xy"), 6, seed=3):
        ref, fw = nm.forward(q, u), em.forward(q, u)
        assert fw.multipliers[0] / ref.multipliers[0] == pytest.approx(SOLIMP[0], abs=1e-9)
        # |A^-1 D|_inf = max_i |r_i| (|r_x| + |r_y|)/L^2 in the world rows, in [1, 1.21]
        assert EPS_SOFT * (1 - 1e-9) <= fw.raw["predicted_rel_force_bound"] <= EPS_SOFT * 1.21
        t = np.array([u[0], u[1]]) / np.hypot(*u)  # tangential direction
        assert abs((fw.accelerations - ref.accelerations) @ t) <= 1e-9 * (1 + max_abs(u) ** 2)


@pytest.mark.parametrize("solimp0", [0.9, 0.99])
def test_deregularization_does_not_depend_on_d(solimp0):
    """With a softer constraint (MuJoCo's default dmin 0.9 -> 10 % raw error) the recovered
    rigid answer is as good: f + A^-1 R f holds for any impedance."""
    ad = MujocoAdapter(solimp=(solimp0, solimp0, 0.001, 0.5, 2.0))
    em = ad.build("slider_crank_split")
    nm = reference("slider_crank_split")
    _, s_lam = scales("slider_crank_split")
    for q, u in states(reference("slider_crank_split"), 5, seed=4):
        ref, fw = nm.forward(q, u), em.forward(q, u)
        eps = (1 - solimp0) / solimp0
        force_scale = max(max_abs(ref.multipliers), s_lam)  # the forces the model carries
        assert max_abs(fw.multipliers - ref.multipliers) >= 0.1 * eps * force_scale  # soft
        assert scaled_error(fw.raw["rigid_multipliers"], ref.multipliers) <= TOL_RIGID
        assert scaled_error(fw.raw["rigid_accelerations"], ref.accelerations) <= TOL_RIGID


def test_sparse_jacobian_storage_gives_the_same_answer():
    """efc_J in CSR storage (mj_isSparse) is read as the dense one (the two storages change
    MuJoCo's own round-off, ~1e-11 here, amplified by 1/R in the soft solve)."""
    em = ADAPTER.build("double_pendulum_3d", None, "free")
    q, u = states(reference("double_pendulum_3d"), 1, seed=5)[0]
    dense = em.forward(q, u)
    assert not dense.raw["sparse_jacobian"]
    em.m.opt.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE
    sparse = em.forward(q, u)
    assert sparse.raw["sparse_jacobian"]
    for key in ("rigid_accelerations", "rigid_multipliers"):  # MuJoCo's soft-solve floor
        assert max_abs(sparse.raw[key] - dense.raw[key]) <= 1e-10 * max_abs(dense.raw[key])


# ======================================================================================
# sign and frame of every constraint force: hand-checkable static cases
# ======================================================================================
def _params(name, **over):
    return dict(reference(name).params, **over)


def test_sign_pendulum():
    """Hanging at rest: the rod holds the weight, T = m g, lambda = -T/L; swinging through the
    bottom at theta' = w: T = m g + m L w^2 (the J-dot v term a tendon equality would miss)."""
    p = _params("pendulum_xy")
    m, L, g = p["m"], p["L"], p["g"]
    ang = engine("pendulum_angle", None)
    xy = engine("pendulum_xy", None)
    for w in (0.0, 2.5):
        T = m * g + m * L * w * w
        fa = ang.forward([0.0], [w])
        assert fa.accelerations[0] == pytest.approx(0.0, abs=1e-12)
        assert fa.raw["rod_tension"] == pytest.approx(T, rel=1e-12)
        assert fa.raw["lambda_addendum"] == pytest.approx(-T / L, rel=1e-12)
        assert fa.raw["rod_force_on_bob"] == pytest.approx([0.0, -T, 0.0], abs=1e-12 * T)
        fx = xy.forward([0.0, L], [L * w, 0.0])
        assert fx.raw["rigid_multipliers"][0] == pytest.approx(-T / L, rel=1e-10)
        assert fx.raw["rigid_accelerations"] == pytest.approx([0.0, -L * w * w], abs=1e-9)
        # efc_force is the force ON the bob (site1), world frame (Y down: -Y is up)
        assert fx.raw["rigid_engine_forces"][:3] == pytest.approx([0.0, -T, 0.0], abs=1e-9)
        assert fx.multipliers[0] == pytest.approx(-SOLIMP[0] * T / L, rel=1e-9)


def test_sign_slider_crank():
    """theta1 = theta2 = 0 at rest, with the torque that holds it: the guide carries the
    slider and its share of the rod, lambda = (m2 r2/l2 + m3) g; the slider pushes the rod
    up at C by m2 g r2/l2 (efc_force on the rod, site1); q'' = 0."""
    p = _params("slider_crank")
    m1, m2, m3, l1, l2, r1, r2, g = (p[k] for k in ("m1", "m2", "m3", "l1", "l2", "r1", "r2", "g"))
    lam = (m2 * r2 / l2 + m3) * g
    T = m1 * r1 * g + m2 * g * l1 * (1 - r2 / l2)
    em = ADAPTER.build("slider_crank", {"T": T})
    fw = em.forward([0.0, 0.0], [0.0, 0.0])
    assert fw.raw["rigid_accelerations"] == pytest.approx([0.0, 0.0], abs=1e-9)
    assert fw.raw["rigid_multipliers"][0] == pytest.approx(lam, rel=1e-10)
    assert fw.raw["rigid_engine_forces"][:3] == pytest.approx(
        [0.0, m2 * g * r2 / l2, 0.0], abs=1e-9
    )
    assert fw.raw["guide_force_cfrc"] == pytest.approx(fw.multipliers[0], rel=1e-12)
    nm = NumericModel(get("slider_crank"), None, {"T": T})
    assert nm.forward([0.0, 0.0], [0.0, 0.0]).multipliers[0] == pytest.approx(lam, rel=1e-12)


def test_sign_slider_crank_split():
    """theta1 = 0, x = l1 + l2, theta2 = pi (C to B) at rest, held by its torque: the rod
    hangs half on B, so the rod pushes the crank DOWN at B: (lambda1, lambda2) =
    (0, -m2 g r2/l2) with r2 = |C G2|; efc_force (site1 = crank) is that force."""
    p = _params("slider_crank_split")
    m1, m2, l1, l2, r1, r2, g = (p[k] for k in ("m1", "m2", "l1", "l2", "r1", "r2", "g"))
    lam = np.array([0.0, -m2 * g * r2 / l2])
    T = m1 * g * r1 - l1 * lam[1]
    em = ADAPTER.build("slider_crank_split", {"T": T})
    q, u = [0.0, l1 + l2, math.pi], [0.0, 0.0, 0.0]
    fw = em.forward(q, u)
    assert fw.raw["rigid_accelerations"] == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
    assert fw.raw["rigid_multipliers"] == pytest.approx(lam, abs=1e-10 * abs(lam[1]))
    assert fw.raw["rigid_engine_forces"][:3] == pytest.approx([*lam, 0.0], abs=1e-9)
    nm = NumericModel(get("slider_crank_split"), None, {"T": T})
    assert nm.forward(q, u).multipliers == pytest.approx(lam, abs=1e-12)


HANG = (-math.pi / 2, math.pi / 2, math.pi / 2)  # 3-1-3 angles of a link hanging along -N2


@pytest.mark.parametrize("variant", ["free", "tree"])
def test_sign_double_pendulum(variant):
    """Both links hanging at rest: the force of link 1 on link 2 at A is m2 g up, the ground
    holds (m1 + m2) g at O, lambda = [F_O - F_A, F_A] = [(0, m1 g, 0), (0, m2 g, 0)]."""
    p = _params("double_pendulum_3d")
    m1, m2, g = p["m1"], p["m2"], p["g"]
    em = engine("double_pendulum_3d", variant)
    fw = em.forward(HANG + HANG, np.zeros(12))
    lam = [0.0, m1 * g, 0.0, 0.0, m2 * g, 0.0]
    assert fw.raw["rigid_accelerations"] == pytest.approx(np.zeros(12), abs=1e-9)
    assert fw.raw["rigid_multipliers"] == pytest.approx(lam, abs=1e-9)
    if variant == "free":  # efc_force = [F_O on link 1, F_A on link 2]
        assert fw.raw["rigid_engine_forces"] == pytest.approx(
            [0.0, (m1 + m2) * g, 0.0, 0.0, m2 * g, 0.0], abs=1e-9
        )
    nm = reference("double_pendulum_3d")
    assert nm.forward(HANG + HANG, np.zeros(12)).multipliers == pytest.approx(lam, abs=1e-12)


def test_sign_top():
    """Upright at rest (eps = (0, 0, 0, 1)): the socket pushes the top up by m g at O; the
    normalization multiplier of Exercise 6.7 (d'Alembert/Kane) is 2 L lambda_O . e3."""
    p = _params("top_cartesian")
    m, L, g = p["m"], p["L"], p["g"]
    em = engine("top_cartesian", None)
    q = [0.0, 0.0, L, 0.0, 0.0, 0.0, 1.0]
    fw = em.forward(q, np.zeros(7))
    lam = [0.0, 0.0, m * g, 2 * L * m * g]
    assert fw.raw["rigid_multipliers"] == pytest.approx(lam, abs=1e-10)
    assert fw.raw["rigid_engine_forces"] == pytest.approx([0.0, 0.0, m * g], abs=1e-10)
    for form in get("top_cartesian").formulations:
        assert reference("top_cartesian", form).forward(
            q, np.zeros(7)
        ).multipliers == pytest.approx(lam, abs=1e-12)
    fe = engine("top_euler", None).forward([0.0, 0.0, 0.0, 1.0], np.zeros(4))
    assert fe.multipliers is None
    assert fe.raw["socket_force"] == pytest.approx([0.0, 0.0, m * g], abs=1e-12)


def test_sign_frame_bar():
    """theta = 0, no torques, rates phi' and theta': the bearing's n1 moment is the rate of
    the bar's angular momentum about O along n1, lambda = (I3 - I1 - I2) phi' theta'."""
    p = _params("frame_bar")
    I1, I2, I3 = p["I1"], p["I2"], p["I3"]
    phi_dot, theta_dot = 1.7, -2.3
    q, u = [0.4, 0.0], [0.0, theta_dot, phi_dot]  # omega = (-S phi', theta', C phi')
    fw = engine("frame_bar", None).forward(q, u)
    lam = (I3 - I1 - I2) * phi_dot * theta_dot
    assert fw.multipliers[0] == pytest.approx(lam, rel=1e-10)
    assert reference("frame_bar").forward(q, u).multipliers[0] == pytest.approx(lam, rel=1e-12)


def test_sign_exercise_6_1():
    """Static equilibrium of the ladder with default parameters: at rest the reduced equation
    (reference docstring, part b) holds with theta'' = 0 when k l C = (m/2 + m_p) g + F. There
    the block presses the bar's end B down, F_B = (k l S, -(m_p g + F)) (F_Bx balances the
    spring at A), the slider pushes the bar at A with F_A = (-k l S, (m + m_p) g + F), and
    lambda = ((F_Bx - F_Ax)/2, (F_Ay - F_By)/2) = (k l S, (m/2 + m_p) g + F), the reference's
    rows 1 and 2 at rest (k x = lambda1, (m/2 + m_p) g = lambda2 - F)."""
    p = _params("exercise_6_1")
    m, m_p, l, k, c, F, g = (p[n] for n in ("m", "m_p", "l", "k", "c", "F", "g"))
    th = math.acos(((m / 2 + m_p) * g + F) / (k * l))
    S, C = math.sin(th), math.cos(th)
    q, u = [l * S, l * C, th], [0.0, 0.0, 0.0]
    lam = [k * l * S, (m / 2 + m_p) * g + F]
    fw = engine("exercise_6_1", None).forward(q, u)
    raw = fw.raw
    assert raw["rigid_accelerations"] == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
    assert raw["rigid_multipliers"] == pytest.approx(lam, rel=1e-10)
    assert raw["rigid_engine_forces"] == pytest.approx(
        [k * l * S, -(m_p * g + F), 0.0], rel=1e-10, abs=1e-10
    )
    assert raw["spring_damper_force"] == pytest.approx(-k * l * S, rel=1e-14)
    # the slider's force on the bar (cfrc_int) at MuJoCo's own (soft) answer, ~1e-4 off
    assert raw["pin_A_force_cfrc"] == pytest.approx(
        [-k * l * S, (m + m_p) * g + F, 0.0], rel=1e-3, abs=1e-9
    )
    assert fw.multipliers == pytest.approx(lam, rel=1e-3)
    assert reference("exercise_6_1").forward(q, u).multipliers == pytest.approx(lam, rel=1e-12)
    # moving: the damper opposes x' (qfrc_passive = -k x - c x'), and the slider transmits it
    # to the bar (cfrc_int = the Newton-derived F_A at MuJoCo's answer; light slider: 1e-12)
    w = 1.3
    fm = engine("exercise_6_1", None).forward([l * S, l * C, th], [l * C * w, -l * S * w, w])
    assert fm.raw["spring_damper_force"] == pytest.approx(-k * l * S - c * l * C * w, rel=1e-14)
    assert fm.raw["pin_A_force_cfrc"][0] == pytest.approx(fm.raw["spring_damper_force"], rel=1e-10)
    assert fm.raw["pin_A_force_cfrc"] == pytest.approx(fm.raw["pin_A_force"], rel=1e-10, abs=1e-10)


def test_sign_exercise_6_2():
    """Y down. Hanging at rest with the spring holding F (k x = F): q'' = 0 and the pin holds
    the bar UP, lambda = (0, -m2 g) (the reference's m2 y_G'' - m2 g = lambda2). Moving at the
    bottom with the block held still by the spring alone is not static, so the second case
    checks the load signs through MuJoCo's own generalized forces: qfrc_passive(x) = -k x -
    c x', qfrc_applied(x) = +F."""
    p = _params("exercise_6_2")
    m2, l, k, c, F, g = (p[n] for n in ("m2", "l", "k", "c", "F", "g"))
    em = engine("exercise_6_2", None)
    q, u = [F / k, 0.0, 0.0, l / 2], [0.0, 0.0, 0.0, 0.0]
    fw = em.forward(q, u)
    assert fw.accelerations == pytest.approx(np.zeros(4), abs=1e-12)
    assert fw.multipliers == pytest.approx([0.0, -m2 * g], rel=1e-13, abs=1e-13)
    assert fw.raw["pin_force_on_bar"] == pytest.approx([0.0, -m2 * g, 0.0], abs=1e-12)
    assert reference("exercise_6_2").forward(q, u).multipliers == pytest.approx(
        [0.0, -m2 * g], abs=1e-12
    )
    x, xd = 0.2, -0.7
    em.forward([x, 0.0, 0.0, l / 2], [xd, 0.0, 0.0, 0.0])
    assert em.d.qfrc_passive[0] == pytest.approx(-k * x - c * xd, rel=1e-14)
    assert em.d.qfrc_applied[0] == F


def test_sign_exercise_6_4():
    """Z up, no motor torques. (a) Hanging at rest: the pin holds the bar up, lambda =
    (0, m g). (b) Hanging, the disk spinning at Omega, theta' = 0: the bar is flung outward,
    theta'' = 3 R Omega^2 / (2 l) (moment balance about P with the radial pin force), and the
    pin pulls it INWARD, lambda1 = m y_G'' - m R Omega^2 = -m R Omega^2 / 4, lambda2 = m g;
    phi'' = 0. (c) The torsional spring and damper act on theta: qfrc_passive = -k theta -
    c theta'."""
    p = _params("exercise_6_4", M_phi=0.0, M_theta=0.0)
    m, R, l, k, c, g = (p[n] for n in ("m", "R", "l", "k", "c", "g"))
    em = ADAPTER.build("exercise_6_4", {"M_phi": 0.0, "M_theta": 0.0})
    nm = NumericModel(get("exercise_6_4"), None, {"M_phi": 0.0, "M_theta": 0.0})
    q = [0.3, 0.0, R, -l / 2]
    fw = em.forward(q, [0.0] * 4)
    assert fw.accelerations == pytest.approx(np.zeros(4), abs=1e-12)
    assert fw.multipliers == pytest.approx([0.0, m * g], rel=1e-13, abs=1e-13)
    W = 2.5
    fw = em.forward(q, [W, 0.0, 0.0, 0.0])
    thdd = 3 * R * W * W / (2 * l)
    assert fw.accelerations == pytest.approx([0.0, thdd, l / 2 * thdd, 0.0], rel=1e-11, abs=1e-11)
    assert fw.multipliers == pytest.approx([-m * R * W * W / 4, m * g], rel=1e-11)
    assert nm.forward(q, [W, 0.0, 0.0, 0.0]).multipliers == pytest.approx(
        [-m * R * W * W / 4, m * g], rel=1e-12
    )
    th, thd = 0.4, -1.1
    em.forward(
        [0.3, th, R + l / 2 * math.sin(th), -l / 2 * math.cos(th)],
        [0.0, thd, l / 2 * math.cos(th) * thd, l / 2 * math.sin(th) * thd],
    )
    assert em.d.qfrc_passive[1] == pytest.approx(-k * th - c * thd, rel=1e-14)


@pytest.mark.parametrize("name", ["exercise_6_1", "exercise_6_2", "exercise_6_4"])
def test_energy_includes_the_joint_springs(name):
    """d.energy[0] holds the joint springs' 1/2 k (q - springref)^2 (not only gravity): with
    the stiffness zeroed in the compiled model the potential drops by exactly the reference's
    spring term k x^2/2 (6.1, 6.2) or k theta^2/2 (6.4). So the adapter's V needs no spring
    correction (the light bodies' energy aside)."""
    nm = reference(name)
    em = engine(name, None)
    no_springs = ADAPTER.build(name)
    assert np.count_nonzero(no_springs.m.jnt_stiffness) == 1
    no_springs.m.jnt_stiffness[:] = 0.0
    for q, u in states(reference(name), 3, seed=8):
        _, V = nm.energy(q, u)
        spring = 0.5 * nm.params["k"] * (q[1] if name == "exercise_6_4" else q[0]) ** 2
        assert spring > 1e-6
        assert em.energy(q, u)[1] == pytest.approx(V, abs=1e-12 * (1 + abs(V)))
        assert no_springs.energy(q, u)[1] == pytest.approx(V - spring, abs=1e-12 * (1 + abs(V)))


@pytest.mark.parametrize("name", ["exercise_6_2", "exercise_6_4"])
def test_exercise_mass_matrix_on_the_manifold(name):
    """mass_matrix is None (the reference's M belongs to its relaxed coordinates), but on the
    constraint manifold the two must agree: with u = Z(q) v_e (Z = d u / d v_e, the speed map
    from the engine's minimal speeds), Z^T M_ref Z = M_engine (less the 6.4 bar's 1e-12 axial
    inertia)."""
    nm = reference(name)
    em = engine(name, None)
    assert em.mass_matrix(nm.model.initial_q) is None
    for q, u in states(reference(name), 4, seed=9):
        qe, ve = em.to_engine_state(q, u)
        Z = np.column_stack(
            [
                em.from_engine_state(qe, e)[1] - em.from_engine_state(qe, 0 * e)[1]
                for e in np.eye(len(ve))
            ]
        )
        M, *_ = nm.matrices(q, u)
        em.d.qpos[:], em.d.qvel[:] = qe, ve
        mujoco.mj_forward(em.m, em.d)
        Me = np.zeros((em.m.nv, em.m.nv))
        mujoco.mj_fullM(em.m, em.d, Me)
        assert max_abs(Z.T @ M @ Z - Me) <= TOL_MASS * max_abs(Me), (name, Z.T @ M @ Z, Me)


# ======================================================================================
# why pendulum_xy is a light rod and not a tendon equality (docs/engines/mujoco.md)
# ======================================================================================
def test_tendon_equality_misses_jdot_v():
    """A spatial tendon origin -> bob held at its length: its one row has aref = 0 (no J-dot v),
    so at speed v its de-regularized tension is m g cos(theta) only, short of m v^2/L; at v = 0
    it agrees. The adapter's light-rod connect has no such gap (test_sign_pendulum)."""
    p = _params("pendulum_xy")
    m, L, g = p["m"], p["L"], p["g"]
    xml = f"""<mujoco><option gravity="0 {g!r} 0" tolerance="1e-15"><flag contact="disable"/>
    </option><worldbody><site name="o"/><body name="bob" pos="0 {L!r} 0">
    <joint name="x" type="slide" axis="1 0 0"/><joint name="y" type="slide" axis="0 1 0"/>
    <inertial pos="0 0 0" mass="{m!r}" diaginertia="1e-12 1e-12 1e-12"/><site name="b"/>
    </body></worldbody>
    <tendon><spatial name="rod"><site site="o"/><site site="b"/></spatial></tendon>
    <equality><tendon tendon1="rod" solimp="{" ".join(map(str, SOLIMP))}"/></equality>
    </mujoco>"""
    mm = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(mm)
    th = 0.3
    for w in (0.0, 2.0):
        d.qpos[:] = [L * math.sin(th), L * math.cos(th) - L]  # qpos0: the tendon length is L
        d.qvel[:] = [L * w * math.cos(th), -L * w * math.sin(th)]
        mujoco.mj_forward(mm, d)
        assert abs(d.efc_aref[0]) <= 1e-9  # J-dot v of the length row would be L w^2
        T_rigid = -d.efc_force[0] * (1 + (1 - SOLIMP[0]) / SOLIMP[0])  # f = d f_rigid (1 row)
        assert T_rigid == pytest.approx(m * g * math.cos(th), rel=1e-9)
        missing = m * L * w * w
        assert (m * g * math.cos(th) + missing) - T_rigid == pytest.approx(missing, abs=1e-9)


# ======================================================================================
# energy and simulation
# ======================================================================================
def test_simulate_rk4_matches_reference_and_energy_is_read_after_forward():
    """pendulum_angle, RK4, dt = 1e-3 for 1 s against the reference integrated by scipy at
    1e-12: RK4's global error ~ dt^4 leaves < 1e-9 rad; energy conserved to 1e-10; and with
    Euler the d.energy read right after mj_step is the one of the state at the START of the
    step (docs/engines/mujoco.md), which is why simulate() calls mj_forward first."""
    from scipy.integrate import solve_ivp

    em = engine("pendulum_angle", None)
    nm = reference("pendulum_angle")
    q0, u0 = [1.2], [0.5]
    tr = em.simulate(q0, u0, np.linspace(0.0, 1.0, 11), integrator="RK4", timestep=1e-3)
    assert tr.steps == 1000 and tr.t[-1] == pytest.approx(1.0) and len(tr.t) == 11
    sol = solve_ivp(
        lambda t, y: [y[1], nm.forward([y[0]], [y[1]]).accelerations[0]],
        (0, tr.t[-1]),
        [q0[0], u0[0]],
        t_eval=tr.t,
        rtol=1e-12,
        atol=1e-12,
        method="DOP853",
    )
    assert max_abs(tr.q[:, 0] - sol.y[0]) <= 1e-9
    assert max_abs(tr.u[:, 0] - sol.y[1]) <= 1e-8
    E = tr.energy
    assert E[0] == pytest.approx(sum(nm.energy(q0, u0)), abs=1e-14)
    assert max_abs(E - E[0]) <= 1e-10
    # lagged energy straight after mj_step
    m = mujoco.MjModel.from_xml_string(em.xml)
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = q0, u0
    mujoco.mj_step(m, d)
    lagged = d.energy.copy()
    mujoco.mj_forward(m, d)
    assert abs(lagged.sum() - d.energy.sum()) > 1e-6
    assert lagged.sum() == pytest.approx(sum(nm.energy(q0, u0)), abs=1e-12)


def test_simulate_steps_in_one_call_as_step_by_step_and_rejects_bad_times():
    """The steps between two output times go to MuJoCo as one mj_step(nstep=k) call: the
    recorded states equal a step-by-step loop's to the bit. Output times that go backwards or
    start before 0 are an error that says what is expected."""
    em = engine("slider_crank_split", None)
    nm = reference("slider_crank_split")
    q0, u0 = nm.model.initial_q, nm.model.initial_u
    t_eval = [0.0, 0.013, 0.05, 0.051]
    tr = em.simulate(q0, u0, t_eval, integrator="RK4", timestep=1e-3)
    m = mujoco.MjModel.from_xml_string(em.xml)
    m.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    m.opt.timestep = 1e-3
    d = mujoco.MjData(m)
    em._set(*em.to_engine_state(q0, u0), m, d)
    stepwise = []
    for k in range(52):
        if k:
            mujoco.mj_step(m, d)
        if k in (0, 13, 50, 51):
            stepwise.append(em.from_engine_state(d.qpos.copy(), d.qvel.copy()))
    assert tr.steps == 51 and len(tr.t) == len(stepwise) == 4
    for (q, u), tq, tu in zip(stepwise, tr.q, tr.u, strict=True):
        assert np.array_equal(q, tq) and np.array_equal(u, tu)
    for bad in ([0.0, 0.02, 0.01], [-0.001, 0.01]):
        with pytest.raises(ValueError, match="increasing times >= 0"):
            em.simulate(q0, u0, bad, integrator="RK4", timestep=1e-3)


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast", "RK4"])
def test_simulate_constrained_drift(integrator):
    """slider_crank_split for 0.5 s at dt = 1e-3: the state comes back in reference
    coordinates, the connect drift stays small (solref 0.02 1) and shrinks with RK4."""
    em = engine("slider_crank_split", None)
    nm = reference("slider_crank_split")
    q0, u0 = nm.model.initial_q, nm.model.initial_u
    tr = em.simulate(q0, u0, np.linspace(0.0, 0.5, 51), integrator=integrator, timestep=1e-3)
    assert tr.q.shape == (51, 3) and tr.u.shape == (51, 3) and tr.steps == 500
    pos, _ = nm.residuals(tr.q[-1], tr.u[-1])
    assert max_abs(pos) == pytest.approx(tr.violation[-1], rel=1e-6, abs=1e-12)
    limit = {"Euler": 5e-3, "implicitfast": 5e-3, "RK4": 1e-4}[integrator]
    assert max_abs(tr.violation) <= limit
    E = tr.energy
    assert E[0] == pytest.approx(sum(nm.energy(q0, u0)), abs=1e-12)
    # the energy error's size: tests/test_mujoco_bounds.py (derived from order and step)


@pytest.mark.parametrize(
    "name,limit", [("exercise_6_1", 1e-5), ("exercise_6_2", 1e-9), ("exercise_6_4", 1e-9)]
)
def test_simulate_exercises_against_reference(name, limit):
    """1 s of MuJoCo RK4 (dt = 1e-3) from the model's initial state against the reference
    (projection method, tolerance 1e-12). The trees (6.2, 6.4: springs and dampers as joint
    stiffness/damping, motor torques as qfrc_applied) stay within RK4's ~1e-11; the ladder's
    error follows its connect drift (solref 0.02: ~1e-6 here), so its bound is 1e-5."""
    from reference.integrate.driver import simulate

    nm = reference(name)
    q0, u0 = nm.project(nm.model.initial_q, nm.model.initial_u)
    tr = engine(name, None).simulate(q0, u0, [0.0, 1.0], integrator="RK4", timestep=1e-3)
    ref = simulate(nm, q0, u0, 1.0, "projection", rtol=1e-12, atol=1e-12)
    assert tr.t[-1] == pytest.approx(ref.t[-1])
    assert max_abs(tr.q[-1] - ref.q[-1]) <= limit
    assert max_abs(tr.violation) <= limit
    E0 = sum(nm.energy(q0, u0))
    assert tr.energy[0] == pytest.approx(E0, abs=1e-12 * (1 + abs(E0)))


# ======================================================================================
# MJCF files and the adapter contract
# ======================================================================================
def test_mjcf_files_are_current_and_load(tmp_path):
    """crosscheck/engines/mujoco/mjcf/ holds exactly what the generator writes (regenerate with
    `python -m crosscheck.engines.mujoco.adapter`); each file loads, contacts are off, energy
    is on, every equality has solimp 0.9999, and trees sit under one top-level body."""
    fresh = {p.name: p.read_text() for p in write_mjcf(tmp_path)}
    stored = {p.name: p.read_text() for p in MJCF_DIR.glob("*.xml")}
    assert stored == fresh
    for name, text in fresh.items():
        m = mujoco.MjModel.from_xml_string(text)
        assert m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
        assert m.opt.enableflags & mujoco.mjtEnableBit.mjENBL_ENERGY
        assert m.opt.tolerance == 1e-15
        for e in range(m.neq):
            assert tuple(m.eq_solimp[e]) == SOLIMP
        has_free = any(m.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
        top_level = [b for b in range(1, m.nbody) if m.body_parentid[b] == 0]
        assert has_free or len(top_level) == 1, name  # free joints must be top-level


def test_mjcf_gravity_follows_the_reference_axes():
    """Each MJCF file's gravity is the reference model's, on its own axes (Example 1 Y down,
    the planar and spatial models Y up, the top Z up), and the files hold numbers generated
    from the parameters, not parameter names."""
    assert tuple(engine("pendulum_xy", None).m.opt.gravity) == (0.0, 9.81, 0.0)  # Y down
    assert tuple(engine("slider_crank", None).m.opt.gravity) == (0.0, -9.81, 0.0)
    assert tuple(engine("double_pendulum_3d", "free").m.opt.gravity) == (0.0, -9.81, 0.0)
    assert tuple(engine("top_euler", None).m.opt.gravity) == (0.0, 0.0, -9.81)
    assert "m2" not in mjcf("slider_crank")  # numbers, not names: generated from parameters
