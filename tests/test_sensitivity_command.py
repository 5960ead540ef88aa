"""`crosscheck sensitivity` on the three cross-check models: every parameter an engine's model
uses is caught below 1e-8 relative; one it does not use is reported with that reason."""

from __future__ import annotations

import functools
import json

import pytest

from crosscheck.checks.sensitivity import engine_thresholds
from crosscheck.cli import main
from crosscheck.commands.sensitivity import DEFAULT_MODELS
from reference import models

CAUGHT_BY = 1e-8  # the bar: an error of 1e-8 in any used parameter must fail a record
ENGINES = ("pinocchio", "mujoco", "exudyn", "opensim")

thresholds = functools.cache(engine_thresholds)  # one search per model and engine


def _cases():
    for name in DEFAULT_MODELS:
        for engine in ENGINES:
            for p in models.get(name).parameters:
                key = (name, engine, p.name)
                yield pytest.param(*key, id="-".join(key))


@pytest.mark.parametrize(("name", "engine", "parameter"), list(_cases()))
def test_every_used_parameter_is_caught_below_1_e_8(name, engine, parameter):
    """Every parameter the engine's model uses (its fingerprint changes with it) is caught at
    1e-8 or below, by an instantaneous check or, where none sees it, by a trajectory record."""
    rows = {t.parameter: t for t in thresholds(name, engine)}
    t = rows[parameter]
    if t.caught_at is None:
        assert t.reason.startswith("not used by the engine's model"), t
    else:
        assert t.caught_at <= CAUGHT_BY, t
        assert t.failing_check.startswith(f"{name}/{engine}/{t.comparison}/"), t


def test_unused_parameter_is_named():
    """Pinocchio's pendulum_xy is written in (x, y) with the row x x' + y y' = 0: L enters
    only through the states, so changing it in the engine changes nothing."""
    rows = {t.parameter: t for t in thresholds("pendulum_xy", "pinocchio")}
    assert rows["L"].caught_at is None and "not used" in rows["L"].reason
    assert rows["m"].caught_at is not None


@pytest.mark.parametrize("engine", ["exudyn", "opensim"])
def test_parameter_unseen_at_consistent_states_is_searched_on_trajectories(engine):
    """Exudyn's and OpenSim's pendulum_xy hold L as the rod's length (their fingerprint
    changes with it), but at states the reference made consistent no acceleration-level figure
    depends on it: the search repeats `crosscheck run`'s trajectory comparison instead, and
    the threshold names the trajectory record that caught it and the run that reproduces it."""
    rows = {t.parameter: t for t in thresholds("pendulum_xy", engine)}
    L = rows["L"]
    assert L.comparison == "trajectory" and L.caught_at is not None, L
    assert L.failing_check.startswith(f"pendulum_xy/{engine}/trajectory/"), L
    assert L.reason.startswith("no instantaneous check sees it"), L
    assert f"--perturb {engine}:L=" in L.reason and "5 s" in L.reason
    assert rows["m"].comparison == "instantaneous"


def test_command_writes_json(tmp_path, capsys):
    assert (
        main(["sensitivity", "pendulum_angle", "--engines", "pinocchio", "--out", str(tmp_path)])
        == 0
    )
    doc = json.loads((tmp_path / "sensitivity.json").read_text())
    assert {t["parameter"] for t in doc["thresholds"]} == {"m", "L", "g"}
    assert "pendulum_angle" in capsys.readouterr().out


def test_report_marks_a_parameter_caught_by_a_trajectory(tmp_path):
    """The report's table marks a threshold found by the trajectory comparison, and its cell's
    title names the trajectory record and how the search ran."""
    import html
    from types import SimpleNamespace

    from crosscheck.report.sections import sensitivity as report_sensitivity

    out = str(tmp_path)
    args = ["sensitivity", "pendulum_xy", "--engines", "opensim", "--states", "1", "--out", out]
    assert main(args) == 0
    doc = json.loads((tmp_path / "sensitivity.json").read_text())
    L = next(t for t in doc["thresholds"] if t["parameter"] == "L")
    assert L["comparison"] == "trajectory" and "/trajectory/" in L["failing_check"]
    c = SimpleNamespace(results_path=str(tmp_path / "results.json"))
    page = report_sensitivity.html(c)
    assert f"{L['caught_at']:.0e} (trajectory)" in page
    assert html.escape(L["failing_check"], quote=True) in page
    assert f"{L['caught_at']:.0e} (trajectory)" in "\n".join(report_sensitivity.md(c))
