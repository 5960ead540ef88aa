"""What only the Pinocchio adapter does, with the real Pinocchio 4.1 (no mocks).

What every engine does (state maps, accelerations, multipliers and energy against the
reference, the fingerprint, the nominal maps, faults seen, the timing hook, refusals) is
tests/test_engine_contract.py. Here, model by model and (for the 3-D models) engine variant
by variant:
- the engine state on Pinocchio's own constraint manifold, and engine -> reference -> engine
  with its quaternions' sign convention;
- which models give M and f in the reference's speeds, and those against every formulation;
- V as Pinocchio's computePotentialEnergy, and the top's formulation-dependent multiplier;
- the sign and frame of every constraint force, on static poses whose force balance is done
  by hand below (and the rod tension of Example 1 in motion);
- Pinocchio's own solve (iterations, primal/dual residuals), the proximal settings chosen for
  redundant planar rows, and short trajectories with the adapter's right-hand side.

States: hypothesis draws an integer seed, tests.support.states draws a consistent state from
it. Every @settings has derandomize=True, so the examples are the same on every run whatever
hypothesis profile is loaded.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pinocchio as pin
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from crosscheck.engines.pinocchio.adapter import PROX_EXACT, PROX_REDUNDANT, PinocchioAdapter
from reference.models import get, names, user_names
from reference.numeric.model import NumericModel, resolve_parameters
from tests.support import QUICK_MODELS, representative, scaled_error, states

EPS = np.finfo(float).eps

# ---- named tolerances, each with its reason ---------------------------------------------
# State map: the round trip composes at most a few rotations, quaternion <-> matrix
# conversions and acos/atan2 of matrix entries (3-1-3 angles; theta2 >= 0.3 keeps acos'
# amplification below 1/sin(0.3) ~ 3.4), each a few ulp: 1e-14 relative to max(1, |x|) is
# ~45 ulp; the states are consistent to round-off (tests.support.states).
STATE_MAP_RTOL = 1e-14
# The engine measures the state's violation in length units (| |p| - L | = |f|/L for the
# pendulum, anchor mismatch = |f| for the closures): round-off of coordinates up to ~10, with
# margin.
MANIFOLD_ATOL = 1e-12
# Accelerations and multipliers. Both sides solve the same KKT system with backward-stable
# factorizations (reference: Cholesky of M and of the Schur complement; engine: ABA, Cholesky
# of the KKT matrix or proximal Cholesky iterations), so the forward error is ~cond * eps times
# the size of the terms. The worst conditioned case is the 3-D double pendulum, whose axial
# inertias (2e-4 and 1e-4 kg m^2 against ~0.08 transverse) give cond(M) ~ 1e3 and measured
# errors up to ~1e-12 relative; the proximal iterations for the redundant planar rows stop at
# |d lambda| <= 1e-12 with a contraction ~mu |G^-1| ~ 1e-8 per iteration, far below that.
# 1e-11 is the suite's contract for Pinocchio: ~10x above the worst measured figure, ~1e4x
# below the 1e-7 effect of the fault injection m2 * (1 + 1e-6).
ACC_RTOL = 1e-11
LAM_RTOL = 1e-11
# M, f and energies: the same closed-form expressions evaluated in a different order, no
# solve: a few ulp per term, 1e-13 relative to max(1, |ref|) leaves a margin of ~50 ulp.
MATRIX_RTOL = 1e-13
ENERGY_RTOL = 1e-13
# Pinocchio's own residuals |J a + gamma| and |rnea(q, v, a, f_ext) - tau|: round-off on terms
# up to ~300 (the top's omega^2 L) in SI units: 1e-10 absolute is ~1e-12 relative.
RESIDUAL_ATOL = 1e-10
# Trajectories: the engine and the reference integrate the same ODE in different coordinates
# with DOP853 at rtol = atol = 1e-10 for 1 s; each global error is ~1e-9 (measured), so 1e-7
# bounds their difference with margin while the fault-injection effect (1e-7 relative in
# accelerations, ~1e-7 in the state after 1 s) is not what this check is for.
SIM_TOL = 1e-7
SIM_RTOL = 1e-10

ADAPTER = PinocchioAdapter()
# T != 0 and motor torques != 0 so the torque maps are exercised
PARAMS = {
    "slider_crank": {"T": 0.7},
    "slider_crank_split": {"T": 0.7},
    "slider_crank_free": {"T": 0.7},
    "frame_bar": {"M_phi": 0.3, "M_theta": -0.2},
    "knife_edge": {"P": 0.4, "T": -0.3},
}

PLANAR = [
    "pendulum_angle",
    "pendulum_xy",
    "slider_crank",
    "slider_crank_split",
    "slider_crank_free",
]
THREE_D = ["frame_bar", "double_pendulum_3d", "top_euler", "top_cartesian"]
OTHERS = ["knife_edge", "pendulum_moving_support", "exercise_6_1", "exercise_6_2", "exercise_6_4"]
MODELS = PLANAR + THREE_D + OTHERS
# (model, variant) pairs: every engine variant of every mapped model
ALL_CASES = [(m, v) for m in MODELS for v in ADAPTER.variants(m)]
CASES = representative(ALL_CASES, QUICK_MODELS, key=lambda c: c[0])


@cache
def reference(model_name: str, formulation: str | None = None, params_key=()):
    params = dict(PARAMS.get(model_name, {}))
    params.update(dict(params_key))
    return NumericModel(get(model_name), formulation, params)


@cache
def engine(model_name: str, variant=None, params_key=()):
    params = dict(PARAMS.get(model_name, {}))
    params.update(dict(params_key))
    return ADAPTER.build(model_name, params, variant=variant)


def params_of(model_name):
    return resolve_parameters(get(model_name), PARAMS.get(model_name, {}))


def canonical_engine_state(em, qe):
    """Quaternion blocks with w >= 0 (q and -q are the same rotation)."""
    qe = np.array(qe, float)
    for jm in em.model.joints[1:]:
        kind, iq = jm.shortname(), jm.idx_q
        k = (
            iq
            if kind == "JointModelSpherical"
            else iq + 3
            if kind == "JointModelFreeFlyer"
            else None
        )
        if k is not None and qe[k + 3] < 0:
            qe[k : k + 4] *= -1
    return qe


SEEDS = st.integers(min_value=0, max_value=2**32 - 1)


# ---- state map --------------------------------------------------------------------------
@pytest.mark.parametrize("model_name,variant", CASES)
@settings(derandomize=True, max_examples=15, deadline=None)
@given(seed=SEEDS)
def test_engine_state_is_on_pinocchios_manifold_and_maps_back(model_name, variant, seed):
    """The mapped engine state has Pinocchio's sizes and lies on the engine's own constraint
    manifold, and engine -> reference -> engine is the identity, a quaternion and its negative
    being one rotation (the reference -> engine -> reference round trip is the contract's)."""
    em = engine(model_name, variant)
    q, u = states(reference(model_name), 1, seed=seed)[0]
    qe, ve = em.to_engine_state(q, u)
    assert qe.shape == (em.model.nq,) and ve.shape == (em.model.nv,)
    assert em.constraint_violation(qe) <= MANIFOLD_ATOL * max(1.0, np.max(np.abs(qe)))
    qe2, ve2 = em.to_engine_state(*em.from_engine_state(qe, ve))
    canonical = canonical_engine_state(em, qe2), canonical_engine_state(em, qe)
    assert scaled_error(*canonical) <= STATE_MAP_RTOL
    assert scaled_error(ve2, ve) <= STATE_MAP_RTOL


# ---- instantaneous agreement ------------------------------------------------------------
@pytest.mark.parametrize("formulation", get("top_euler").formulations)
@settings(derandomize=True, max_examples=15, deadline=None)
@given(seed=SEEDS)
def test_the_tops_normalization_multiplier_is_in_raw(formulation, seed):
    """The top's normalization row has no engine force (multipliers None, the note says
    why); raw carries the textbook value of its formulation-dependent multiplier computed
    from the engine's K and V: 2V - 4K for Lagrange, 0 for d'Alembert and Kane."""
    em, nm = engine("top_euler"), reference("top_euler", formulation)
    q, u = states(reference("top_euler"), 1, seed=seed)[0]
    out = em.forward(q, u)
    assert out.multipliers is None and out.multipliers_note
    key = (
        "normalization_lambda_lagrange"
        if formulation == "lagrange"
        else "normalization_lambda_dalembert_kane"
    )
    assert scaled_error([out.raw[key]], nm.forward(q, u).multipliers) <= LAM_RTOL


@pytest.mark.parametrize("model_name,variant", CASES)
def test_engine_solve_quality(model_name, variant):
    """Pinocchio's own answer satisfies its constraint rows (primal) and its inverse dynamics
    with the constraint forces applied gives back tau (dual); iterations as documented (a tree
    on aba: no solve, 0)."""
    em = engine(model_name, variant)
    for q, u in states(reference(model_name), 5, seed=0):
        raw = em.forward(q, u).raw
        if em.solver == "aba":
            assert raw["solver"] == "aba" and raw["iterations"] == 0
            continue
        assert raw["primal_residual"] <= RESIDUAL_ATOL
        assert raw["dual_residual"] <= RESIDUAL_ATOL
        if raw["solver"] == "constraint":
            assert 1 <= raw["iterations"] <= raw["prox_settings"][2]
            if raw["prox_settings"] == PROX_EXACT:
                assert raw["iterations"] == 1


def test_redundant_planar_rows_need_the_proximal_settings():
    """docs/engines/pinocchio.md: the slider-crank's 3-row closure has an identically zero
    out-of-plane row, so the plain Cholesky KKT (mu = 0, one iteration) gives NaN, and
    PROX_REDUNDANT converges in a few iterations to the reference's answer."""
    model_name = "slider_crank"
    q, u = states(reference(model_name), 1, seed=7)[0]
    em = ADAPTER.build(model_name, PARAMS[model_name])
    ok = em.forward(q, u)
    assert ok.raw["iterations"] <= 10
    em.prox = pin.ProximalSettings(*PROX_EXACT)
    bad = em.forward(q, u)
    assert not np.all(np.isfinite(bad.accelerations))
    assert PROX_REDUNDANT[1] > 0


@pytest.mark.parametrize("model_name,variant", CASES)
def test_mass_matrix_and_forcing(model_name, variant):
    """Where the coordinates map linearly the engine's M (crba) and f = tau - nle equal the
    reference's M and f of every formulation; elsewhere the adapter says None, and says why
    in the class attribute mass_matrix_note (one sentence, shown in results)."""
    em = engine(model_name, variant)
    for q, u in states(reference(model_name), 4, seed=0):
        M = em.mass_matrix(q)
        f = em.forcing(q, u)
        for formulation in get(model_name).formulations:
            Mr, fr, _, _ = reference(model_name, formulation).matrices(q, u)
            if M is not None:
                assert scaled_error(M, Mr) <= MATRIX_RTOL
            if f is not None:
                assert scaled_error(f, fr) <= MATRIX_RTOL
    expected_M = {
        "pendulum_angle",
        "pendulum_xy",
        "slider_crank_split",
        "slider_crank_free",
        "knife_edge",
        "pendulum_moving_support",
    }
    assert (em.mass_matrix(q) is not None) == (
        model_name in expected_M or (model_name, variant) == ("double_pendulum_3d", "free")
    )
    note = type(em).mass_matrix_note
    if em.mass_matrix(q) is None:
        assert isinstance(note, str) and len(note) > 20 and "\n" not in note
    else:
        assert note is None


@cache
def _spring_potential(model_name):
    """The reference's spring potential (its model's `potential`), by sympy lambdify."""
    mod = get(model_name)
    sub = {sp.Symbol(k, real=True): v for k, v in params_of(model_name).items()}
    return sp.lambdify(
        [list(mod.coordinates), list(mod.speeds)], sp.sympify(mod.potential).xreplace(sub), "math"
    )


@pytest.mark.parametrize("model_name,variant", CASES)
def test_potential_is_pinocchios_computePotentialEnergy(model_name, variant):
    """V is computed by the adapter from the body positions and equals Pinocchio's
    computePotentialEnergy: both put the datum at the world origin (the pivot O / point A), as
    the reference does (V = -sum m g . r_G); the springs' potential (Exercises 6.1, 6.2, 6.4)
    is added by the adapter. (V against the reference is the contract's.)"""
    em = engine(model_name, variant)
    for q, u in states(reference(model_name), 4, seed=0):
        K, V = em.energy(q, u)
        qe, _ = em.to_engine_state(q, u)
        V_gravity = V - _spring_potential(model_name)(list(q), list(u))
        scale = max(1.0, abs(K) + abs(V))
        assert (
            abs(V_gravity - pin.computePotentialEnergy(em.model, em.data, qe))
            <= ENERGY_RTOL * scale
        )


def test_planar_in_plane_inertia_does_not_matter():
    """The planar bars get diag(I/2, I/2, I) in the engine; other in-plane values change
    nothing (hinges about Z and slides in the plane never excite them)."""
    for model_name in ("slider_crank", "slider_crank_split", "slider_crank_free"):
        q, u = states(reference(model_name), 1, seed=3)[0]
        em = ADAPTER.build(model_name, PARAMS[model_name])
        before = em.forward(q, u)
        for i in range(1, em.model.njoints):
            Y = em.model.inertias[i]
            if Y.inertia[2, 2] > 0:
                I = Y.inertia.copy()
                I[0, 0], I[1, 1] = 3.0 * I[2, 2], 5.0 * I[2, 2]
                em.model.inertias[i] = pin.Inertia(Y.mass, Y.lever, I)
        after = em.forward(q, u)
        assert scaled_error(after.accelerations, before.accelerations) <= 4 * EPS
        if before.multipliers is not None and before.multipliers.size:
            assert scaled_error(after.multipliers, before.multipliers) <= 4 * EPS


# ---- signs and frames of the constraint forces: hand-computed cases ------------------------
def _both(model_name, q, u, variant=None, formulation=None, params=None):
    mod = get(model_name)
    params = params or PARAMS.get(model_name, {})
    em = ADAPTER.build(model_name, params, variant=variant)
    nm = NumericModel(mod, formulation or mod.formulations[0], params)
    q, u = np.asarray(q, float), np.asarray(u, float)
    return em.forward(q, u), nm.forward(q, u), em


def test_pendulum_rod_tension():
    """Example 1 with Y down. At rest at the bottom the rod holds the bob up: tension m g,
    lambda = -T/L = -m g/L (Addendum). In motion, radial balance of the bob gives
    T = m L thetadot^2 + m g cos(theta); 1(a) reads it from rnea (raw rod_tension), 1(b) as
    -lambda L, and both agree with the hand formula."""
    p = params_of("pendulum_xy")
    m, L, g = p["m"], p["L"], p["g"]
    e, r, _ = _both("pendulum_xy", [0.0, L], [0.0, 0.0])
    assert abs(e.multipliers[0] - (-m * g / L)) <= 1e-13 * m * g / L
    assert abs(r.multipliers[0] - (-m * g / L)) <= 1e-13 * m * g / L
    assert np.max(np.abs(e.accelerations)) <= 1e-14 * g
    e, _, _ = _both("pendulum_angle", [0.0], [0.0])
    assert abs(e.raw["rod_tension"] - m * g) <= 1e-13 * m * g
    for th, thd in ((0.3, 1.0), (2.0, -3.0), (-1.2, 0.5)):
        T = m * L * thd**2 + m * g * math.cos(th)
        ea, _, _ = _both("pendulum_angle", [th], [thd])
        exy, rxy, _ = _both(
            "pendulum_xy",
            [L * math.sin(th), L * math.cos(th)],
            [L * thd * math.cos(th), -L * thd * math.sin(th)],
        )
        assert abs(ea.raw["rod_tension"] - T) <= 1e-13 * max(1.0, abs(T))
        assert abs(exy.raw["rod_tension"] - T) <= 1e-13 * max(1.0, abs(T))
        assert abs(-rxy.multipliers[0] * L - T) <= 1e-13 * max(1.0, abs(T))


def test_slider_crank_guide_force_static():
    """Example 2(b) at rest with the crank straight up (theta1 = pi/2, B above A), T = 0.
    The slider has no horizontal external force, so the rod pushes it only vertically; the
    rod's moments about B give the guide force N c = m2 g (r2 cos theta2) + m3 g c with
    c = l2 cos theta2, i.e. N = g (m3 + m2 r2 / l2), UPWARD (lambda > 0); the rod's force at B
    is vertical through A and the crank's weight acts through A, so the mechanism is in
    equilibrium: u' = 0. r2 is moved off l2/2 so r2/l2 is really tested."""
    params = {"T": 0.0, "r2": 0.3}
    p = resolve_parameters(get("slider_crank"), params)
    th2 = -math.asin(p["l1"] / p["l2"])
    e, r, _em = _both("slider_crank", [math.pi / 2, th2], [0.0, 0.0], params=params)
    N = p["g"] * (p["m3"] + p["m2"] * p["r2"] / p["l2"])
    assert N > 0
    for lam in (e.multipliers[0], r.multipliers[0], e.raw["guide_force_rnea"]):
        assert abs(lam - N) <= 1e-13 * N
    # the engine's own force: slider on rod at C = (0, N - m3 g, 0) = (0, m2 g r2/l2, 0)
    assert np.allclose(
        e.raw["force_on_rod_at_C"],
        [0.0, p["m2"] * p["g"] * p["r2"] / p["l2"], 0.0],
        rtol=0,
        atol=1e-13 * N,
    )
    assert np.max(np.abs(e.accelerations)) <= 1e-13 and np.max(np.abs(r.accelerations)) <= 1e-13


def test_slider_crank_split_force_on_crank_static():
    """Note 2 / 6.3, same pose (theta2 from C to B, r2 = |C G2| = 0.3). The rod + slider has no
    horizontal external force except the crank's at B, so that force is vertical; moments of
    the rod about C: F_By c = m2 g r2 c / l2. The force of the rod on the crank is the
    opposite: (lambda1, lambda2) = (0, -m2 g r2 / l2), pointing DOWN; u' = 0."""
    params = {"T": 0.0, "r2": 0.3}
    p = resolve_parameters(get("slider_crank_split"), params)
    c = math.sqrt(p["l2"] ** 2 - p["l1"] ** 2)
    q = [math.pi / 2, c, math.atan2(p["l1"], -c)]
    e, r, _ = _both("slider_crank_split", q, [0.0, 0.0, 0.0], params=params)
    lam = np.array([0.0, -p["m2"] * p["g"] * p["r2"] / p["l2"]])
    for got in (e.multipliers, r.multipliers):
        assert np.max(np.abs(got - lam)) <= 1e-13 * abs(lam[1])
    assert np.max(np.abs(e.accelerations)) <= 1e-13


def test_frame_bar_bearing_moment_sign():
    """Example 3 at theta = 0 with phi' = W, theta' = s, no torques: omega = (0, s, W), the
    constraint rate gives omega1' = -W s, the printed equations give omega2' = omega3' = 0 and
    lambda = (I1 + m d^2) omega1' + (I3 + m d^2 - I2) s W = W s (I3 - I1 - I2): the n1 moment
    of the bearing on F, read in the engine from rnea's data.f[1]."""
    params = {"M_phi": 0.0, "M_theta": 0.0}
    p = resolve_parameters(get("frame_bar"), params)
    W, s = 3.0, 1.5
    e, r, _ = _both("frame_bar", [0.4, 0.0], [0.0, s, W], params=params)
    lam = W * s * (p["I3"] - p["I1"] - p["I2"])
    for got in (e.multipliers[0], r.multipliers[0]):
        assert abs(got - lam) <= 1e-13 * max(1.0, abs(lam))
    assert np.allclose(e.accelerations, [-W * s, 0.0, 0.0], rtol=0, atol=1e-13)


@pytest.mark.parametrize("variant", ADAPTER.variants("double_pendulum_3d"))
def test_double_pendulum_hanging_forces(variant):
    """Example 4 hanging at rest (theta_i = (-pi/2, pi/2, pi/2), links along -N2): link 1
    holds link 2 up at A, F_A = m2 g N2, the ground holds both at O, F_O = (m1 + m2) g N2, so
    lambda = (F_O - F_A, F_A) = (m1 g N2, m2 g N2) and u' = 0."""
    p = params_of("double_pendulum_3d")
    hang = (-math.pi / 2, math.pi / 2, math.pi / 2)
    e, r, _ = _both("double_pendulum_3d", hang + hang, np.zeros(12), variant=variant)
    lam = np.array([0, p["m1"] * p["g"], 0, 0, p["m2"] * p["g"], 0])
    for got in (e.multipliers, r.multipliers):
        assert np.max(np.abs(got - lam)) <= 1e-13 * p["g"]
    assert np.max(np.abs(e.accelerations)) <= 1e-13


@pytest.mark.parametrize("variant", ADAPTER.variants("top_cartesian"))
def test_top_upright_socket_force(variant):
    """Exercise 6.7 upright at rest (eps = (0, 0, 0, 1), G above O): an equilibrium, the
    socket pushes up with m g: (lambda1..3) = (0, 0, m g) and lambda4 = 2 L F_O . e3 = 2 m g L.
    Exercise 6.5 (Lagrange) has lambda = 2V - 4K = 2 m g L at the same state."""
    p = params_of("top_cartesian")
    m, g, L = p["m"], p["g"], p["L"]
    q = [0.0, 0.0, L, 0.0, 0.0, 0.0, 1.0]
    e, r, _ = _both("top_cartesian", q, np.zeros(7), variant=variant)
    lam = np.array([0.0, 0.0, m * g, 2 * m * g * L])
    for got in (e.multipliers, r.multipliers):
        assert np.max(np.abs(got - lam)) <= 1e-13 * m * g
    assert np.max(np.abs(e.accelerations)) <= 1e-13
    e, r, _ = _both("top_euler", q[3:], np.zeros(4), formulation="lagrange")
    assert abs(e.raw["normalization_lambda_lagrange"] - 2 * m * g * L) <= 1e-13 * m * g * L
    assert abs(r.multipliers[0] - 2 * m * g * L) <= 1e-13 * m * g * L
    assert np.allclose(e.raw["socket_force"], [0.0, 0.0, m * g], rtol=0, atol=1e-13 * m * g)


def test_exercise_6_1_end_forces_and_multipliers():
    """Exercise 6.1 (Y up) at rest in static equilibrium: the reduced equation (reference
    docstring, part b) has theta'' = 0 at rest where k l C = (m/2 + m_p) g + F. By hand, with
    F_A, F_B the forces on the bar at A and B: the block is at rest, so the bar holds it up
    against m_p g + F: F_By = -(m_p g + F); the massless slider passes the spring's force,
    F_Ax = -k x = -k l S; the bar's balance gives F_Bx = -F_Ax = k l S and
    F_Ay = m g - F_By = (m + m_p) g + F; its moments about A,
    l S (m_p g + F) - l C k l S + m g l S / 2 = l S ((m/2 + m_p) g + F - k l C), vanish at
    that angle. Mapped: lambda = ((F_Bx - F_Ax)/2, (F_Ay - F_By)/2) = (k l S,
    (m/2 + m_p) g + F), the reference's rows 1 and 2 at rest (k x = lambda1,
    (m/2 + m_p) g = lambda2 - F). Then in motion at the same pose: the damper's sign
    (tau_x = -k x - c x', passed by the slider to the bar: rnea's F_Ax), F_A from rnea equals
    the bar's momentum balance, and the engine's own accelerations and mapped multipliers
    satisfy all three of the reference's printed equations."""
    p = params_of("exercise_6_1")
    m, m_p, l, k, c, F, g = (p[n] for n in ("m", "m_p", "l", "k", "c", "F", "g"))
    th = math.acos(((m / 2 + m_p) * g + F) / (k * l))
    S, C = math.sin(th), math.cos(th)
    e, r, _ = _both("exercise_6_1", [l * S, l * C, th], [0.0, 0.0, 0.0])
    lam = np.array([k * l * S, (m / 2 + m_p) * g + F])
    scale = float(np.max(lam))
    for got in (e.multipliers, r.multipliers):
        assert np.max(np.abs(got - lam)) <= 1e-13 * scale
    assert np.max(np.abs(e.accelerations)) <= 1e-13
    assert np.max(np.abs(r.accelerations)) <= 1e-13
    F_B = np.array([k * l * S, -(m_p * g + F), 0.0])
    F_A = np.array([-k * l * S, (m + m_p) * g + F, 0.0])
    assert np.max(np.abs(e.raw["force_of_block_on_bar_at_B"] - F_B)) <= 1e-13 * scale
    assert np.max(np.abs(e.raw["pin_A_force_rnea"] - F_A)) <= 1e-13 * scale
    assert np.max(np.abs(e.raw["pin_A_force_momentum"] - F_A)) <= 1e-13 * scale
    # moving through the same pose
    w = 1.3
    e, r, _ = _both("exercise_6_1", [l * S, l * C, th], [l * C * w, -l * S * w, w])
    xd = l * C * w
    assert abs(e.raw["spring_damper_force"] - (-k * l * S - c * xd)) <= 1e-14 * scale
    F_A = e.raw["pin_A_force_rnea"]
    assert abs(F_A[0] - e.raw["spring_damper_force"]) <= 1e-13 * scale
    assert np.max(np.abs(F_A - e.raw["pin_A_force_momentum"])) <= 1e-13 * scale
    (xdd, ydd, thdd), (lam1, lam2) = e.accelerations, e.multipliers
    assert abs(m / 4 * xdd + c * xd + k * l * S - lam1) <= 1e-13 * scale
    assert abs((m / 4 + m_p) * ydd + (m / 2 + m_p) * g - (lam2 - F)) <= 1e-13 * scale
    assert abs(m * l**2 / 12 * thdd - l * (-lam1 * C + lam2 * S)) <= 1e-13 * scale
    assert scaled_error(e.multipliers, r.multipliers) <= LAM_RTOL
    assert scaled_error(e.accelerations, r.accelerations) <= ACC_RTOL


def test_euler_parameters_are_pinocchio_quaternions():
    """The reference's R(eps) and omega = 2 E eps' are Pinocchio's quaternion (x, y, z, w) =
    (eps1, eps2, eps3, eps4) rotation and LOCAL angular velocity: checked through the engine's
    kinematics (the mass center position and velocity of the top)."""
    from reference.models.top import E_matrix, rotation

    em = engine("top_cartesian", "tree")
    for q, u in states(reference("top_cartesian"), 5, seed=0):
        eps, eps_dot = q[3:7], u[3:7]
        R = rotation(tuple(map(float, eps)))
        # the two formulas differ by a multiple of |eps|^2 - 1 (projection round-off)
        assert (
            np.max(np.abs(R - pin.Quaternion(eps[3], *eps[:3]).toRotationMatrix()))
            <= STATE_MAP_RTOL
        )
        qe, ve = em.to_engine_state(q, u)
        assert np.max(np.abs(ve - 2 * E_matrix(tuple(map(float, eps))) @ eps_dot)) <= 1e-13
        qr, ur = em.from_engine_state(qe, ve)  # x and x' from Pinocchio's forwardKinematics
        assert scaled_error(qr[:3], q[:3]) <= STATE_MAP_RTOL
        assert scaled_error(ur[:3], u[:3]) <= STATE_MAP_RTOL


def test_knife_edge_lateral_force():
    """Knife edge along +X (theta = 0) moving at v with turning rate w, no loads: Newton-Euler
    (reference docstring) gives (I_G + m a^2) w' = -m a v w and the lateral force of the
    ground on the blade lambda = m (v w + a w'), along +Y here; C's velocity stays along X."""
    params = {"P": 0.0, "T": 0.0}
    p = resolve_parameters(get("knife_edge"), params)
    m, a, I_G = p["m"], p["a"], p["I_G"]
    v, w = 1.3, 0.7
    e, r, _ = _both("knife_edge", [0.2, -0.1, 0.0], [v, 0.0, w], params=params)
    wd = -m * a * v * w / (I_G + m * a * a)
    lam = m * (v * w + a * wd)
    for got in (e.multipliers[0], r.multipliers[0]):
        assert abs(got - lam) <= 1e-14 * max(1.0, abs(lam))
    assert abs(e.accelerations[2] - wd) <= 1e-14
    assert abs(e.accelerations[1] - v * w) <= 1e-14  # y'' = d/dt(S v) = C w v at theta = 0


@settings(derandomize=True, max_examples=15, deadline=None)
@given(seed=SEEDS)
def test_moving_support_tension(seed):
    """Example 1(b) with the support at x_s(t) = a sin(Omega t), at random t: in the support's
    frame the bob feels the inertial force -m x_s'' X, so the radial balance gives the rod
    tension T = m L theta'^2 + m g cos(theta) - m x_s'' sin(theta) = -lambda L (Y down);
    engine and reference agree with it and with each other (explicit-time terms included)."""
    rng = np.random.default_rng(seed)
    p = params_of("pendulum_moving_support")
    m, L, g, a, W = p["m"], p["L"], p["g"], p["a"], p["Omega"]
    t, th, thd = rng.uniform(0, 5), rng.uniform(-1.5, 1.5), rng.uniform(-3, 3)
    xs, xsd, xsdd = a * math.sin(W * t), a * W * math.cos(W * t), -a * W * W * math.sin(W * t)
    q = [xs + L * math.sin(th), L * math.cos(th)]
    u = [xsd + L * thd * math.cos(th), -L * thd * math.sin(th)]
    em = engine("pendulum_moving_support")
    nm = reference("pendulum_moving_support", "lagrange")
    e, r = em.forward(q, u, t), nm.forward(q, u, t)
    T = m * L * thd**2 + m * g * math.cos(th) - m * xsdd * math.sin(th)
    assert abs(e.raw["rod_tension"] - T) <= 1e-13 * max(1.0, abs(T))
    assert abs(-r.multipliers[0] * L - T) <= 1e-13 * max(1.0, abs(T))
    assert scaled_error(e.accelerations, r.accelerations) <= ACC_RTOL
    assert em.velocity_violation(*em.to_engine_state(q, u), t) <= 1e-14 * max(1.0, L * W)


# ---- the adapter ------------------------------------------------------------------------
def test_expresses_every_system_of_the_unit():
    """Pinocchio refuses none of the unit's systems (users' models registered by other tests
    come on top)."""
    assert set(ADAPTER.models()) - set(user_names()) == set(names())
    assert not ADAPTER.unsupported()


# ---- trajectories -----------------------------------------------------------------------
def _reference_trajectory(model_name, q0, u0, t_eval):
    """The reference's forward dynamics under the same solve_ivp (DOP853); only for models
    whose speeds are the coordinate rates (q' = u)."""
    nm = reference(model_name, "lagrange")
    n = nm.nq

    def rhs(t, y):
        ud, _lam, _piv = nm.forward_fast(list(y[:n]), list(y[n:]), t)
        return np.concatenate([y[n:], ud])

    sol = solve_ivp(
        rhs,
        (0.0, t_eval[-1]),
        np.concatenate([q0, u0]),
        method="DOP853",
        rtol=SIM_RTOL,
        atol=SIM_RTOL,
        t_eval=t_eval,
    )
    return sol.y.T


@pytest.mark.parametrize(
    "model_name",
    [
        "pendulum_angle",
        "pendulum_xy",
        "slider_crank",
        "slider_crank_split",
        "knife_edge",
        "pendulum_moving_support",
    ],
)
def test_simulate_matches_reference_trajectory(model_name):
    """The adapter's right-hand side in the engine's coordinates under the reference's DOP853
    at SIM_RTOL for 1 s against the reference's forward dynamics under scipy's: within
    SIM_TOL, on the rows, and (planar models) the work-energy balance of the crank torque."""
    em = engine(model_name)
    mod = get(model_name)
    q0, u0 = np.array(mod.initial_q), np.array(mod.initial_u)
    t_eval = np.linspace(0.0, 1.0, 21)
    tr = em.simulate(q0, u0, t_eval, integrator="DOP853", rtol=SIM_RTOL)
    assert tr.failure is None and tr.steps > 0 and np.array_equal(tr.t, t_eval)
    ref = _reference_trajectory(model_name, q0, u0, t_eval)
    n = len(q0)
    assert np.max(np.abs(tr.q - ref[:, :n])) <= SIM_TOL
    assert np.max(np.abs(tr.u - ref[:, n:])) <= SIM_TOL
    assert np.max(tr.violation) <= SIM_TOL
    assert np.max(tr.velocity_violation) <= SIM_TOL
    if model_name in PLANAR:
        # work-energy balance: the constant crank torque T does work T (theta1 - theta1(0))
        T = params_of(model_name).get("T", 0.0)
        E = tr.energy - T * (tr.q[:, 0] - q0[0])
        assert np.max(np.abs(E - E[0])) <= SIM_TOL * max(1.0, abs(E[0]))


def test_simulate_3d_variants_agree():
    """The ball-joint tree and the two constrained free bodies give the same 1 s trajectory
    in reference coordinates, and the top stays a unit quaternion and on its rows."""
    mod = get("double_pendulum_3d")
    q0, u0 = np.array(mod.initial_q), np.array(mod.initial_u)
    t_eval = np.linspace(0.0, 1.0, 11)
    a = engine("double_pendulum_3d", "tree").simulate(
        q0, u0, t_eval, integrator="DOP853", rtol=SIM_RTOL
    )
    b = engine("double_pendulum_3d", "free").simulate(
        q0, u0, t_eval, integrator="DOP853", rtol=SIM_RTOL
    )
    assert np.max(np.abs(a.q - b.q)) <= SIM_TOL and np.max(np.abs(a.u - b.u)) <= SIM_TOL
    assert np.max(b.violation) <= SIM_TOL
    for tr in (a, b):
        assert np.max(np.abs(tr.energy - tr.energy[0])) <= SIM_TOL
    top = get("top_cartesian")
    tr = engine("top_cartesian", "free").simulate(
        np.array(top.initial_q),
        np.array(top.initial_u),
        np.linspace(0.0, 0.2, 101),
        integrator="DOP853",
        rtol=SIM_RTOL,
    )
    nm = reference("top_cartesian", "dalembert")
    for q, u in zip(tr.q, tr.u, strict=True):
        pos, vel = nm.residuals(q, u)
        assert np.max(np.abs(pos)) <= SIM_TOL and np.max(np.abs(vel)) <= SIM_TOL


# ---- agreement table (not a test): python -m tests.test_engine_pinocchio [N] ------------
def agreement_table(n_states: int = 200) -> list[dict]:
    """Worst agreement per model x variant x formulation over n_states seeded
    states: max abs and max relative (per state, as scaled_error) errors of
    the accelerations and multipliers, and the most proximal iterations used."""
    rows = []
    for model_name, variant, formulation in (
        (m, v, f) for m, v in ALL_CASES for f in get(m).formulations
    ):
        em, nm = engine(model_name, variant), reference(model_name, formulation)
        w = {"acc_abs": 0.0, "acc_rel": 0.0, "lam_abs": 0.0, "lam_rel": 0.0, "iter": 0}
        for q, u in states(reference(model_name), n_states, seed=0):
            ref, out = nm.forward(q, u), em.forward(q, u)
            lam = out.multipliers
            if lam is None and model_name == "top_euler":  # the textbook value from raw
                lam = np.array(
                    [
                        out.raw[
                            "normalization_lambda_lagrange"
                            if formulation == "lagrange"
                            else "normalization_lambda_dalembert_kane"
                        ]
                    ]
                )
            w["acc_abs"] = max(
                w["acc_abs"], float(np.max(np.abs(out.accelerations - ref.accelerations)))
            )
            w["acc_rel"] = max(w["acc_rel"], scaled_error(out.accelerations, ref.accelerations))
            if lam is None:
                w["lam_abs"] = w["lam_rel"] = float("nan")  # no engine counterpart
            elif ref.multipliers.size:
                w["lam_abs"] = max(w["lam_abs"], float(np.max(np.abs(lam - ref.multipliers))))
                w["lam_rel"] = max(w["lam_rel"], scaled_error(lam, ref.multipliers))
            w["iter"] = max(w["iter"], int(out.raw["iterations"]))
        rows.append(
            {"model": model_name, "variant": variant or "-", "formulation": formulation, **w}
        )
    return rows


if __name__ == "__main__":  # pragma: no cover
    import sys
    import time

    n = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    t0 = time.perf_counter()
    rows = agreement_table(n)
    print(
        f"Pinocchio {pin.__version__} vs reference, {n} states per row "
        f"(rel = max|err| / max(max|ref|, 1); tolerances ACC_RTOL={ACC_RTOL}, "
        f"LAM_RTOL={LAM_RTOL})"
    )
    print(
        f"{'model':24s} {'variant':7s} {'formulation':11s} {'acc abs':>9s} {'acc rel':>9s} "
        f"{'lam abs':>9s} {'lam rel':>9s} {'iter':>4s}"
    )
    for r in rows:
        print(
            f"{r['model']:24s} {r['variant']:7s} {r['formulation']:11s} {r['acc_abs']:9.1e} "
            f"{r['acc_rel']:9.1e} {r['lam_abs']:9.1e} {r['lam_rel']:9.1e} {r['iter']:4d}"
        )
    print(f"({time.perf_counter() - t0:.1f} s)")


def test_quaternion_rate_is_the_quaternion_product():
    """ode.quat_rate, written out on floats, against the product it stands for,
    q (x) (omega, 0) / 2 in numpy's form (w omega + v x omega, -v . omega) / 2: equal to the
    last bit, as the floats follow the same operations (random unit and non-unit q)."""
    from crosscheck.engines.pinocchio.ode import quat_rate

    rng = np.random.default_rng(7)
    for _ in range(1000):
        q, omega = rng.standard_normal(4), 10.0 * rng.standard_normal(3)
        v, w = q[:3], q[3]
        numpy_form = 0.5 * np.concatenate([w * omega + np.cross(v, omega), [-(v @ omega)]])
        assert np.array_equal(quat_rate(q, omega), numpy_form)


def test_quaternion_rotation_is_eigens_matrix_row_by_row():
    """ode.quat_rotate on floats against Pinocchio's (Eigen's) rotation matrix applied to v one
    row at a time, in order: equal to the bit; numpy's R @ v may fuse multiply-adds, so it is
    held to a few units in the last place only."""
    from crosscheck.engines.pinocchio.engine_model import quat_to_R
    from crosscheck.engines.pinocchio.ode import quat_rotate

    rng = np.random.default_rng(11)
    for _ in range(1000):
        q, v = rng.standard_normal(4), 10.0 * rng.standard_normal(3)
        q /= np.linalg.norm(q)
        R = quat_to_R(q)
        in_order = [R[i, 0] * v[0] + R[i, 1] * v[1] + R[i, 2] * v[2] for i in range(3)]
        assert quat_rotate(q, v) == in_order
        assert np.allclose(quat_rotate(q, v), R @ v, rtol=0.0, atol=1e-14 * np.linalg.norm(v))


def test_trajectory_right_hand_side_keeps_quaternions_unit_and_maps_rates():
    """ode.normalized scales only the quaternions to unit length, and coordinate_rates gives
    q' = v on hinges, the quaternion product on ball joints, R v and the product on a free
    flyer (top_cartesian's free body, double_pendulum_3d's ball-joint tree)."""
    from crosscheck.engines.pinocchio.engine_model import quat_to_R
    from crosscheck.engines.pinocchio.ode import coordinate_rates, normalized, quat_rate

    rng = np.random.default_rng(5)
    for name, variant in (("top_cartesian", "free"), ("double_pendulum_3d", "tree")):
        em = engine(name, variant)
        lay = em.layout
        assert lay.quaternions, name
        qe = 1.5 * rng.standard_normal(em.model.nq)
        ve = rng.standard_normal(em.model.nv)
        qn = normalized(lay, qe)
        for iq in lay.quaternions:
            assert abs(np.linalg.norm(qn[iq : iq + 4]) - 1.0) <= 4e-16
            assert np.allclose(qn[iq : iq + 4], qe[iq : iq + 4] / np.linalg.norm(qe[iq : iq + 4]))
        rest = np.ones(em.model.nq, bool)
        for iq in lay.quaternions:
            rest[iq : iq + 4] = False
        assert np.array_equal(qn[rest], qe[rest])
        rates = np.array(coordinate_rates(lay, qn.tolist(), ve.tolist()))
        for iq, iv in lay.spherical:
            assert rates[iq : iq + 4].tolist() == quat_rate(qn[iq : iq + 4], ve[iv : iv + 3])
        for iq, iv in lay.free_flyer:
            R = quat_to_R(qn[iq + 3 : iq + 7])
            assert np.allclose(rates[iq : iq + 3], R @ ve[iv : iv + 3], rtol=0, atol=1e-14)
            assert rates[iq + 3 : iq + 7].tolist() == quat_rate(
                qn[iq + 3 : iq + 7], ve[iv + 3 : iv + 6]
            )
        for iq, iv, n in lay.plain:
            assert np.array_equal(rates[iq : iq + n], ve[iv : iv + n])


def test_right_hand_side_is_normalized_then_coordinate_rates_to_the_bit():
    """ode.right_hand_side (its call and its `into`, which LeanDOP853 fills its stages with)
    gives the same bits as coordinate_rates(normalized(q_e), v_e) and the accelerations at the
    normalized q_e (the test above holds what those two compute), hinges-only layouts on their
    shortcut q_e' = v_e included. Layouts: a free flyer, two ball joints, hinges only, and a
    hinge before a ball joint (built by hand)."""
    from crosscheck.engines.pinocchio.ode import (
        JointLayout,
        coordinate_rates,
        normalized,
        right_hand_side,
    )

    mixed = JointLayout(
        nq=5, nv=4, spherical=((1, 1),), free_flyer=(), plain=((0, 0, 1),), quaternions=(1,)
    )
    layouts = [
        engine(n, v).layout
        for n, v in (
            ("top_cartesian", "free"),
            ("double_pendulum_3d", "tree"),
            ("slider_crank", None),
        )
    ]
    rng = np.random.default_rng(17)
    for lay in [*layouts, mixed]:
        seen = []

        def accelerations(qe, ve, t, lay=lay, seen=seen):
            seen.append(np.array(qe))
            return np.sin(np.arange(lay.nv) + t) * ve.sum() + qe.sum()

        rhs = right_hand_side(lay, accelerations)
        for _ in range(50):
            y = 1.5 * rng.standard_normal(lay.nq + lay.nv)
            qn = normalized(lay, y[: lay.nq])
            expected = np.concatenate(
                [
                    coordinate_rates(lay, qn.tolist(), y[lay.nq :].tolist()),
                    accelerations(qn, y[lay.nq :], 0.3),
                ]
            )
            out = np.full(lay.nq + lay.nv, np.nan)
            rhs.into(0.3, y, out)
            assert np.array_equal(out, expected) and np.array_equal(rhs(0.3, y), expected)
            assert all(np.array_equal(s, qn) for s in seen[-3:])
