"""Stress scenes (crosscheck.bench.stress) end flagged or within tolerance, never failed or hung;
the work-precision records carry every field the benchmark promises. The full-length scenes and the
whole `crosscheck bench --quick` are marked slow."""

from __future__ import annotations

import json

import pytest

from crosscheck.bench import stress, targets, workprecision
from tests.support import cli


def _statuses(rec):
    return rec["status"], "; ".join(rec["reasons"])


def test_slider_crank_rank_loss_is_refused_or_reported_never_silent():
    rec = stress.slider_crank_rank_loss(quick=True)
    assert rec["status"] == "flagged", _statuses(rec)
    assert rec["wall_s"] < rec["bound_s"] * len(rec["runs"])
    for run in rec["runs"]:
        # each run refused with SingularSystemError at the pose, or crossed it and its
        # integrator reported every passage (never a timeout, never a silent passage)
        assert run["verdict"] in stress.RANK_LOSS_ALLOWED, (run["run"], run["verdict"])
        if run["verdict"] == "refused_singular":
            assert "at t =" in run["message"]
        else:
            through = [t for t, r in zip(run["crossings_t"], run["reversed"], strict=True) if r]
            assert through and set(through) <= set(run["integrator_rank_crossings_t"])
            assert any("lost rank" in w for w in run["warnings"]), run["warnings"]
            assert any(
                run["run"] in r and "reported by the integrator" in r for r in rec["reasons"]
            )


def test_a_silent_passage_of_the_rank_loss_pose_fails():
    # the judge on a run whose integrator did not report the passage (as the projection run at
    # rtol 1e-8 was before the rank monitor: pivot ratio 9.7e-4, no warning)
    rec = stress._record("s", "w", "t", 1.0)
    run = {
        "run": "projection rtol=1e-08",
        "outcome": "completed",
        "crossings_t": [0.26, 0.72],
        "reversed": [True, True],
        "integrator_rank_crossings_t": [0.26],
        "min_pivot_ratio": 9.7e-4,
        "max_abs_sin_theta1_plus_theta2": 0.0,
        "warnings": [],
    }
    stress._rank_loss_judge(rec, run["run"], run)
    assert run["verdict"] == "crossed_silently" and rec["status"] == "failed", rec


def test_redundant_constraints_are_refused_naming_the_row():
    rec = stress.redundant_constraints(quick=True)
    assert rec["status"] == "ok", _statuses(rec)
    (run,) = rec["runs"]
    assert run["outcome"] == "refused"
    assert run["error"] in ("RedundantConstraintError", "SingularSystemError")
    assert "rod_twice" in run["message"] or run["error"] == "SingularSystemError"


def test_pendulum_drift_growth_flags_only_the_unstabilized_form():
    rec = stress.pendulum_long(quick=True)
    assert rec["status"] == "flagged", _statuses(rec)
    # flagged for drift only: every run completed (a timeout is a flag too, and not expected)
    assert [r["outcome"] for r in rec["runs"]] == ["completed"] * 4, rec["runs"]
    assert all(r.startswith("index1") for r in rec["reasons"]), rec["reasons"]
    runs = {r["run"]: r for r in rec["runs"]}
    assert runs["index1"]["growth_per_decade"] > 1.5  # quadratic drift-off
    for m in ("projection", "nullspace", "baumgarte"):
        assert runs[m]["growth_per_decade"] <= stress.PENDULUM_GROWTH_MAX


def test_mass_ratio_within_tolerance():
    rec = stress.mass_ratio(quick=True)
    assert rec["status"] == "ok", _statuses(rec)


def test_top_spinning_fast_within_tolerance():
    rec = stress.top_fast_spin(quick=True)
    # top_euler is a built-in model: a skip would mean it left the registry
    assert rec["status"] == "ok", _statuses(rec)


def test_double_pendulum_near_the_313_pole():
    rec = stress.double_pendulum_313(quick=True)
    # double_pendulum_3d is a built-in model: a skip would mean it left the registry
    assert rec["status"] == "ok", _statuses(rec)
    assert rec["closest_sin_theta12"] < 1e-3  # the scene really passes near the pole


def test_a_scene_that_breaks_is_recorded_not_raised(monkeypatch):
    def broken(quick):
        raise RuntimeError("boom")

    monkeypatch.setattr(stress, "SCENES", {"broken": broken})
    (rec,) = stress.stress_records(quick=True)
    assert rec["status"] == "failed" and "boom" in rec["reasons"][0]


def test_work_precision_records_have_the_promised_fields(monkeypatch):
    monkeypatch.setattr(workprecision, "LADDER_QUICK", (1e-6, 1e-10))
    monkeypatch.setattr(workprecision, "REPEATS_QUICK", 1)
    recs = workprecision.work_precision_records(["slider_crank"], quick=True, engines=("nope",))
    ref = [r for r in recs if r["engine"] == "reference"]
    assert {r["method"] for r in ref} == {"index1", "baumgarte", "projection", "nullspace"}
    for r in ref:
        for key in (
            "model",
            "engine",
            "method",
            "setting",
            "wall_s",
            "error",
            "residual",
            "energy_drift",
            "nfev",
            "reference_accuracy",
            "error_resolved",
        ):
            assert key in r, key
        assert r["error"] is not None and r["wall_s"] > 0
    skipped = [r for r in recs if r["engine"] == "nope"]
    assert skipped and skipped[0]["skipped"] is True and "unknown engine" in skipped[0]["reason"]
    tg = targets.targets([], recs)
    t1 = tg["slider_crank_work_precision"]
    assert t1["reference"]["engine"] == "reference"
    assert t1["reference"]["error"] <= 1e-8 and t1["reference"]["residual"] <= 1e-10
    assert t1["met"] is None  # no MuJoCo rows in this run: not decided


def _wp_inputs(name):
    from reference import NumericModel, models
    from reference.minimal import reference_final_state

    nm = NumericModel(models.get(name))
    ref = reference_final_state(name, workprecision.horizon(name))
    return nm, ref, workprecision._base(name, "e", None, None, None, "timestep", 1.0, ref)


def test_an_engine_refusal_is_a_listed_skip_and_a_broken_build_a_failure():
    from crosscheck.engines.registry import get_engine

    nm, _ref, row = _wp_inputs("knife_edge")
    em, (rec,) = workprecision._engine_model(get_engine("mujoco"), "knife_edge", nm, row)
    assert em is None and rec["skipped"] and rec["refusal"] == "EngineUnsupported", rec
    nm, _ref, row = _wp_inputs("slider_crank")
    # a build that breaks (an option MuJoCo cannot parse) is a failure, never a skip
    broken = get_engine("mujoco", solref=("x", 1.0))
    em, (rec,) = workprecision._engine_model(broken, "slider_crank", nm, row)
    assert em is None and "skipped" not in rec and "ValueError" in rec["failed"], rec
    from crosscheck.commands.bench import failed_checks

    assert failed_checks({"work_precision": [rec], "stress": []})  # the bench exits 1


def test_errors_below_the_reference_accuracy_are_not_reported_as_resolved():
    _nm, ref, row = _wp_inputs("slider_crank")
    low, high = dict(row), dict(row)
    workprecision._judge_error(low, ref.accuracy / 10, ref)
    workprecision._judge_error(high, ref.accuracy * 10, ref)
    assert (
        low["error_resolved"] is False
        and "at or below the reference's accuracy" in low["error_note"]
    )
    assert high["error_resolved"] is True and "error_note" not in high


def test_engine_fixed_step_integrators_are_benchmarked_with_steps_dividing_the_horizon():
    # Exudyn declares only fixed-step integrators: every one gets rows (the generic ladder)
    from crosscheck.engines.registry import get_engine

    nm, ref, _row = _wp_inputs("slider_crank")
    adapter = get_engine("exudyn")
    recs = workprecision.engine_records("slider_crank", True, ref, nm, adapter)
    assert {r["integrator"] for r in recs} == set(adapter.capabilities.integrators)
    T = workprecision.horizon("slider_crank")
    for r in recs:
        assert "failed" not in r and r["error"] is not None, r
        assert r["nsteps"] * r["setting"] == pytest.approx(T, rel=1e-12)


def test_work_precision_target_compares_with_mujocos_most_accurate_run():
    # the target's decision on records of one real quick run: MuJoCo's rows at their default
    # and stiffer constraint settings, the reference's ladder
    from crosscheck.engines.registry import get_engine

    nm, ref, _row = _wp_inputs("slider_crank")
    recs = workprecision.reference_records(
        "slider_crank", True, ref, nm, methods=("projection",), ladder=(1e-10,)
    )
    mj = workprecision.engine_records("slider_crank", True, ref, nm, get_engine("mujoco"))
    assert any(r.get("solref") == [2 * r["setting"], 1.0] for r in mj)  # 2 steps: the floor
    t1 = targets.work_precision_target(recs + mj, "slider_crank")
    assert t1["ratio"] is not None and t1["met"] == (t1["ratio"] > 1.0), t1
    timed = [r for r in mj if r.get("error") is not None and not r.get("flagged")]
    hit = [r for r in timed if r["error"] <= targets.TARGET_MUJOCO_ERROR]
    other = min(hit, key=lambda r: r["wall_s"]) if hit else min(timed, key=lambda r: r["error"])
    assert t1["ratio"] == other["wall_s"] / t1["reference"]["wall_s"]


# each full-length scene's expected status and the runs a flag may name (measured: every run
# of these scenes completes; the rank-loss scene's runs are judged by their verdicts instead)
FULL_EXPECTED = {
    "slider_crank_rank_loss": ("flagged", None),
    "double_pendulum_313": ("ok", ()),
    "pendulum_long": ("flagged", ("index1",)),  # the unstabilized form drifts off
    "mass_ratio_1e6": ("ok", ()),
    # 64 partitions at this spin: each restart costs accuracy (the scene's own explanation)
    "top_1000_rad_s": ("flagged", ("nullspace",)),
    "redundant_constraints": ("ok", ()),
}


@pytest.mark.slow
@pytest.mark.parametrize("scene", list(stress.SCENES))
def test_full_scenes(scene):
    assert set(FULL_EXPECTED) == set(stress.SCENES)  # a new scene states its expectation
    status, flagged_runs = FULL_EXPECTED[scene]
    rec = stress.SCENES[scene](quick=False)
    assert rec["status"] == status, _statuses(rec)
    if flagged_runs is None:
        assert all(r["verdict"] in stress.RANK_LOSS_ALLOWED for r in rec["runs"]), rec["runs"]
    elif scene != "redundant_constraints":  # its one run is an expected refusal
        assert all(r["outcome"] == "completed" for r in rec["runs"]), rec["runs"]
        assert all(r.split(":")[0] in flagged_runs for r in rec["reasons"]), rec["reasons"]


@pytest.mark.parametrize(
    "model,engines",
    [
        ("pendulum_angle", "pinocchio"),
        pytest.param("slider_crank", None, marks=pytest.mark.slow),  # every engine
    ],
)
def test_bench_quick_writes_every_section(tmp_path, model, engines):
    """`crosscheck bench --quick` in this process: one model is enough to see every section
    written (the stress scenes and targets do not depend on the model list); the whole suite's
    quick bench is a benchmark, not a test."""
    from crosscheck.engines.registry import available_engines, get_engine

    argv = ["bench", model, "--quick", "--out", tmp_path]
    r = cli(*argv, *(["--engines", engines] if engines else []))
    assert r.returncode == 0, r.stderr[-2000:]
    data = json.loads((tmp_path / "bench.json").read_text())
    for key in ("forward", "work_precision", "stress", "targets", "skips"):
        assert data[key], key
    named = engines.split(",") if engines else available_engines()
    # every engine with trajectories runs its own integrators beside the reference's methods
    with_trajectories = {e for e in named if get_engine(e).capabilities.integrators}
    for engine in with_trajectories | {"reference"}:
        rows = [
            rec
            for rec in data["work_precision"]
            if rec["model"] == model and rec["engine"] == engine
        ]
        assert rows and all(r.get("error") is not None for r in rows), engine
    for e in with_trajectories:
        integrators = {rec["integrator"] for rec in data["work_precision"] if rec["engine"] == e}
        caps = get_engine(e).capabilities
        fixed = {i for i in caps.integrators if i not in caps.adaptive_integrators}
        assert fixed <= integrators, (e, fixed - integrators)
    assert data["failed_checks"] == [] and all(s["status"] != "failed" for s in data["stress"])
    assert data["meta"]["wall_s"] < 180


def test_kkt_saving_compares_one_model_with_and_without_its_rows():
    from crosscheck.bench import skip_savings
    from reference import NumericModel, models

    model = models.get("pendulum_xy")
    free = NumericModel(skip_savings.unconstrained(model))
    # like for like: the same coordinates and speeds, only the constraint rows gone
    assert free.m == 0 and free.nq == len(model.coordinates) and free.n == len(model.speeds)
    rec = skip_savings.kkt_saving("pendulum_xy", rounds=1)
    assert rec["constraint_rows"] == 1 and rec["states"] == skip_savings.KKT_STATES
    assert rec["forward_us"]["kkt"] > 0 and rec["forward_us"]["rows_removed"] > 0
    assert rec["projection_run"]["nfev"] > 0
