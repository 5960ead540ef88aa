"""The Exudyn adapter against the reference, with the real Exudyn 1.13 (no mocks).

Checked model by model: the state map both ways, accelerations and multipliers against the
reference's KKT solve at random consistent states and parameters (crosscheck.checks.sampling), the
finite-difference floor of Exudyn's plain answer and its removal, the physical sign of the
constraint forces on poses done by hand, energy, that a 1e-6 parameter fault is caught, the
two gaps of Exudyn's initial-acceleration solve the special models work around, short
trajectories against the reference, and the unsupported models' reasons.
"""

from __future__ import annotations

import math
import re
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest

from crosscheck.checks.instantaneous import build
from crosscheck.checks.perturb import check_perturb_changes
from crosscheck.checks.sampling import random_consistent_state, random_params
from crosscheck.engines.base import EngineAdapter, EngineUnsupported
from crosscheck.engines.building import resolve_params
from crosscheck.engines.exudyn import ExudynAdapter
from crosscheck.engines.exudyn.trajectory import ExudynIntegrationError
from reference.errors import ModelInputError
from reference.integrate.driver import simulate as reference_simulate
from reference.models import get, names
from reference.numeric.model import NumericModel

warnings.filterwarnings("ignore", category=DeprecationWarning)

ADAPTER = ExudynAdapter()
MODELS = ADAPTER.models()
# reference -> engine -> reference: sines, cosines and one subtraction of pi, a few ulps
STATE_MAP_RTOL = 1e-13
# Exudyn's answer at its default relativeEpsilon 1e-7 (no extrapolation): measured up to
# 8.8e-7 scaled error over 100 sampled states per model (python -m
# crosscheck.engines.exudyn.measure --samples 100, docs/engines/exudyn.md); 1e-5 bounds it: the
# finite-difference floor, 1e4x above the extrapolated answer.
PLAIN_FLOOR = 1e-5
# Energy: K from Exudyn's mass matrix, V from its node positions; round-off only.
ENERGY_RTOL = 1e-11
SAMPLES = 6


def scaled_error(value, ref) -> float:
    value, ref = np.asarray(value, float), np.asarray(ref, float)
    if ref.size == 0:
        return 0.0
    return float(np.max(np.abs(value - ref)) / max(float(np.max(np.abs(ref))), 1.0))


def _instances(name: str, n: int, seed: int = 3):
    """(params, t, q, u) drawn as the sweeps draw them (crosscheck.checks.sampling)."""
    m = get(name)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        params = random_params(m, rng)
        nm = NumericModel(m, params=params)
        t = float(rng.uniform(0.0, 2.0))
        q, u = random_consistent_state(nm, rng, t=t)
        out.append((params, nm, t, q, u))
    return out


def test_adapter_contract():
    assert isinstance(ADAPTER, EngineAdapter)
    assert (ADAPTER.name, ADAPTER.distribution) == ("exudyn", "exudyn")
    caps = ADAPTER.capabilities
    assert caps.multipliers and caps.exact and caps.nonholonomic
    assert set(caps.integrators) == {"generalized-alpha", "trapezoidal-index2"}
    project = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())
    eps = project["project"]["entry-points"]["crosscheck.engines"]
    assert eps["exudyn"] == "crosscheck.engines.exudyn:ExudynAdapter"


def test_every_model_supported_or_refused_with_reason():
    every = set(names())
    refused = ADAPTER.unsupported()
    assert set(MODELS) | set(refused) == every
    assert not set(MODELS) & set(refused)
    for name, reason in refused.items():
        assert len(reason) > 20
        with pytest.raises(EngineUnsupported, match=re.escape(reason[:30])):
            ADAPTER.build(name)
    with pytest.raises(EngineUnsupported, match="no model 'no_such_model'"):
        ADAPTER.build("no_such_model")
    with pytest.raises(EngineUnsupported, match="single variant"):
        ADAPTER.build("pendulum_xy", variant="tree")


@pytest.mark.parametrize("name", MODELS)
def test_state_round_trip(name):
    for params, _nm, t, q, u in _instances(name, 3):
        em = ADAPTER.build(name, params)
        em.time = t
        qe, ve = em.to_engine_state(q, u)
        q2, u2 = em.from_engine_state(qe, ve)
        assert scaled_error(q2, q) < STATE_MAP_RTOL
        assert scaled_error(u2, u) < STATE_MAP_RTOL
        # a consistent reference state maps onto the engine's constraint manifold
        assert em.constraint_violation(qe, t) < 1e-12
        assert em.velocity_violation(qe, ve, t) < 1e-9


@pytest.mark.parametrize("name", MODELS)
def test_forward_against_reference(name):
    tol = ADAPTER.exact_tolerance(name)
    assert tol.reason and "crosscheck" in tol.reason  # the command that measures it
    for params, nm, t, q, u in _instances(name, SAMPLES):
        ref = nm.forward(q, u, t)
        out = ADAPTER.build(name, params).forward(q, u, t)
        assert scaled_error(out.accelerations, ref.accelerations) < tol.value
        if len(ref.multipliers):
            assert out.multipliers is not None
            assert scaled_error(out.multipliers, ref.multipliers) < tol.value
        # Exudyn's own answer at its default step: the finite-difference floor
        plain = scaled_error(out.raw["plain_accelerations"], ref.accelerations)
        assert plain < PLAIN_FLOOR


@pytest.mark.parametrize("name", ["pendulum_xy", "pendulum_angle"])
def test_rod_tension_at_rest_is_the_weight(name):
    """Hanging at rest (Y down): the rod carries m g, and Example 1(b)'s lambda = -T/L."""
    em = ADAPTER.build(name)
    m, L, g = em.params["m"], em.params["L"], em.params["g"]
    q = [0.0, L] if name == "pendulum_xy" else [0.0]
    out = em.forward(q, np.zeros(len(q)))
    assert out.raw["rod_tension"] == pytest.approx(m * g, rel=1e-10)
    if name == "pendulum_xy":
        assert out.multipliers[0] == pytest.approx(-m * g / L, rel=1e-10)


def test_slider_crank_guide_force_balances_the_slider():
    """The slider's vertical balance (y_C'' = 0): guide force N, weight -m3 g and the hinge C's
    force on it, -lam_C (items.hinge_2d's sign, checked on the pendulum), so
    N = m3 g + lam_C,y; forward's lambda must be that N."""
    params, _, t, q, u = _instances("slider_crank", 1, seed=2)[0]
    em = ADAPTER.build("slider_crank", params)
    out = em.forward(q, u, t)
    lam_c_y = out.raw["engine_multipliers"][5]
    assert out.multipliers[0] == pytest.approx(params["m3"] * params["g"] + lam_c_y, rel=1e-12)


def test_knife_edge_lateral_force_sign():
    """Moving straight ahead (v along the blade) and turning at w with w' from the reference:
    lambda = m (v w + a w'), the ground's force on the blade along n (the module docstring)."""
    nm = NumericModel(get("knife_edge"))
    em = ADAPTER.build("knife_edge")
    th, v, w = 0.4, 1.3, 0.7
    q, u = [0.1, -0.2, th], [v * math.cos(th), v * math.sin(th), w]
    out = em.forward(q, u)
    p = em.params
    wd = out.accelerations[2]
    assert out.multipliers[0] == pytest.approx(p["m"] * (v * w + p["a"] * wd), rel=1e-9)
    assert scaled_error(out.multipliers, nm.forward(q, u).multipliers) < 1e-9


@pytest.mark.parametrize("name", MODELS)
def test_energy(name):
    for params, nm, t, q, u in _instances(name, 2):
        em = ADAPTER.build(name, params)
        em.time = t
        K, V = em.energy(q, u)
        K_ref, V_ref = nm.energy(q, u, t)
        assert abs(K - K_ref) <= ENERGY_RTOL * max(1.0, abs(K_ref))
        assert abs(V - V_ref) <= ENERGY_RTOL * max(1.0, abs(V_ref))


@pytest.mark.parametrize(
    "name,param", [("slider_crank", "m2"), ("knife_edge", "I_G"), ("pendulum_moving_support", "L")]
)
def test_parameter_fault_is_caught(name, param):
    """The engine built with one parameter 1e-6 off disagrees beyond the tolerance."""
    tol = ADAPTER.exact_tolerance(name).value
    params, nm, t, q, u = _instances(name, 1, seed=11)[0]
    ref = nm.forward(q, u, t)
    bad = dict(params, **{param: params[param] * (1 + 1e-6)})
    out = ADAPTER.build(name, bad).forward(q, u, t)
    err = max(
        scaled_error(out.accelerations, ref.accelerations),
        scaled_error(out.multipliers, ref.multipliers),
    )
    assert err > 10 * tol


def test_initial_solve_drops_the_velocity_term_of_a_velocity_level_row():
    """Why the knife edge's one-state system declares its row at position level: with the
    honest velocity-level row (the trajectory system) Exudyn's initial solve returns lam = 0
    and accelerations off by O(1) at a turning state."""
    m = get("knife_edge")
    nm = NumericModel(m)  # default parameters: no loads (P = T = 0)
    q, u = random_consistent_state(nm, np.random.default_rng(5))
    honest = type(ADAPTER.build("knife_edge"))("knife_edge", nm.params, simulation=True)
    qe, ve = honest.to_engine_state(q, u)
    ae, lam = honest._engine_answer(qe, ve, 0.0, 1e-7)
    ref = nm.forward(q, u)
    assert lam[0] == 0.0 and ref.multipliers[0] != 0.0
    assert scaled_error(honest._acc_to_reference(qe, ve, ae), ref.accelerations) > 1e-2


def test_timed_forward_is_forwards_engine_call():
    params, _, t, q, u = _instances("slider_crank", 1)[0]
    em = ADAPTER.build("slider_crank", params)
    ae, lam = em.timed_forward(q, u, t)()
    out = em.forward(q, u, t)
    assert np.array_equal(ae, out.raw["engine_accelerations"])
    assert np.array_equal(lam, out.raw["engine_multipliers"])


def test_bad_input_is_refused():
    em = ADAPTER.build("pendulum_xy")
    with pytest.raises(ModelInputError):
        em.forward([0.1], [0.0, 0.0])
    with pytest.raises(ModelInputError):
        em.forward([np.nan, 0.8], [0.0, 0.0])
    m = get("pendulum_xy")
    with pytest.raises(EngineUnsupported, match="step grid"):
        em.simulate(
            m.initial_q, m.initial_u, [0.0, 0.0105], integrator="generalized-alpha", timestep=1e-3
        )
    with pytest.raises(EngineUnsupported, match="timestep"):
        em.simulate(m.initial_q, m.initial_u, [0.0, 0.1], integrator="generalized-alpha")
    with pytest.raises(EngineUnsupported, match="unknown integrator"):
        em.simulate(m.initial_q, m.initial_u, [0.0, 0.1], integrator="RK4", timestep=1e-3)


@pytest.mark.parametrize(
    "name",
    [
        "pendulum_xy",
        "slider_crank",
        "knife_edge",
        "pendulum_moving_support",
        "double_pendulum_3d",
        "exercise_6_1",
        "exercise_6_4",
        "frame_bar",
    ],
)
@pytest.mark.parametrize("integrator", ["generalized-alpha", "trapezoidal-index2"])
def test_short_trajectory_against_reference(name, integrator):
    """0.3 s from the model's initial state: both of Exudyn's integrators are second order
    (the error falls ~4x when the step halves) and close to the reference."""
    m = get(name)
    nm = NumericModel(m)
    t_eval = np.linspace(0.0, 0.3, 7)
    ref = reference_simulate(
        nm, m.initial_q, m.initial_u, 0.3, "projection", rtol=1e-11, atol=1e-11, t_eval=t_eval
    )
    em = ADAPTER.build(name)
    errs = []
    for h in (2e-3, 1e-3):
        tr = em.simulate(m.initial_q, m.initial_u, t_eval, integrator=integrator, timestep=h)
        assert tr.q.shape == ref.q.shape and tr.steps == round(0.3 / h)
        errs.append(float(np.max(np.abs(tr.q - ref.q))))
    assert errs[1] < 1e-3
    assert 3.0 < errs[0] / errs[1] < 5.0


def test_exercise_6_4_pin_force_is_the_bars_momentum_balance():
    """The pin joint's force mapped to disk axes equals m (a_G - g) of the bar from Exudyn's
    own accelerations (the pin is the only force on the bar besides gravity)."""
    params, _, t, q, u = _instances("exercise_6_4", 1, seed=4)[0]
    out = ADAPTER.build("exercise_6_4", params).forward(q, u, t)
    assert scaled_error(out.multipliers, out.raw["pin_force_momentum"]) < 1e-10


def test_frame_bar_bearing_moment_is_newton_euler():
    """Example 3: the bearing joint's moment row (lambda = -lam[4]) equals the reference's
    formula m d a_G . k + (I alpha + omega x I omega) . n1 evaluated on Exudyn's own
    accelerations."""
    params, _, t, q, u = _instances("frame_bar", 1, seed=4)[0]
    out = ADAPTER.build("frame_bar", params).forward(q, u, t)
    assert out.multipliers[0] == pytest.approx(out.raw["lambda_newton_euler"], rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("name", MODELS)
def test_fingerprint_follows_the_physics(name):
    """Same parameters: same digest; a nonzero parameter changed by 1e-6: a different digest
    (every nonzero parameter of every model is in its built system)."""
    params = random_params(get(name), np.random.default_rng(1))
    a, b = ADAPTER.build(name, params), ADAPTER.build(name, params)
    assert a.fingerprint() == b.fingerprint()
    for key in (k for k, v in params.items() if v != 0.0):
        changed = ADAPTER.build(name, dict(params, **{key: params[key] * (1 + 1e-6)}))
        assert changed.fingerprint() != a.fingerprint(), key


def test_fingerprint_reads_the_built_system():
    """The digest is of the system Exudyn holds (read back item by item), not of the
    parameter dict: an entry the system does not use leaves it unchanged; a mass changed in
    the built system changes it."""
    params = resolve_params("slider_crank", None)
    em = ADAPTER.build("slider_crank", params)
    before = em.fingerprint()
    assert type(em)("slider_crank", dict(params, unused=1.0)).fingerprint() == before
    body = next(
        i for i in range(em.mbs.systemData.NumberOfObjects()) if "mass" in em.mbs.GetObject(i)
    )
    em.mbs.ModifyObject(body, {"mass": em.mbs.GetObject(body)["mass"] * (1 + 1e-12)})
    assert em.fingerprint() != before


def test_perturbation_that_changes_nothing_is_refused():
    """--perturb exudyn:T=... on the slider-crank (T = 0: no torque load in the system) is
    refused with the reason; exudyn:m2=1e-6 changes the rod's mass and is accepted."""
    with pytest.raises(ModelInputError, match="does not change exudyn's model"):
        check_perturb_changes(["slider_crank"], ["exudyn"], {"exudyn": {"T": 1e-6}})
    check_perturb_changes(["slider_crank"], ["exudyn"], {"exudyn": {"m2": 1e-6}})


@pytest.mark.parametrize(
    "name,param",
    [
        ("pendulum_angle", "L"),
        ("knife_edge", "a"),
        ("pendulum_moving_support", "a"),
        ("slider_crank", "l2"),
        ("top_euler", "L"),
    ],
)
def test_maps_use_the_nominal_geometry(name, param):
    """A perturbation changes the engine's physics only: with a length 1e-3 off, the state
    maps are the nominal model's (the same engine state, the exact round trip) while the
    answer differs."""
    params, _nm, t, q, u = _instances(name, 1, seed=7)[0]
    bad = dict(params, **{param: params[param] * (1 + 1e-3)})
    nominal, perturbed = (
        build(ADAPTER, name, params, None),
        build(ADAPTER, name, bad, None, nominal=params),
    )
    nominal.time = perturbed.time = t
    qe, ve = perturbed.to_engine_state(q, u)
    qn, vn = nominal.to_engine_state(q, u)
    assert np.array_equal(qe, qn) and np.array_equal(ve, vn)
    q2, u2 = perturbed.from_engine_state(qe, ve)
    assert scaled_error(q2, q) < STATE_MAP_RTOL and scaled_error(u2, u) < STATE_MAP_RTOL
    assert (
        scaled_error(
            perturbed.forward(q, u, t).accelerations, nominal.forward(q, u, t).accelerations
        )
        > 1e-6
    )


def test_solver_output_is_silenced_and_failures_keep_their_reason(capfd, monkeypatch):
    """Exudyn's console writing is off during a trajectory: neither its "DYNAMIC SOLVER
    FAILED" banner nor its memory-allocation note reaches stdout, and a failure still raises
    with the solver's reason."""
    import exudyn.solver

    m = get("slider_crank")
    em = ADAPTER.build("slider_crank")
    with pytest.raises(ExudynIntegrationError, match=r"did not converge .* at t = "):
        em.simulate(
            m.initial_q, m.initial_u, [0.0, 0.5], integrator="generalized-alpha", timestep=0.25
        )
    # Exudyn notes allocations per step above a threshold; at 1 it fires on any run with
    # Python user functions (the knife edge's row)
    monkeypatch.setattr(exudyn.solver, "solverCheckMemoryAllocationsThreshold", 1)
    k = get("knife_edge")
    tr = ADAPTER.build("knife_edge").simulate(
        k.initial_q, k.initial_u, [0.0, 0.01], integrator="generalized-alpha", timestep=1e-3
    )
    assert tr.failure is None
    out = capfd.readouterr().out
    assert "SOLVER FAILED" not in out and "memory allocations" not in out


def test_angles_read_with_atan2_are_continuous_along_a_trajectory():
    from crosscheck.engines.exudyn.trajectory import _continuous_angles

    wrapped = np.array([[3.0, 0.1], [-3.1, 0.2], [-2.9, 0.3]])  # angle 0 crosses +pi
    out = _continuous_angles(wrapped.copy(), np.array([3.0 - 2 * np.pi * 0, 0.1]), (0,))
    assert np.allclose(np.diff(out[:, 0]), [2 * np.pi - 6.1, 0.2])
    shifted = _continuous_angles(wrapped.copy(), np.array([3.0 + 2 * np.pi, 0.1]), (0,))
    assert shifted[0, 0] == pytest.approx(3.0 + 2 * np.pi)


def test_measure_prints_the_figures_exudyn_exact_rests_on(capsys):
    """The measurement EXUDYN_EXACT's reason cites, on two states: the extrapolated answer is
    within the tolerance and closer to the reference than Exudyn's plain answer."""
    from crosscheck.engines.exudyn import measure
    from crosscheck.engines.exudyn.adapter import EXUDYN_EXACT

    measure.main(["--samples", "2", "pendulum_xy"])
    row = capsys.readouterr().out.splitlines()[1].split()
    acc, lam, plain_acc, plain_lam = map(float, row[1:5])
    assert row[0] == "pendulum_xy"
    assert max(acc, lam) <= EXUDYN_EXACT.value and max(acc, lam) < max(plain_acc, plain_lam)
