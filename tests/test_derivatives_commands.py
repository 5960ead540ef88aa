"""The derivatives through the commands: `crosscheck run --derivatives` (results.json and the
report), `crosscheck sweep --derivatives` (a resumed campaign keeps the setting) and
`crosscheck sensitivity --derivatives` (the relative error each block's record catches)."""

from __future__ import annotations

import json
from pathlib import Path

from crosscheck.cli import main
from crosscheck.sweep.campaign import campaign
from crosscheck.sweep.config import Campaign
from crosscheck.sweep.store import ChunkStore

DATA = Path(__file__).parent / "data"
# Pinocchio's analytical derivatives are judged at most at the 1e-8 bar
# (crosscheck.checks.derivatives.tolerances.ANALYTIC_BAR): a relative error of that size in
# any of its blocks must fail that block's record
ANALYTIC_CAUGHT_BY = 1e-8


def test_run_writes_the_derivatives_records_and_reports_them(tmp_path, capsys):
    """Every block of the reference's and Pinocchio's derivatives on Exercise 6.1's loop: in
    results.json with the figures behind the tolerance, and in the report's tables."""
    argv = ["run", "exercise_6_1", "--engines", "pinocchio", "--instantaneous", "--states", "2"]
    code = main([*argv, "--derivatives", "--out", str(tmp_path)])
    assert code == 0, capsys.readouterr().out
    res = json.loads((tmp_path / "results.json").read_text())
    recs = [r for r in res["records"] if r["check"] == "derivatives"]
    blocks = {f"d{of}_{b}" for of in ("accelerations", "multipliers") for b in ("dq", "du", "dtau")}
    for engine in ("reference", "pinocchio"):
        mine = {r["quantity"]: r for r in recs if r["engine"] == engine}
        assert set(mine) == blocks and all(r["passed"] for r in mine.values()), engine
    pin = [r for r in recs if r["engine"] == "pinocchio"]
    assert all(r["kkt_condition"] >= 1 and "map_error" in r for r in pin)
    assert all(r["derivative_method"] == "computeConstraintDynamicsDerivatives" for r in pin)
    ref = [r for r in recs if r["engine"] == "reference"]
    assert all(r["difference_step"] > 0 and "truncation_estimate" in r for r in ref)
    report = (tmp_path / "report.md").read_text()
    for qty in blocks:
        assert f"| pinocchio | derivatives | {qty} |" in report, qty


def _interrupted(out, derivatives: bool) -> None:
    """A slider-crank campaign stopped by Ctrl-C after its first chunk, stored in out."""
    cfg = Campaign(["slider_crank"], 4, 3, engines=("opensim",), out=str(out))
    cfg.derivatives = derivatives

    def ctrl_c(res):
        raise KeyboardInterrupt

    part = campaign(cfg, workers=1, chunk=2, on_chunk=ctrl_c, store=ChunkStore(out, cfg))
    assert part["status"]["stopped"] == "interrupted"


def test_a_resumed_derivatives_campaign_keeps_the_setting(tmp_path, capsys):
    """A campaign with the derivatives comparison, stopped after its first chunk, resumes
    without the flag and still compares the derivatives at every sample; one stored without
    it refuses the flag on resume (one line, exit 2)."""
    _interrupted(tmp_path / "with", True)
    code = main(["sweep", "--resume", str(tmp_path / "with"), "--workers", "1"])
    assert code == 0, capsys.readouterr().out
    res = json.loads((tmp_path / "with" / "sweep.json").read_text())
    rows = [r for r in res["results"] if r["quantity"].startswith("d") and not r.get("skipped")]
    assert {r["quantity"] for r in rows} >= {"daccelerations_dq", "dmultipliers_du"}
    assert all(r["count"] == 4 and not r["outside_tolerance"] for r in rows)
    _interrupted(tmp_path / "without", False)
    capsys.readouterr()
    code = main(["sweep", "--resume", str(tmp_path / "without"), "--derivatives"])
    err = capsys.readouterr().err
    assert code == 2 and "(derivatives False)" in err and err.count("\n") == 1, err


def test_sensitivity_sizes_every_block_of_an_analytical_engine(tmp_path, capsys):
    """`crosscheck sensitivity --derivatives`: every block of Pinocchio's derivatives on
    Exercise 6.1's loop is caught at a relative error of at most 1e-8, by its own record."""
    argv = ["sensitivity", "exercise_6_1", "--engines", "pinocchio", "--states", "2"]
    code = main([*argv, "--derivatives", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0, out
    doc = json.loads((tmp_path / "sensitivity.json").read_text())
    rows = doc["derivative_thresholds"]
    assert len(rows) == 6, rows
    for r in rows:
        assert r["caught_at"] is not None and r["caught_at"] <= ANALYTIC_CAUGHT_BY, r
        assert r["failing_check"] == r["quantity"], r
    assert "6 derivative blocks" in out


def test_sweep_counts_a_sample_near_a_limit_at_a_shrunk_step(tmp_path, capsys):
    """A user's arm with joint limits: a differenced engine's sample whose stencil would reach
    the wrist's limit at the balanced step is differenced at a shrunk one and counted (no
    fault), as Pinocchio's own derivatives are at every sample."""
    argv = ["sweep", "--model-file", str(DATA / "robot_arm.xml"), "--samples", "6"]
    argv += ["--engines", "mujoco,pinocchio", "--workers", "1", "--derivatives"]
    code = main([*argv, "--out", str(tmp_path)])
    assert code == 0, capsys.readouterr().out
    res = json.loads((tmp_path / "sweep.json").read_text())
    rows = [r for r in res["results"] if r["quantity"] == "daccelerations_dq"]
    counts = {r["engine"]: r["count"] for r in rows}
    assert counts == {"pinocchio": 6, "mujoco": 6}, counts
    assert not res["faults"]["records"]
