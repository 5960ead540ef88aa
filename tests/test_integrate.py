"""reference.integrate.driver: each method keeps its stated guarantee; errors against exact or
minimal-coordinate references shrink at the integrator's order; energy and work balance hold;
bad starts and singular poses give clear errors.

Tolerances and why:
- PROJECTED: after a projection the residual is Gauss-Newton's stopping test, 4e-15 (1 + |q|),
  with |q| up to ~20 rad here: 1e-12 leaves a wide margin and is far below any integrator error.
- Unstabilized drift is bounded by DRIFT_GAIN x rtol over these horizons (measured 1-20x).
- Trajectory errors: DOP853's global error over a few seconds is ~1-100 x rtol x |y|.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import sympy as sp

from reference import NumericModel, models
from reference.errors import ModelInputError, OffManifoldError, SingularSystemError
from reference.integrate.driver import (
    METHODS,
    IntegrationTimeout,
    consistent_initial_state,
    simulate,
)
from reference.minimal import (
    TIGHT_RTOL,
    _ode_run,
    pendulum_exact,
    reference_final_state,
    slider_crank_one_coordinate,
)

PROJECTED = 1e-12
DRIFT_GAIN = 1e3
GLOBAL_ERROR_GAIN = 100.0


@pytest.fixture(scope="module")
def sc():
    return NumericModel(models.get("slider_crank"))


@pytest.fixture(scope="module")
def pxy():
    return NumericModel(models.get("pendulum_xy"))


@pytest.fixture(scope="module")
def sc_ref():
    return reference_final_state("slider_crank", 1.0)


def _start(nm):
    return nm.model.initial_q, nm.model.initial_u


# ---- the references themselves ----------------------------------------------------------------
def test_pendulum_exact_solution_matches_a_tight_theta_run():
    ang = NumericModel(models.get("pendulum_angle"))
    g, L = ang.params["g"], ang.params["L"]
    th0, w0 = ang.model.initial_q[0], ang.model.initial_u[0]
    for T in (0.7, 4.0, 10.0):
        th, w = pendulum_exact(th0, w0, g, L, T)
        y = _ode_run(ang, [th0, w0], T, TIGHT_RTOL, TIGHT_RTOL)
        # DOP853 at rtol 1e-13 over <= 10 s: global error ~1e-13..1e-12 (measured 2.6e-13)
        assert abs(y[0] - th) < 2e-12 and abs(y[1] - w) < 2e-12
    # the negative-rate branch of the phase
    th, w = pendulum_exact(th0, -w0, g, L, 1.3)
    y = _ode_run(ang, [th0, -w0], 1.3, TIGHT_RTOL, TIGHT_RTOL)
    assert abs(y[0] - th) < 2e-12 and abs(y[1] - w) < 2e-12


def test_one_coordinate_slider_crank_is_example_2b(sc):
    one = NumericModel(slider_crank_one_coordinate())
    rng = np.random.default_rng(4)
    l1, l2 = sc.params["l1"], sc.params["l2"]
    for _ in range(5):
        th1, w1 = rng.uniform(-math.pi, math.pi), rng.uniform(-9, 9)
        th2 = math.asin(-l1 * math.sin(th1) / l2)
        w2 = -l1 * math.cos(th1) * w1 / (l2 * math.cos(th2))
        a2 = sc.forward([th1, th2], [w1, w2]).accelerations[0]
        a1 = one.forward([th1], [w1]).accelerations[0]
        assert abs(a1 - a2) <= 1e-11 * max(1.0, abs(a2))


def test_reference_states_its_accuracy(sc_ref):
    # the slider-crank reduction's own error estimate is far below the 1e-8 target it judges
    assert 0 < sc_ref.accuracy < 1e-9
    assert "one-coordinate" in sc_ref.kind
    r = reference_final_state("pendulum_xy", 10.0)
    assert r.accuracy < 1e-11 and "elliptic" in r.kind


# ---- constraint guarantees -----------------------------------------------------------------------
@pytest.mark.parametrize("name", ["pendulum_xy", "slider_crank", "slider_crank_split", "top_euler"])
@pytest.mark.parametrize("method", ["projection", "nullspace"])
def test_projection_and_nullspace_hold_the_constraints_at_round_off(name, method):
    nm = NumericModel(models.get(name))
    # a loose tolerance: the integrator's error is ~1e-5, the constraints still hold to 1e-12
    tr = simulate(nm, *_start(nm), 1.0, method, rtol=1e-6, atol=1e-6, energy="none")
    r = tr.max_residual()
    assert r["position"] <= PROJECTED and r["velocity"] <= PROJECTED, r


def test_index1_drift_grows_with_the_tolerance(sc):
    res = {}
    for tol in (1e-6, 1e-8, 1e-10):
        tr = simulate(sc, *_start(sc), 2.0, "index1", rtol=tol, atol=tol, energy="none")
        res[tol] = max(tr.max_residual().values())
        assert res[tol] <= DRIFT_GAIN * tol  # drift follows the integrator's error ...
    assert res[1e-6] > 10 * res[1e-8] > 100 * res[1e-10]  # ... and shrinks with it
    assert res[1e-10] > 1e-13  # it is real drift, not round-off


def test_baumgarte_keeps_the_residual_bounded_where_index1_drifts(pxy):
    """Over 60 s the unstabilized residual grows (quadratic drift in x^2 + y^2); Baumgarte's
    stays at its tolerance-dependent level (the constraint error obeys a damped oscillator)."""
    T = 60.0
    ib = simulate(pxy, *_start(pxy), T, "index1", rtol=1e-7, atol=1e-7)
    bg = simulate(pxy, *_start(pxy), T, "baumgarte", rtol=1e-7, atol=1e-7)
    P_i, _ = ib.residuals()
    P_b, _ = bg.residuals()
    first_i = np.max(np.abs(P_i[ib.t <= T / 6]))
    last_i = np.max(np.abs(P_i[ib.t >= 5 * T / 6]))
    first_b = np.max(np.abs(P_b[bg.t <= T / 6]))
    last_b = np.max(np.abs(P_b[bg.t >= 5 * T / 6]))
    assert last_i > 5 * first_i  # drift grows
    assert last_b < 3 * max(first_b, 1e-14)  # bounded
    assert max(bg.max_residual().values()) < max(ib.max_residual().values()) / 10
    assert bg.settings["alpha"] == 10.0 and bg.settings["beta"] == 10.0


# ---- accuracy and order --------------------------------------------------------------------------
@pytest.mark.parametrize("method", METHODS)
def test_error_against_the_one_coordinate_reference_follows_the_tolerance(sc, sc_ref, method):
    errs = {}
    for tol in (1e-6, 1e-10):
        tr = simulate(sc, *_start(sc), 1.0, method, rtol=tol, atol=tol, energy="none")
        errs[tol] = float(np.max(np.abs(tr.final_state - sc_ref.state)))
        scale = 1.0 + float(np.max(np.abs(sc_ref.state)))
        assert errs[tol] <= GLOBAL_ERROR_GAIN * tol * scale, (tol, errs[tol])
    # the error follows the tolerance (at least 10x over 4 decades: the reduced ODE of nullspace
    # has a 2-component state whose RMS error norm weighs theta1 ~ 10 rad, measured 50x)
    assert errs[1e-6] > 10 * errs[1e-10]


@pytest.mark.parametrize("method", ["index1", "projection", "nullspace"])
def test_fixed_step_convergence_order_is_dop853s(pxy, method):
    """With steps forced to h (rtol = atol = 1e3 accepts every step; first_step = max_step = h)
    the error against the exact elliptic solution falls like h^8: projection after every step and
    the partitioned ODE keep the base method's order (Eich 1993). At h = 0.2 .. 0.05
    (omega0 h = 0.7 .. 0.18) the observed order is 7.0-8.4 (pre-asymptotic from below)."""
    T = 2.0
    ref = reference_final_state("pendulum_xy", T)
    errs = []
    for h in (0.2, 0.1, 0.05):
        tr = simulate(
            pxy,
            *_start(pxy),
            T,
            method,
            rtol=1e3,
            atol=1e3,
            first_step=h,
            max_step=h,
            energy="none",
        )
        assert abs(tr.nsteps - round(T / h)) <= 1  # (+1: a round-off sliver at t_end)
        errs.append(float(np.max(np.abs(tr.final_state - ref.state))))
    orders = [math.log2(errs[i] / errs[i + 1]) for i in range(2)]
    assert all(6.5 < p < 9.5 for p in orders), orders


def test_dense_output_at_t_eval_is_projected(sc, sc_ref):
    t_eval = np.linspace(0.0, 1.0, 11)
    tr = simulate(
        sc, *_start(sc), 1.0, "projection", rtol=1e-10, atol=1e-10, t_eval=t_eval, energy="none"
    )
    assert np.allclose(tr.t, t_eval)
    assert max(tr.max_residual().values()) <= PROJECTED
    assert np.max(np.abs(tr.final_state - sc_ref.state)) < 1e-7


# ---- energy -------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["pendulum_xy", "top_euler", "double_pendulum_3d"])
def test_energy_is_conserved_over_a_short_run(name):
    nm = NumericModel(models.get(name))
    assert nm.model.energy_conserved
    for method in ("projection", "index1"):
        tr = simulate(nm, *_start(nm), 1.0, method, rtol=1e-10, atol=1e-10)
        # relative drift ~ the integrator's error (measured 1e-12 .. 5e-10)
        assert tr.energy_drift() < 1e-8, (method, tr.energy_drift())


def test_work_energy_balance_with_a_torque_and_without_bookkeeping():
    nm = NumericModel(models.get("slider_crank"), params={"T": 1.7})
    assert not nm.model.energy_conserved
    tr = simulate(nm, *_start(nm), 1.0, "projection", rtol=1e-10, atol=1e-10)
    E = tr.energy()
    assert abs(tr.work[-1]) > 1.0 and abs(E[-1] - E[0]) > 1.0  # the torque does real work
    assert tr.energy_drift() < 1e-9  # E - E0 = W
    none = simulate(nm, *_start(nm), 1.0, "projection", rtol=1e-10, atol=1e-10, energy="none")
    assert none.energy_drift() is None and none.work is None
    # W is not error-controlled and the other tolerances are rescaled: the same steps
    assert none.nsteps == tr.nsteps
    assert np.max(np.abs(none.final_state - tr.final_state)) < 1e-11


def test_work_of_a_rheonomic_constraint_enters_the_balance():
    nm = NumericModel(models.get("pendulum_moving_support"))
    tr = simulate(nm, *_start(nm), 1.0, "projection", rtol=1e-10, atol=1e-10)
    E = tr.energy()
    assert np.max(np.abs(E - E[0])) > 1e-3  # the moving support pumps energy in and out
    assert tr.energy_drift() < 1e-8


# ---- starts, bounds, refusals ----------------------------------------------------------------
def test_inconsistent_start_is_projected_and_reported(pxy):
    q0 = np.asarray(pxy.model.initial_q) * 1.01
    u0 = np.asarray(pxy.model.initial_u) + 0.05
    tr = simulate(pxy, q0, u0, 0.5, "projection")
    assert 1e-3 < tr.stats["ic_correction"] < 0.1
    assert max(tr.max_residual().values()) <= PROJECTED
    with pytest.raises(OffManifoldError, match="far off the constraint manifold"):
        simulate(pxy, q0, u0, 0.5, "projection", max_correction=1e-6)


def test_start_without_a_consistent_state_is_refused():
    """x^2 + y^2 = L^2 and x = 2 L have no common point: the projection cannot succeed."""
    base = models.get("pendulum_xy")
    x, _y = base.coordinates
    L = sp.Symbol("L", real=True)
    bad = dataclasses.replace(
        base,
        name="pendulum_xy_unreachable",
        configuration_constraints=(base.configuration_constraints[0], x - 2 * L),
        constraint_names=("rod", "wall"),
    )
    nm = NumericModel(bad)
    with pytest.raises(OffManifoldError):
        consistent_initial_state(nm, base.initial_q, base.initial_u)


def test_singular_pose_mid_run_raises_with_the_time():
    P = {"l1": 0.3, "l2": 0.3, "r2": 0.15, "I_G2": 2.0 * 0.09 / 12}
    nm = NumericModel(models.get("slider_crank"), params=P)
    with pytest.raises(SingularSystemError, match=r"at t = 0\.\d+.*singular"):
        simulate(nm, [0.5, -0.5], [8.0, -8.0], 1.0, "index1", rtol=1e-12, atol=1e-12, energy="none")


def test_passing_close_to_a_singular_pose_leaves_a_warning():
    P = {"l1": 0.3, "l2": 0.3, "r2": 0.15, "I_G2": 2.0 * 0.09 / 12}
    nm = NumericModel(models.get("slider_crank"), params=P)
    # measured: this run steps across theta1 = pi/2 with a pivot ratio of 1e-11 and changes
    # branch; the run completes, so the warning is what keeps it from being silent
    tr = simulate(nm, [0.5, -0.5], [8.0, -8.0], 1.0, "index1", rtol=1e-8, atol=1e-8, energy="none")
    assert tr.stats["min_pivot_ratio"] < 1e-8
    assert tr.warnings and "singular pose" in tr.warnings[0]
    calm = simulate(
        NumericModel(models.get("slider_crank")),
        [0.5, -0.19],
        [8.0, -3.1],
        0.2,
        "index1",
        energy="none",
    )
    assert not calm.warnings


def test_bounds_stop_a_run_instead_of_hanging(sc):
    with pytest.raises(IntegrationTimeout, match="max_steps"):
        simulate(sc, *_start(sc), 10.0, "projection", rtol=1e-12, atol=1e-12, max_steps=5)


def test_bad_settings_name_the_valid_ones(sc):
    with pytest.raises(ModelInputError, match="valid: index1, baumgarte, projection, nullspace"):
        simulate(sc, *_start(sc), 1.0, "magic")
    with pytest.raises(ModelInputError, match="multistep"):
        simulate(sc, *_start(sc), 1.0, "projection", integrator="BDF")
    with pytest.raises(ModelInputError, match="Baumgarte gains"):
        simulate(sc, *_start(sc), 1.0, "baumgarte", alpha=-1.0)


@pytest.mark.parametrize("integrator", ["RK45", "Radau"])
def test_projection_with_other_one_step_integrators(sc, sc_ref, integrator):
    tr = simulate(
        sc,
        *_start(sc),
        1.0,
        "projection",
        rtol=1e-9,
        atol=1e-9,
        integrator=integrator,
        energy="none",
    )
    assert max(tr.max_residual().values()) <= PROJECTED
    # A one-step method that keeps each step's local error under rtol |y| ends a short
    # non-stiff run within C rtol |y| of the exact solution (tolerance proportionality);
    # measured C = 0.3..4.7 here over rtol 1e-7..1e-11 for RK45, Radau and DOP853 (against
    # rtol 1e-13), so C = 10 is the bound: a dropped term or a wrong order fails it.
    scale = max(1.0, float(np.max(np.abs(sc_ref.state))))
    assert np.max(np.abs(tr.final_state - sc_ref.state)) <= 10 * 1e-9 * scale


def test_nullspace_repartitions_when_the_dependent_block_degrades():
    """Euler parameters of a spinning top: the best dependent parameter changes as the top turns;
    every restart keeps the constraints at round-off."""
    nm = NumericModel(models.get("top_euler"))
    tr = simulate(nm, *_start(nm), 0.5, "nullspace", rtol=1e-8, atol=1e-8, energy="none")
    assert tr.stats["partitions"] > 1
    assert max(tr.max_residual().values()) <= PROJECTED
    ref = simulate(nm, *_start(nm), 0.5, "projection", rtol=1e-12, atol=1e-12, energy="none")
    # Tolerance proportionality as above, with the top's spin amplifying the phase error: at
    # ~60 rad/s for 0.5 s (30 rad of spin) the measured C is 35..74 over rtol 1e-6..1e-10
    # (the restarts at each repartition add local errors), so C = 200.
    scale = max(1.0, float(np.max(np.abs(ref.final_state))))
    assert np.max(np.abs(tr.final_state - ref.final_state)) <= 200 * 1e-8 * scale


def test_rank_monitor_ignores_rows_that_are_dependent_everywhere():
    """A planar four-bar closed by a tilted 3-D connect has a dependent row at every pose:
    det(A A^T) is 0 with a round-off sign, which read as a rank crossing at about half of the
    steps. The monitor watches the rows independent at the start, so a smooth run reports
    none (the slider-crank's genuine crossings are tests/test_stress.py's)."""
    from pathlib import Path

    from crosscheck.user_models import load_model_file, register_all

    path = Path(__file__).parent / "data" / "fourbar_tilted.xml"
    (name,) = register_all(load_model_file(path))
    nm = NumericModel(models.get(name))
    assert nm.redundant
    tr = simulate(
        nm, nm.model.initial_q, nm.model.initial_u, 2.0, "projection", rtol=1e-10, atol=1e-10
    )
    assert tr.stats.get("rank_crossings_t", []) == []


@pytest.mark.parametrize(
    "method,integrator",
    [("projection", i) for i in ("DOP853", "RK45", "RK23", "Radau")]
    + [("index1", i) for i in ("BDF", "LSODA")],
)
def test_every_integrator_runs_with_the_work_integral(method, integrator):
    """scipy's integrators with the default energy setting on a model whose energy is not
    conserved (the work W of a moving support is integrated beside the state): Radau took a
    vector rtol badly. The work-energy balance holds to 1e3 rtol over the 0.5 s (each step's
    local error is within rtol; measured <= 6e-10 at rtol 1e-9, BDF's the largest)."""
    from reference.integrate.driver import simulate

    nm = NumericModel(models.get("pendulum_moving_support"))
    q0, u0 = nm.model.initial_q, nm.model.initial_u
    tr = simulate(nm, q0, u0, 0.5, method, rtol=1e-9, atol=1e-11, integrator=integrator)
    assert tr.work is not None and tr.t[-1] == pytest.approx(0.5)
    assert tr.energy_drift() <= 1e3 * 1e-9
