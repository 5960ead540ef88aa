"""The blind spots of the suite, each closed and held here."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from crosscheck.checks.sampling import physical, random_params
from reference import models


@pytest.mark.parametrize("name", ["double_pendulum_3d", "frame_bar", "top_euler"])
def test_sampler_draws_inertias_apart_and_physical(name):
    """No two inertias of a draw keep one common factor (a swapped axis would cancel), and
    every body's principal inertias satisfy the triangle inequalities."""
    model = models.get(name)
    defaults = {p.name: p.default for p in model.parameters}
    inertias = [p.name for p in model.parameters if p.unit == "kg m^2"]
    rng = np.random.default_rng(3)
    for _ in range(50):
        params = random_params(model, rng)
        factors = {round(params[n] / defaults[n], 12) for n in inertias}
        assert len(factors) == len(inertias), factors
        for body in model.bodies:
            diag = [body.inertia[i, i] for i in range(3)]
            if all(d != 0 for d in diag):
                assert physical([params[str(d)] for d in diag], {}), params


def test_run_checks_the_generic_parameter_set_as_records_of_their_own():
    """`run` repeats the instantaneous checks at reference.generic's parameter set, under
    check names of their own (the gate sees them as new records, not as changed ones)."""
    from crosscheck.run.checks import generic_model, run

    records, _ = run(["pendulum_xy"], ["pinocchio"], n_states=2, trajectories=False)
    checks = {r["check"] for r in records if r["engine"] == "pinocchio"}
    assert checks == {"instantaneous", "instantaneous_generic"}
    generic = [r for r in records if r["check"] == "instantaneous_generic"]
    assert generic and all(r["passed"] is not False for r in generic)
    defaults = {p.name: p.default for p in models.get("pendulum_xy").parameters}
    assert all(v != defaults[k] for k, v in generic_model("pendulum_xy").params.items())


def test_a_model_without_parameters_has_one_generic_record_that_says_why(tmp_path):
    """An MJCF file's model has no parameters: its generic set would be its nominal one, so
    instead of records repeating the nominal ones (which could not fail on their own) one
    skipped record says so."""
    from crosscheck.run.checks import run
    from crosscheck.user_models import load_model_file, register_all

    um = load_model_file(Path(__file__).with_name("data") / "fourbar_connect.xml")[0]
    register_all([um])
    records, _ = run([um.name], ["pinocchio"], n_states=2, trajectories=False)
    generic = [r for r in records if r["check"].endswith("_generic")]
    assert [(r["check"], r["quantity"], r["skipped"]) for r in generic] == [
        ("instantaneous_generic", "parameter_set", True)
    ]
    assert "no parameters" in generic[0]["reason"]


def test_the_formulations_bar_is_round_off_or_the_solves_conditioning():
    """Two exact KKT solves differ by round-off up to eps x cond(K): the bar is the round-off
    one (1e-11) on every textbook model (cond(K) <= 1.8e4) and eps x cond(K) above 4.5e4,
    with the figure in its reason."""
    from crosscheck.checks.tolerances import FORMULATIONS, formulations_tolerance

    assert formulations_tolerance(1.8e4) is FORMULATIONS
    loose = formulations_tolerance(2.4e6)  # Cassie's
    assert loose.value == pytest.approx(np.finfo(float).eps * 2.4e6)
    assert "cond(K) = 2.4e+06" in loose.reason


@pytest.mark.parametrize(
    "argv,why",
    [
        (
            ["pendulum_xy", "--engines", "pinocchio", "--perturb", "pinocchio:L=1e-3"],
            "does not contain L",
        ),
        (
            ["slider_crank", "--engines", "mujoco", "--perturb", "mujoco:T=1e-3"],
            "T is 0 at the model's defaults",
        ),
        (
            ["slider_crank", "--engines", "pinocchio", "--perturb", "mujoco:m3=1e-3"],
            "not among this run's engines",
        ),
    ],
)
def test_perturbation_that_changes_nothing_is_refused(tmp_path, capsys, argv, why):
    """Exit 2 with the reason, before any work (no results.json)."""
    from crosscheck.cli import main

    code = main(["run", *argv, "--instantaneous", "--out", str(tmp_path)])
    assert code == 2 and why in capsys.readouterr().err
    assert not (tmp_path / "results.json").exists()


@pytest.mark.parametrize("engine", ["pinocchio", "mujoco"])
@pytest.mark.parametrize(
    "name,param", [("slider_crank", "l1"), ("slider_crank", "m3"), ("double_pendulum_3d", "l1")]
)
def test_perturbation_changes_the_physics_not_the_maps(engine, name, param):
    """With the nominal values given, a perturbed engine model maps states and multipliers
    exactly as the nominal one does (every variant: the free-body double pendulum's state map
    reads l1, the slider-crank's multiplier map m3 g), and its fingerprint differs."""
    from crosscheck.checks.instantaneous import build
    from crosscheck.engines.registry import get_engine
    from crosscheck.run.checks import consistent_states
    from reference import NumericModel

    adapter = get_engine(engine)
    nm = NumericModel(models.get(name))
    bad = {**nm.params, param: nm.params[param] * (1 + 1e-3)}
    for variant in adapter.variants(name):
        good_em = build(adapter, name, nm.params, variant, nominal=nm.params)
        bad_em = build(adapter, name, bad, variant, nominal=nm.params)
        assert good_em.fingerprint() != bad_em.fingerprint()
        calls = []  # the engine-side inputs of the nominal model's multiplier map
        own = good_em._multipliers
        good_em._multipliers = lambda *a, own=own, calls=calls: calls.append(a) or own(*a)
        for q, u in consistent_states(nm, 2):
            for a, b in zip(
                good_em.to_engine_state(q, u), bad_em.to_engine_state(q, u), strict=True
            ):
                assert np.array_equal(a, b), (variant, "state map")
            good_em.forward(q, u)
        # a variant without constraint rows (a ball-joint tree) takes its multipliers from the
        # engine's own inverse dynamics: physics, which the perturbation must change
        mapped = [a for a in calls if np.size(a[3])]
        assert mapped or variant == "tree", "no multiplier map was called: the test proves nothing"
        for a in mapped:
            assert np.array_equal(own(*a), bad_em._multipliers(*a)), (variant, "multiplier map")


def test_reference_drift_is_held_to_the_projection_guarantee():
    """The reference's drift records carry the projection's own bounds, so a run without
    stabilization fails them: the same model integrated without projection (index1) exceeds
    both, with projection it stays inside."""
    from crosscheck.checks.trajectory.check import REF_RTOL, output_grid
    from crosscheck.checks.trajectory.measures import residual_series
    from crosscheck.checks.trajectory.tolerances import projected_drift, projected_velocity_drift
    from reference import NumericModel
    from reference.integrate.driver import simulate

    nm = NumericModel(models.get("pendulum_xy"))
    q0, u0 = nm.project(nm.model.initial_q, nm.model.initial_u)
    for method, inside in (("projection", True), ("index1", False)):
        r = simulate(nm, q0, u0, 5.0, method, rtol=REF_RTOL, atol=REF_RTOL, t_eval=output_grid(5.0))
        pos, vel = residual_series(nm, r.t, r.q, r.u)
        assert bool(pos.max() <= projected_drift(r.q).value) is inside, (method, pos.max())
        assert bool(vel.max() <= projected_velocity_drift(r.u).value) is inside, (method, vel.max())


def test_projection_runs_after_every_accepted_step():
    """The half-switched-off stabilization the drift records cannot see: with the projection
    after each step skipped but the output points still projected (dense_state), every
    recorded state lies on the manifold and `crosscheck run pendulum_xy slider_crank` passes
    (reference state error 9.5e-12 and 3.2e-12, drift 5.8e-15 and 5.6e-15 over 5 s,
    docs/checks.md); the integrator's own count of projections shows it."""
    from crosscheck.checks.trajectory.check import REF_RTOL
    from reference import NumericModel
    from reference.integrate.driver import simulate

    nm = NumericModel(models.get("slider_crank"))
    q0, u0 = nm.project(nm.model.initial_q, nm.model.initial_u)
    r = simulate(nm, q0, u0, 0.5, "projection", rtol=REF_RTOL, atol=REF_RTOL)
    assert r.nsteps > 10 and r.stats["projections"] == r.nsteps, (r.nsteps, r.stats)


def test_failed_integration_is_a_failed_record_and_the_run_goes_on(monkeypatch):
    """A reference run that raises (here: a step-size underflow) gives a failed record with the
    reason, the engines' trajectory records are skipped with why, and nothing is raised."""
    import crosscheck.checks.trajectory.check as T
    from reference import NumericModel
    from reference.integrate.driver import IntegrationError

    def underflow(*a, **k):
        raise IntegrationError("pendulum_xy: step size underflow at t = 0.31")

    monkeypatch.setattr(T, "simulate", underflow)
    from crosscheck.engines.registry import get_engine

    nm = NumericModel(models.get("pendulum_xy"))
    records, _series = T.trajectory_records("pendulum_xy", nm, [get_engine("pinocchio")], 0.1)
    ref = [r for r in records if r["engine"] == "reference"]
    assert len(ref) == 1 and ref[0]["passed"] is False and "underflow" in ref[0]["reason"]
    assert all(r["skipped"] for r in records if r["engine"] == "pinocchio")


def test_report_shows_sensitivity_beside_results(tmp_path, capsys):
    """`crosscheck report` adds DIR/sensitivity.json (when beside results.json) as a table and a
    plot; a parameter nothing catches is marked in red with its reason."""
    import json

    from crosscheck.cli import main

    out = str(tmp_path)
    assert (
        main(
            [
                "run",
                "pendulum_xy",
                "--engines",
                "pinocchio",
                "--states",
                "2",
                "--instantaneous",
                "--no-report",
                "--out",
                out,
            ]
        )
        == 0
    )
    assert (
        main(
            ["sensitivity", "pendulum_xy", "--engines", "pinocchio", "--states", "1", "--out", out]
        )
        == 0
    )
    doc = json.loads((tmp_path / "sensitivity.json").read_text())
    missed = [t for t in doc["thresholds"] if t["caught_at"] is None]
    assert missed, "pendulum_xy's L is not in Pinocchio's model: nothing can catch it"
    assert main(["report", "--results", str(tmp_path / "results.json"), "--out", out]) == 0
    page = (tmp_path / "index.html").read_text()
    assert 'id="sensitivity"' in page and "not caught" in page and "sensitivity thresholds" in page
    import html

    assert html.escape(missed[0]["reason"], quote=True) in page
    md = (tmp_path / "report.md").read_text()
    assert "## Sensitivity" in md and "NOT CAUGHT" in md
