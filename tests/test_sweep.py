"""`crosscheck sweep`: seeded campaigns that give the same numbers however they are run.

- a sample is the property tests' instance (same generator, same seed), and the sweep's fast
  paths (shared compiled code with new parameters, the reference batched over samples with
  per-sample parameters) give the numbers of the slow obvious ones;
- per-sample errors are those of `crosscheck run`'s stage-by-stage checks at the same state;
- the aggregate is identical for 1 or 2 worker processes, any chunk size, and a Dask cluster;
- a worst case is reproduced bit for bit by the command line recorded beside it;
- faults (an engine that raises, a draw that fails, MuJoCo refusing a parameter set) are
  recorded with their reason and seed, and the campaign finishes;
- an interrupted or time-limited campaign reports exactly what it completed;
- the command's exit codes: 0 clean, 1 outside tolerance or faulted, 2 bad input (one line).
Throughput is measured by `crosscheck sweep --bench`, not here.
"""

from __future__ import annotations

import json
import shlex

import numpy as np
import pytest

from crosscheck.checks.sampling import draw_sample, sample_seed, with_params
from crosscheck.cli import main
from crosscheck.sweep.campaign import campaign
from crosscheck.sweep.config import (
    DASK_MAX_CHUNK,
    DASK_MIN_CHUNK,
    LOCAL_CHUNK_MAX,
    QUANTILES,
    Campaign,
)
from crosscheck.sweep.executors import dask_chunk, local_chunk
from crosscheck.sweep.worker import base_model, cached_adapter, reference_batch
from crosscheck.sweep.worker import draw_sample as sweep_draw_sample
from reference import NumericModel, models

DETERMINISTIC = ("status", "series", "results", "faults")


def _same(a: dict, b: dict) -> None:
    a, b = json.loads(json.dumps(a)), json.loads(json.dumps(b))  # as written to sweep.json
    for key in DETERMINISTIC:
        assert a[key] == b[key], key


@pytest.fixture(scope="module")
def local_run():
    """The reference campaign: in this process, chunks of 3."""
    cfg = Campaign(["pendulum_xy", "slider_crank_split"], samples=8, seed=11)
    return cfg, campaign(cfg, workers=1, chunk=3)


# ---- a sample is the property tests' instance; fast paths = slow paths ---------------------
@pytest.mark.parametrize("name", ["slider_crank", "top_cartesian", "pendulum_moving_support"])
def test_sample_is_the_property_tests_instance(name):
    from tests.test_properties import _instance

    base = base_model(name)
    for i in (0, 7):
        s, nm, t, q, u = draw_sample(base, 5, i)
        assert s == sample_seed(5, name, i) and 0 <= s < 2**32  # a valid hypothesis seed
        nm2, q2, u2, t2 = _instance(name, base.formulation, s)
        assert nm.params == nm2.params and t == t2
        assert np.array_equal(q, q2) and np.array_equal(u, u2)
    # the seed depends on (seed, model, index) only, and each of them changes it
    seeds = {
        sample_seed(5, name, 0),
        sample_seed(6, name, 0),
        sample_seed(5, name, 1),
        sample_seed(5, name + "_", 0),
    }
    assert len(seeds) == 4


def test_with_params_equals_the_constructor():
    model = models.get("double_pendulum_3d")
    base = base_model(model.name)
    _, nm, t, q, u = draw_sample(base, 1, 0)
    slow = NumericModel(model, base.formulation, nm.params)
    fast = with_params(base, nm.params)
    assert fast.sref == slow.sref and fast.p == slow.p
    a, b = fast.forward(q, u, t), slow.forward(q, u, t)
    assert np.array_equal(a.accelerations, b.accelerations)
    assert np.array_equal(a.multipliers, b.multipliers)
    assert base.p != fast.p  # the base keeps its own parameters


@pytest.mark.parametrize("name", ["slider_crank_split", "top_euler", "exercise_6_4"])
def test_batched_reference_with_per_sample_parameters_equals_scalar(name):
    base = base_model(name)
    draws = [draw_sample(base, 2, i) for i in range(6)]
    UD, LAM, errs = reference_batch(
        base,
        [d[1] for d in draws],
        [d[2] for d in draws],
        [d[3] for d in draws],
        [d[4] for d in draws],
    )
    assert errs == [None] * 6
    for j, (_, nm, t, q, u) in enumerate(draws):
        fw = nm.forward(q, u, t)
        scale = max(1.0, np.abs(fw.accelerations).max())
        assert np.abs(UD[j] - fw.accelerations).max() <= 1e-13 * scale
        if base.m:
            scale = max(1.0, np.abs(fw.multipliers).max())
            assert np.abs(LAM[j] - fw.multipliers).max() <= 1e-13 * scale


def test_batched_reference_isolates_a_singular_sample():
    # the slider-crank folded onto itself (l2 = l1 at theta1 = pi/2) beside regular samples
    base = base_model("slider_crank")
    draws = [draw_sample(base, 2, i) for i in range(3)]
    fold = with_params(base, {**draws[1][1].params, "l2": draws[1][1].params["l1"]})
    nms = [draws[0][1], fold, draws[2][1]]
    Q = [draws[0][3], np.array([np.pi / 2, -np.pi / 2]), draws[2][3]]
    U = [draws[0][4], np.zeros(2), draws[2][4]]
    UD, _, errs = reference_batch(base, nms, [0.0] * 3, Q, U)
    assert errs[0] is None and errs[2] is None and "singular" in str(errs[1])
    assert np.array_equal(UD[2], reference_batch(base, nms[2:], [0.0], Q[2:], U[2:])[0][0])


@pytest.mark.parametrize(
    "name,engine",
    [
        ("slider_crank", "mujoco"),
        ("slider_crank", "pinocchio"),
        ("exercise_6_1", "mujoco"),
        ("top_cartesian", "pinocchio"),
    ],
)
def test_sample_errors_are_the_run_checks_at_that_state(name, engine):
    """A sweep sample's values (compare_at_state) = run's records (engine_records) on that
    single state (these models are scleronomic, so run's t = 0 and the sample's t give the
    same numbers), each against the same tolerance."""
    from crosscheck.checks.instantaneous import (
        build,
        compare_at_state,
        engine_records,
        reference_answer,
        tolerance,
    )
    from crosscheck.engines.registry import get_engine

    base = base_model(name)
    _, nm, t, q, u = draw_sample(base, 4, 1)
    ad = get_engine(engine)
    for variant in ad.variants(name):
        recs = engine_records(name, nm, [(q, u)], ad, nm.params, variant)
        em = build(ad, name, nm.params, variant)
        sc = compare_at_state(em, q, u, t, reference_answer(nm, q, u, t), nm.m, ad.capabilities)
        assert recs
        for r in recs:
            if r["skipped"]:
                assert r["quantity"] in sc.skips and r["quantity"] not in sc.values
                continue
            assert sc.values[r["quantity"]] == r["error"], r["quantity"]
            tol, _ = tolerance(r["quantity"], sc.soft, ad, name)
            assert tol.value == r["tolerance"]


# ---- the same aggregate however it is run ---------------------------------------------------
def test_identical_for_worker_counts_and_chunk_sizes(local_run):
    cfg, a = local_run
    assert a["status"]["complete"] and a["status"]["completed"] == {
        "pendulum_xy": 8,
        "slider_crank_split": 8,
    }
    b = campaign(cfg, workers=2, chunk=5)
    assert b["meta"]["executor"]["kind"] == "processes"
    _same(a, b)
    _same(a, campaign(cfg, workers=1, chunk=8))
    # and each sample is its own: a sub-range of the campaign gives its part of the values
    part = campaign(Campaign(["pendulum_xy"], samples=3, seed=11, index=4), workers=1)
    full = {(r["engine"], r["quantity"]): r for r in a["results"] if r["model"] == "pendulum_xy"}
    for r in part["results"]:
        if r.get("skipped"):
            continue
        worst = {w["index"]: w["error"] for w in full[(r["engine"], r["quantity"])]["worst"]}
        for w in r["worst"]:
            if w["index"] in worst:
                assert worst[w["index"]] == w["error"]


def test_dask_cluster_equals_local_run(local_run):
    distributed = pytest.importorskip("distributed")
    cfg, a = local_run
    with (
        distributed.LocalCluster(
            n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        b = campaign(cfg, dask=client, chunk=3)
    assert b["meta"]["executor"]["kind"] == "dask"
    _same(a, b)


def test_chunk_sizes_keep_task_overhead_small():
    assert dask_chunk(10_000, 8) == 313  # a quarter of a model's samples per thread
    assert dask_chunk(1_000, 8) == DASK_MIN_CHUNK  # never below the overhead floor ...
    assert dask_chunk(40, 8) == 5  # ... unless that would leave threads idle
    assert dask_chunk(10**6, 8) == DASK_MAX_CHUNK  # tasks of seconds, not minutes
    assert local_chunk(10_000, 2) == LOCAL_CHUNK_MAX and local_chunk(8, 2) == 1


# ---- worst cases reproduce exactly ----------------------------------------------------------
def test_worst_case_reproduces_bit_for_bit(tmp_path, capsys):
    """A fault injected into MuJoCo's model puts samples outside tolerance; the recorded
    command reruns the worst alone and gives the same error, and `crosscheck eval` gives the
    reference at that case."""
    out = tmp_path / "campaign"
    code = main(
        [
            "sweep",
            "slider_crank",
            "--samples",
            "6",
            "--seed",
            "9",
            "--engines",
            "mujoco",
            "--perturb",
            "mujoco:m2=1e-6",
            "--workers",
            "1",
            "--worst",
            "6",
            "--out",
            str(out),
        ]
    )
    assert code == 1
    capsys.readouterr()
    res = json.loads((out / "sweep.json").read_text())
    rec = next(r for r in res["results"] if r["quantity"] == "accelerations")
    assert rec["outside_tolerance"] == 6 and rec["max"] == rec["worst"][0]["error"]
    worst = rec["worst"][0]
    argv = shlex.split(worst["reproduce"]["sweep"])
    assert argv[:2] == ["crosscheck", "sweep"] and "--perturb" in argv
    argv[argv.index("--out") + 1] = str(tmp_path / "again")
    assert main(argv[1:]) == 1
    capsys.readouterr()
    again = json.loads((tmp_path / "again" / "sweep.json").read_text())
    assert again["status"]["completed_ranges"] == {
        "slider_crank": [[worst["index"], worst["index"] + 1]]
    }
    for r in again["results"]:
        if r.get("skipped"):
            continue
        first = next(x for x in res["results"] if x["quantity"] == r["quantity"])
        errors = {w["index"]: w["error"] for w in first["worst"]}
        assert r["max"] == errors[worst["index"]], r["quantity"]  # bit for bit
    # the reference at the worst case, from the printed eval command (scalar path)
    ev = shlex.split(worst["reproduce"]["eval"])
    assert main(ev[1:]) == 0
    d = json.loads(capsys.readouterr().out)
    base = base_model("slider_crank")
    s, nm, t, q, u = draw_sample(base, 9, worst["index"])
    assert s == worst["sample_seed"] and d["parameters"] == nm.params and d["t"] == t
    assert np.array_equal(d["q"], q) and np.array_equal(d["u"], u)
    UD, LAM, _ = reference_batch(base, [nm], [t], [q], [u])
    assert np.allclose(d["accelerations"], UD[0], rtol=1e-13, atol=1e-13)
    assert np.allclose(d["multipliers"], LAM[0], rtol=1e-13, atol=1e-13)


def test_seed_5_sample_1131_reads_back_the_same_state(tmp_path, capsys):
    """The 3-D double pendulum's theta22 = -0.034 there comes back on the other 3-1-3 branch
    (theta21 + pi, 0.034, theta23 - pi) in every engine: state_map read 1.69, and it is the
    same state (tests/test_state_map.py), so the sample passes."""
    from crosscheck.checks.tolerances import STATE_MAP
    from crosscheck.engines.registry import available_engines, get_engine

    engines = [e for e in available_engines() if "double_pendulum_3d" in get_engine(e).models()]
    argv = ["sweep", "double_pendulum_3d", "--seed", "5", "--index", "1131", "--samples", "1"]
    argv += ["--engines", ",".join(engines), "--workers", "1", "--out", str(tmp_path)]
    assert main(argv) == 0
    assert "1 of 1 samples, 0 outside tolerance, 0 faults" in capsys.readouterr().out
    res = json.loads((tmp_path / "sweep.json").read_text())
    maps = [r for r in res["results"] if r["quantity"] == "state_map"]
    assert {r["engine"] for r in maps} == set(engines)
    assert all(r["count"] == 1 and r["max"] <= STATE_MAP.value for r in maps)


# ---- faults survive -------------------------------------------------------------------------
class _FlakyModel:
    def __init__(self, em):
        self.em = em

    def __getattr__(self, k):
        return getattr(self.em, k)

    def forward(self, q, u, t=0.0):
        raise np.linalg.LinAlgError("solver failure (injected)")


class _FlakyAdapter:
    """Pinocchio, except: a sample whose m drew above its default fails to build, one whose
    L drew below its default fails in forward."""

    def __init__(self, inner):
        self.inner, self.name, self.capabilities = inner, inner.name, inner.capabilities

    def variants(self, name):
        return self.inner.variants(name)

    def exact_tolerance(self, name):
        return self.inner.exact_tolerance(name)

    def build(self, name, params, variant=None):
        em = self.inner.build(name, params)
        if params is None:
            return em
        if params["m"] > 1.5:
            raise RuntimeError("singular pose (injected)")
        return _FlakyModel(em) if params["L"] < 0.8 else em


def test_faults_are_recorded_with_reason_and_seed_and_the_campaign_finishes(monkeypatch):
    from reference.errors import OffManifoldError

    real_adapter, real_draw = cached_adapter, sweep_draw_sample

    def adapter(engine):
        a = real_adapter(engine)
        return _FlakyAdapter(a) if engine == "pinocchio" else a

    def draw(base, seed, index):
        if index == 2:
            raise OffManifoldError("projection did not converge (injected)")
        return real_draw(base, seed, index)

    from crosscheck.sweep import campaign as sweep_campaign
    from crosscheck.sweep import worker as sweep_worker

    for mod in (sweep_worker, sweep_campaign):  # the worker draws and builds; the plan builds
        monkeypatch.setattr(mod, "cached_adapter", adapter)
    monkeypatch.setattr(sweep_worker, "draw_sample", draw)
    cfg = Campaign(["pendulum_xy"], samples=10, seed=1)
    res = campaign(cfg, workers=1, chunk=4)
    st = res["status"]
    assert st["complete"] and st["completed"] == {"pendulum_xy": 10} and not st["passed"]
    params = {i: real_draw(base_model("pendulum_xy"), 1, i)[1].params for i in range(10) if i != 2}
    build = sorted(i for i, p in params.items() if p["m"] > 1.5)
    evaluate = sorted(i for i, p in params.items() if p["m"] <= 1.5 and p["L"] < 0.8)
    assert build and evaluate  # the seed exercises both
    recs = res["faults"]["records"]
    got: dict = {}
    for f in recs:
        got.setdefault((f["engine"], f["stage"]), []).append(f["index"])
    assert got == {
        ("pinocchio", "build"): build,
        ("pinocchio", "evaluate"): evaluate,
        ("reference", "draw"): [2],
    }
    for f in recs:
        assert f["sample_seed"] == sample_seed(1, "pendulum_xy", f["index"])
        assert f"--index {f['index']} --samples 1" in f["reproduce"]
        assert "injected" in f["reason"]
    types = {(g["engine"], g["stage"]): (g["type"], g["count"]) for g in res["faults"]["groups"]}
    assert types[("pinocchio", "evaluate")] == ("LinAlgError", len(evaluate))
    # the other samples and the other engine are untouched
    by = {(r["engine"], r["quantity"]): r for r in res["results"]}
    assert by[("mujoco", "accelerations")]["count"] == 9
    assert by[("pinocchio", "accelerations")]["count"] == 9 - len(build) - len(evaluate)
    series = {s["engine"]: s for s in res["series"]}
    assert series["pinocchio"]["faults"] == len(build) + len(evaluate)


def test_mujoco_refusing_a_parameter_set_is_a_recorded_fault(monkeypatch):
    """A parameter set MuJoCo refuses at compile time (here Example 4's link 1 given
    I_33 > I_11 + I_22, against the triangle inequality) is a recorded build fault with
    MuJoCo's message; the campaign completes and does not pass."""
    import crosscheck.checks.sampling as sampling

    draw = sampling.random_params

    def non_physical(model, rng):
        p = draw(model, rng)
        p["I1_33"] = 3.0 * (p["I1_11"] + p["I1_22"])
        return p

    monkeypatch.setattr(sampling, "random_params", non_physical)
    res = campaign(
        Campaign(["double_pendulum_3d"], samples=2, seed=0, engines=("mujoco",)), workers=1
    )
    groups = res["faults"]["groups"]
    assert {g["variant"] for g in groups} == {"free", "tree"}
    for g in groups:
        assert g["stage"] == "build" and g["count"] == 2 and "A + B >= C" in g["first_reason"]
    assert res["status"]["complete"] and not res["status"]["passed"]


def test_drawn_inertias_stay_physical():
    """The generator draws each inertia on its own but keeps every body physical (second
    moments, rejection for shared parameters), so MuJoCo accepts every draw."""
    res = campaign(
        Campaign(["double_pendulum_3d", "frame_bar"], samples=6, seed=0, engines=("mujoco",)),
        workers=1,
    )
    assert not res["faults"]["groups"], res["faults"]["groups"]


# ---- interrupted campaigns ------------------------------------------------------------------
@pytest.mark.parametrize("workers", [1, 2])
def test_interrupted_campaign_reports_what_it_completed(local_run, workers):
    _cfg, full = local_run
    merged = []

    def interrupt(res):
        merged.append(res)
        if len(merged) == 2:
            raise KeyboardInterrupt

    res = campaign(
        Campaign(["pendulum_xy"], samples=8, seed=11),
        workers=workers,
        chunk=2,
        on_chunk=interrupt,
    )
    st = res["status"]
    assert st["stopped"] == "interrupted" and not st["complete"]
    assert not st["passed"] and st["verdict"] == "incomplete"  # interrupted: never passed
    ranges = st["completed_ranges"]["pendulum_xy"]
    done = sum(b - a for a, b in ranges)
    assert done == st["completed"]["pendulum_xy"] >= 4  # the two merged chunks, maybe more
    assert done < 8 or workers == 2
    # what it completed is exactly what a full campaign says about those samples
    ref = {(r["engine"], r["quantity"]): r for r in full["results"] if r["model"] == "pendulum_xy"}
    for r in res["results"]:
        if r.get("skipped"):
            continue
        assert r["count"] == done
        errors = {w["index"]: w["error"] for w in ref[(r["engine"], r["quantity"])]["worst"]}
        for w in r["worst"]:
            assert any(a <= w["index"] < b for a, b in ranges)
            if w["index"] in errors:
                assert errors[w["index"]] == w["error"]


def test_time_budget_stops_and_says_so(tmp_path, capsys):
    code = main(
        [
            "sweep",
            "pendulum_xy",
            "--samples",
            "100000",
            "--max-seconds",
            "1",
            "--workers",
            "1",
            "--out",
            str(tmp_path),
        ]
    )
    out = capsys.readouterr().out
    res = json.loads((tmp_path / "sweep.json").read_text())
    st = res["status"]
    assert not st["complete"] and "time budget" in st["stopped"] and "stopped" in out
    done = st["completed"]["pendulum_xy"]
    # on a loaded machine the budget can end before the first chunk: what completed (possibly
    # nothing) is reported exactly
    assert done < 100000
    assert st["completed_ranges"]["pendulum_xy"] == ([[0, done]] if done else [])
    assert not st["passed"]  # incomplete: what it did not run, it did not check
    assert (st["verdict"], code) in (("incomplete", 4), ("failed", 1))


# ---- command line ---------------------------------------------------------------------------
def test_cli_clean_campaign_exits_0_and_writes_the_contract(tmp_path, capsys):
    code = main(
        [
            "sweep",
            "pendulum_xy",
            "--samples",
            "4",
            "--seed",
            "2",
            "--engines",
            "pinocchio",
            "--workers",
            "1",
            "--out",
            str(tmp_path),
        ]
    )
    out = capsys.readouterr().out
    assert code == 0 and "4 of 4 samples, 0 outside tolerance, 0 faults" in out
    res = json.loads((tmp_path / "sweep.json").read_text())
    for key in (
        "command",
        "versions",
        "machine",
        "date",
        "seed",
        "samples",
        "seeding",
        "sampler",
        "executor",
    ):
        assert key in res["meta"]
    r = next(r for r in res["results"] if r["quantity"] == "accelerations")
    assert set(r["quantiles"]) == {str(p) for p in QUANTILES}
    assert r["tolerance"] == 1e-11 and r["outside_tolerance"] == 0 and r["count"] == 4
    assert r["max"] == r["worst"][0]["error"] == r["quantiles"]["0.999"]
    h = r["histogram"]
    assert sum(h["counts"]) + h["zero"] + h["below"] + h["above"] + h["nonfinite"] == 4


def test_derivatives_campaign_finds_the_loop_defect_and_nothing_else(tmp_path, capsys):
    """--derivatives: each sample's derivative blocks as error over the tolerance derived
    there (judged against 1). Over random parameter sets and states of the slider-crank,
    Pinocchio's du'/dq and dlambda/dq (its loop-closure defect, docs/engines/pinocchio.md) are
    outside at every sample, every other block of every engine inside."""
    argv = ["sweep", "slider_crank", "--samples", "3", "--seed", "1", "--workers", "1"]
    code = main([*argv, "--derivatives", "--engines", "pinocchio,opensim", "--out", str(tmp_path)])
    assert code == 1, capsys.readouterr().out
    res = json.loads((tmp_path / "sweep.json").read_text())
    rows = [r for r in res["results"] if r["quantity"].startswith("d") and not r.get("skipped")]
    outside = {(r["engine"], r["quantity"]) for r in rows if r["outside_tolerance"]}
    assert outside == {("pinocchio", "daccelerations_dq"), ("pinocchio", "dmultipliers_dq")}
    assert {r["engine"] for r in rows} == {"pinocchio", "opensim"}
    assert all(r["tolerance"] == 1.0 and r["count"] == 3 for r in rows)
    assert all(r["metric"] == "error_over_derived_tolerance" for r in rows)


@pytest.mark.parametrize(
    "argv,needle",
    [
        (["nope"], "unknown model"),
        (["pendulum_xy", "--engines", "bullet"], "unknown engine"),
        (["pendulum_xy", "--samples", "0"], "--samples: 0 must be at least 1"),
        (["pendulum_xy", "--samples", "ten"], "not a whole number"),
        (["pendulum_xy", "--seed", "-1"], "--seed: -1 must be at least 0"),
        (["pendulum_xy", "--workers", "0"], "--workers: 0 must be at least 1"),
        (["pendulum_xy", "--workers", "2", "--dask", "tcp://127.0.0.1:1"], "not both"),
        (["pendulum_xy", "--max-seconds", "0"], "seconds > 0"),
        (["pendulum_xy", "--chunk", "0"], "--chunk: 0 must be at least 1"),
        (["pendulum_xy", "--perturb", "mujoco:nope=1"], "has no parameter 'nope'"),
        (["pendulum_xy", "--perturb", "mujoco-m=1"], "expected ENGINE:PARAM=REL"),
        (["pendulum_xy", "--engines", "pinocchio", "--perturb", "mujoco:m=1"], "not in --engines"),
        (["frame_bar", "--formulation", "lagrange"], "does not declare formulation"),
        (["pendulum_xy", "--dask", "local:x"], "expected local or local:K"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, argv, needle):
    try:  # argument rules refuse at parse time (SystemExit), the registries in the command
        code = main(["sweep", *argv, "--out", str(tmp_path)])
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2, err
    assert needle in err and err.startswith("crosscheck: error:")
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "sweep.json").exists()


# ---- report -----------------------------------------------------------------------------------
def test_report_shows_sweep_histograms(local_run, tmp_path, capsys):
    _, res = local_run
    (tmp_path / "sweep.json").write_text(json.dumps(res, allow_nan=True))
    (tmp_path / "results.json").write_text(json.dumps({"meta": {}, "records": []}))
    assert main(["report", "--results", str(tmp_path / "results.json")]) == 0  # found beside
    capsys.readouterr()
    html = (tmp_path / "index.html").read_text()
    assert 'id="sweep"' in html and "--sweep" in html  # the section and the regenerate command
    for m in ("pendulum_xy", "slider_crank_split"):
        assert f'alt="sweep error histograms for {m}"' in html
    md = (tmp_path / "report.md").read_text()
    assert "## Sweep" in md and "| mujoco | accelerations_soft_vs_predicted |" in md
    site = tmp_path / "only"
    assert main(["report", "--sweep", str(tmp_path / "sweep.json"), "--out", str(site)]) == 0
    assert "sweep only" in (site / "index.html").read_text()
    (tmp_path / "bad.json").write_text('{"results": 3}')
    assert main(["report", "--sweep", str(tmp_path / "bad.json"), "--out", str(site)]) == 2
    assert "is it a sweep.json" in capsys.readouterr().err
