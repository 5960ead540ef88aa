"""What only the Exudyn adapter does, with the real Exudyn 1.13 (no mocks).

What every engine does (state maps, accelerations, multipliers and energy against the
reference, the fingerprint, the nominal maps, faults seen, the timing hook, refusals) is
tests/test_engine_contract.py. Here: what Exudyn declares, a mapped state on Exudyn's own
constraint manifold, the finite-difference floor of its plain answer (which the adapter's
extrapolation removes), the physical sign of the constraint forces on poses done by hand, the
gap of its initial-acceleration solve the knife edge works around, its two integrators'
settings and order, and its console output.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from crosscheck.engines.base import EngineUnsupported
from crosscheck.engines.building import resolve_params
from crosscheck.engines.exudyn import ExudynAdapter
from crosscheck.engines.exudyn.trajectory import ExudynIntegrationError
from reference.integrate.driver import simulate as reference_simulate
from reference.models import get
from reference.numeric.model import NumericModel
from tests.support import QUICK_MODELS, instances, representative, scaled_error, states

warnings.filterwarnings("ignore", category=DeprecationWarning)

ADAPTER = ExudynAdapter()
MODELS = representative(ADAPTER.models(), QUICK_MODELS)
# Exudyn's answer at its default relativeEpsilon 1e-7 (no extrapolation): measured up to
# 8.8e-7 scaled error over 100 sampled states per model (python -m
# crosscheck.engines.exudyn.measure --samples 100, docs/engines/exudyn.md); 1e-5 bounds it: the
# finite-difference floor, 1e4x above the extrapolated answer.
PLAIN_FLOOR = 1e-5
SAMPLES = 6


def test_declares_exact_multipliers_nonholonomic_rows_and_two_integrators():
    """What docs/engines/exudyn.md says Exudyn gives: exact multipliers (the extrapolated
    initial-acceleration solve), velocity-level rows (the knife edge), and its own two
    implicit integrators, fixed-step."""
    assert (ADAPTER.name, ADAPTER.distribution) == ("exudyn", "exudyn")
    caps = ADAPTER.capabilities
    assert caps.multipliers and caps.exact and caps.nonholonomic and not caps.soft_prediction
    assert set(caps.integrators) == {"generalized-alpha", "trapezoidal-index2"}
    assert not caps.adaptive_integrators


@pytest.mark.parametrize("name", MODELS)
def test_a_consistent_state_maps_onto_exudyns_constraint_manifold(name):
    """The mapped state satisfies Exudyn's own position and velocity rows (its residuals, at
    the state's time): the map puts the engine where the reference is, not only somewhere it
    can come back from."""
    for nm, t, q, u in instances(NumericModel(get(name)), 3, seed=3):
        em = ADAPTER.build(name, nm.params)
        em.time = t
        qe, ve = em.to_engine_state(q, u)
        # round-off of the rows evaluated on O(1) coordinates
        assert em.constraint_violation(qe, t) < 1e-12
        # the rates' rows carry |v| ~ 10 (the slider-crank's cranks): round-off, amplified
        assert em.velocity_violation(qe, ve, t) < 1e-9


@pytest.mark.parametrize("name", MODELS)
def test_plain_answer_is_within_the_finite_difference_floor(name):
    """Exudyn's own answer at its default step (raw plain_accelerations) is off the reference
    by its finite-difference error, which the adapter's extrapolated answer removes (the
    contract holds that one to EXUDYN_EXACT, whose reason names the measuring command)."""
    tol = ADAPTER.exact_tolerance(name)
    assert "crosscheck.engines.exudyn.measure" in tol.reason
    for nm, t, q, u in instances(NumericModel(get(name)), SAMPLES, seed=3):
        if name == "exercise_6_4" and abs(q[1]) > math.pi:
            continue  # a spring wound past a half turn: another state for Exudyn (the contract)
        ref = nm.forward(q, u, t)
        out = ADAPTER.build(name, nm.params).forward(q, u, t)
        assert scaled_error(out.raw["plain_accelerations"], ref.accelerations) < PLAIN_FLOOR


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
    nm, t, q, u = instances(NumericModel(get("slider_crank")), 1, seed=2)[0]
    params = nm.params
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


def test_initial_solve_drops_the_velocity_term_of_a_velocity_level_row():
    """Why the knife edge's one-state system declares its row at position level: with the
    honest velocity-level row (the trajectory system) Exudyn's initial solve returns lam = 0
    and accelerations off by O(1) at a turning state."""
    nm = NumericModel(get("knife_edge"))  # default parameters: no loads (P = T = 0)
    q, u = states(nm, 1, seed=5)[0]
    honest = type(ADAPTER.build("knife_edge"))("knife_edge", nm.params, simulation=True)
    qe, ve = honest.to_engine_state(q, u)
    ae, lam = honest._engine_answer(qe, ve, 0.0, 1e-7)
    ref = nm.forward(q, u)
    assert lam[0] == 0.0 and ref.multipliers[0] != 0.0
    assert scaled_error(honest._acc_to_reference(qe, ve, ae), ref.accelerations) > 1e-2


def test_simulate_takes_its_integrators_on_their_step_grid():
    """Exudyn's integrators are fixed-step: a timestep is required, the output times must lie
    on its grid, and an integrator it does not have is refused with the reason."""
    em = ADAPTER.build("pendulum_xy")
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
    nm, t, q, u = instances(NumericModel(get("exercise_6_4")), 1, seed=4)[0]
    out = ADAPTER.build("exercise_6_4", nm.params).forward(q, u, t)
    assert scaled_error(out.multipliers, out.raw["pin_force_momentum"]) < 1e-10


def test_frame_bar_bearing_moment_is_newton_euler():
    """Example 3: the bearing joint's moment row (lambda = -lam[4]) equals the reference's
    formula m d a_G . k + (I alpha + omega x I omega) . n1 evaluated on Exudyn's own
    accelerations."""
    nm, t, q, u = instances(NumericModel(get("frame_bar")), 1, seed=4)[0]
    out = ADAPTER.build("frame_bar", nm.params).forward(q, u, t)
    assert out.multipliers[0] == pytest.approx(out.raw["lambda_newton_euler"], rel=1e-9, abs=1e-12)


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
    """Exudyn's angles come back from rotations through atan2, in (-pi, pi]; along a
    trajectory they are unwrapped onto the initial state's branch (a turn through pi is a
    step of 2 pi - 6.1 rad, not -6.1), whichever branch that is."""
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
