"""`crosscheck gate` as CI and a person use it: a baseline from a real run, then a clean fresh
run (exit 0), a planted regression (exit 1, each regression named), a fault injected into an
engine's model (exit 1), a deliberate --update, and usage errors (exit 2, one line)."""

from __future__ import annotations

import copy
import json

import pytest

from crosscheck.cli import main
from crosscheck.gate import FACTOR, ROUND_OFF_FLOOR, worsened

from .test_report import crosscheck, results_of, synthetic_bench


def key(r: dict) -> str:
    return f"{r['model']}/{r['formulation']}/{r['engine']}/{r['check']}/{r['quantity']}"


def gate(capsys, *argv) -> tuple[int, str, str]:
    code = main(["gate", *map(str, argv)])
    out, err = capsys.readouterr()
    return code, out, err


def regressions(out: str) -> list[str]:
    """The indented lines under 'REGRESSIONS (n):'."""
    lines = out.splitlines()
    if not any(ln.startswith("REGRESSIONS") for ln in lines):
        return []
    start = next(i for i, ln in enumerate(lines) if ln.startswith("REGRESSIONS")) + 1
    block = []
    for ln in lines[start:]:
        if not ln.startswith("  "):
            break
        block.append(ln.strip())
    return block


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    return json.loads(results_of(tmp_path_factory, "clean").read_text())


@pytest.fixture
def baseline(tmp_path, tmp_path_factory, capsys):
    """reports/baseline.json made the way the lead makes it: --update on a clean run."""
    path = tmp_path / "reports" / "baseline.json"
    code, out, _ = gate(
        capsys, "--baseline", path, "--results", results_of(tmp_path_factory, "clean"), "--update"
    )
    assert code == 0 and "created baseline" in out and path.exists()
    return path


def write(tmp_path, name, data) -> str:
    p = tmp_path / name
    p.write_text(json.dumps(data))
    return str(p)


def test_fresh_clean_run_passes_the_gate(baseline, tmp_path_factory):
    """Exit 0 on a second, independent run of the same revision (through the real command)."""
    fresh = results_of(tmp_path_factory, "clean2")
    p = crosscheck("gate", "--baseline", baseline, "--results", fresh)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "no regressions" in p.stdout and "REGRESSIONS" not in p.stdout


def test_planted_regression_is_caught_and_named(baseline, clean, tmp_path):
    """One error 50x worse, one passed check failing, one record removed: exit 1, all three
    named, nothing else."""
    planted = copy.deepcopy(clean)
    recs = planted["records"]
    executed = [r for r in recs if r["passed"]]
    worse, broken, removed = executed[-1], executed[-2], executed[0]
    # 50x worse than the baseline figure, measured from the round-off floor (a figure below
    # the floor is round-off, and 100x of round-off is still round-off: see the next test),
    # and still within its tolerance: a regression the record's own verdict does not show
    worse["error"] = 50 * max(worse["error"], ROUND_OFF_FLOOR)
    assert worse["error"] <= worse["tolerance"]
    broken["passed"], broken["error"] = False, 10 * broken["tolerance"]
    recs.remove(removed)
    p = crosscheck("gate", "--baseline", baseline, "--results", write(tmp_path, "r.json", planted))
    assert p.returncode == 1, p.stdout + p.stderr
    found = regressions(p.stdout)
    assert len(found) == 3, p.stdout
    assert any(
        ln.startswith(key(worse)) and "error" in ln and f"worse than {FACTOR:g}x" in ln
        for ln in found
    )
    assert any(ln.startswith(key(broken)) and "passed -> failed" in ln for ln in found)
    assert any(ln.startswith(key(removed)) and "missing from the results" in ln for ln in found)
    assert "3 regressions" in p.stdout


def test_round_off_changes_are_not_regressions(baseline, clean, tmp_path, capsys):
    noisy = copy.deepcopy(clean)
    tiny = [r for r in noisy["records"] if r["passed"] and r["error"] < ROUND_OFF_FLOOR / 100]
    assert tiny, "the slider-crank's Pinocchio errors are at round-off level"
    for r in tiny:
        r["error"] = max(r["error"], 1e-16) * 100 if r["error"] else ROUND_OFF_FLOOR / 2
        assert r["error"] <= ROUND_OFF_FLOOR
    code, out, _ = gate(
        capsys, "--baseline", baseline, "--results", write(tmp_path, "r.json", noisy)
    )
    assert code == 0, out


@pytest.mark.parametrize(
    "old,new,regressed",
    [
        (1e-15, 1e-13, False),  # both round-off: equal
        (1e-15, 2e-12, True),  # out of round-off by more than 10x the floor
        (1e-12, 9e-12, False),  # within the factor
        (1e-12, 2e-11, True),  # beyond the factor
        (1e-12, float("inf"), True),
        (1e-12, None, True),  # a figure that disappeared
        (float("inf"), float("inf"), False),
        (None, 1.0, False),  # no baseline figure (skipped): nothing to get worse
        (0.0, 5e-14, False),
    ],
)
def test_worsened_rule(old, new, regressed):
    assert worsened(old, new) is regressed


def test_fault_injected_into_an_engine_fails_the_gate(baseline, tmp_path_factory, capsys):
    code, out, _ = gate(
        capsys, "--baseline", baseline, "--results", results_of(tmp_path_factory, "faulty")
    )
    faulty = json.loads(results_of(tmp_path_factory, "faulty").read_text())
    failing = [key(r) for r in faulty["records"] if r["passed"] is False]
    assert code == 1 and failing
    found = regressions(out)
    for k in failing:
        assert any(ln.startswith(k) and "passed -> failed" in ln for ln in found), (k, out)


def test_passed_to_skipped_and_new_failing_records_are_regressions(
    baseline, clean, tmp_path, capsys
):
    data = copy.deepcopy(clean)
    r = next(r for r in data["records"] if r["passed"] and r["engine"] == "pinocchio")
    r.update(passed=None, skipped=True, error=None, tolerance=None, reason="test: not run")
    new_ok = dict(
        r, quantity="new_quantity_ok", passed=True, skipped=False, error=0.0, tolerance=1e-11
    )
    new_bad = dict(new_ok, quantity="new_quantity_bad", passed=False, error=1.0)
    data["records"] += [new_ok, new_bad]
    code, out, _ = gate(
        capsys, "--baseline", baseline, "--results", write(tmp_path, "r.json", data)
    )
    found = regressions(out)
    assert code == 1 and len(found) == 3, out
    assert any(ln.startswith(key(r)) and "passed -> skipped (test: not run)" in ln for ln in found)
    assert any(ln.startswith(key(new_bad)) and "new record, failing" in ln for ln in found)
    assert any(
        ln.startswith(f"{key(new_ok)}: new record (passed)") and "--accept-new" in ln
        for ln in found
    )  # ungated: a regression unless accepted
    code, out, _ = gate(
        capsys, "--baseline", baseline, "--results", write(tmp_path, "r.json", data), "--accept-new"
    )
    found = regressions(out)
    assert code == 1 and len(found) == 2, out  # a new failing record is never accepted
    assert (
        "accepted by --accept-new (run --update to gate them) (1):" in out
        and f"{key(new_ok)}: new record (passed)" in out
    )


def test_a_baseline_of_one_model_does_not_pass_the_whole_suite(clean, tmp_path, capsys):
    """The gate compared nothing new and passed: now the records the baseline
    lacks fail it, unless --accept-new lists them as accepted; a missing record still fails."""
    # the fixture's run has one model: a baseline of its reference records stands for a
    # baseline that covers a part of what the results hold
    part = [r for r in clean["records"] if r["engine"] == "reference"]
    assert 0 < len(part) < len(clean["records"])
    one = {"meta": {}, "records": part}
    base, results = write(tmp_path, "one.json", one), write(tmp_path, "all.json", clean)
    lacking = len(clean["records"]) - len(one["records"])
    code, out, _ = gate(capsys, "--baseline", base, "--results", results)
    assert code == 1 and len(regressions(out)) == lacking, out
    code, out, _ = gate(capsys, "--baseline", base, "--results", results, "--accept-new")
    assert (
        code == 0 and f"accepted by --accept-new (run --update to gate them) ({lacking}):" in out
    ), out
    fewer = copy.deepcopy(clean)
    gone = next(r for r in fewer["records"] if r["engine"] == "reference")
    fewer["records"].remove(gone)
    code, out, _ = gate(
        capsys,
        "--baseline",
        base,
        "--results",
        write(tmp_path, "fewer.json", fewer),
        "--accept-new",
    )
    found = regressions(out)
    assert code == 1 and len(found) == 1 and found[0].startswith(key(gone)), out
    assert "missing from the results" in found[0]


def test_update_rewrites_the_baseline_and_says_what_changed(baseline, clean, tmp_path, capsys):
    data = copy.deepcopy(clean)
    r = next(r for r in data["records"] if r["passed"] and r["engine"] == "pinocchio")
    r["passed"], r["error"] = False, 1.0
    results = write(tmp_path, "r.json", data)
    code, out, _ = gate(capsys, "--baseline", baseline, "--results", results, "--update")
    assert code == 0
    assert "would have been regressions (1)" in out and key(r) in out
    stored = json.loads(baseline.read_text())
    assert stored["records"] == data["records"] and "--update" in stored["meta"]["command"]
    code, out, _ = gate(capsys, "--baseline", baseline, "--results", results)
    assert code == 0 and "known failures" in out and key(r) in out  # now a known failure
    # and the fixed check is an improvement, not a regression
    code, out, _ = gate(
        capsys, "--baseline", baseline, "--results", write(tmp_path, "c.json", clean)
    )
    assert code == 0 and f"{key(r)}: failed -> passed" in out


def test_timings_are_gated_only_as_same_run_ratios(baseline, clean, tmp_path, capsys):
    bench = synthetic_bench("slider_crank")
    results = write(tmp_path, "r.json", clean)
    code, out, _ = gate(
        capsys,
        "--baseline",
        baseline,
        "--results",
        results,
        "--bench",
        write(tmp_path, "b0.json", bench),
        "--update",
    )
    assert code == 0

    def variant(name, change):
        b = copy.deepcopy(bench)
        change(b)
        return gate(
            capsys,
            "--baseline",
            baseline,
            "--results",
            results,
            "--bench",
            write(tmp_path, name, b),
        )

    def scale(b, path, f):
        for r in b["forward"]:
            if path is None or r["path"] == path:
                r["us_per_state"] *= f
                r["us_per_state_min"] *= f

    # a machine 10x slower everywhere: every same-run ratio unchanged
    code, out, _ = variant("slow_machine.json", lambda b: scale(b, None, 10))
    assert code == 0, out
    # one path 3x slower than before relative to Pinocchio: inside the generous band
    code, out, _ = variant("noise.json", lambda b: scale(b, "single", 3))
    assert code == 0, out
    # one path 20x slower: a regression, named with its anchor
    code, out, _ = variant("slower.json", lambda b: scale(b, "single", 20))
    found = regressions(out)
    assert (
        code == 1
        and len(found) == 1
        and found[0].startswith("timing slider_crank/single/engine:pinocchio")
    ), out

    # work-precision accuracy: an error 100x worse, and a row gone
    def wp(b):
        b["work_precision"][0]["error"] *= 100
        del b["work_precision"][-1]

    code, out, _ = variant("wp.json", wp)
    found = regressions(out)
    assert code == 1 and len(found) == 2, out
    assert any("error" in ln and "worse than" in ln for ln in found)
    assert any("missing from the bench" in ln for ln in found)
    # without --bench the timings are not compared, and the gate says so
    code, out, _ = gate(capsys, "--baseline", baseline, "--results", results)
    assert code == 0 and "benchmarks not compared" in out


@pytest.mark.parametrize(
    "argv,needle",
    [
        (["--baseline", "{tmp}/none.json", "--results", "{clean}"], "--update"),
        (["--baseline", "{tmp}/bad.json", "--results", "{clean}"], "not valid JSON"),
        (["--baseline", "{base}", "--results", "{tmp}/norecords.json"], 'no "records" list'),
        (
            ["--baseline", "{base}", "--results", "{clean}", "--bench", "{tmp}/none.json"],
            "not found",
        ),
        (["--baseline", "{base}", "--results", "{clean}", "--factor", "0.5"], "--factor"),
    ],
)
def test_usage_errors_are_one_line_and_exit_2(
    baseline, tmp_path, tmp_path_factory, capsys, argv, needle
):
    (tmp_path / "bad.json").write_text("{nope")
    (tmp_path / "norecords.json").write_text('{"meta": {}}')
    subst = {"tmp": tmp_path, "clean": results_of(tmp_path_factory, "clean"), "base": baseline}
    code, out, err = gate(capsys, *[a.format(**subst) for a in argv])
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("crosscheck: error:") and needle in err
