"""The horizon trajectories are compared on when the reference reaches a singular pose (
the IFToMM A02 four-bars lying flat): cut just before the first such pose, said in a record."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from crosscheck.checks.trajectory.horizon import (
    HORIZON_MARGIN,
    HORIZON_QUANTUM,
    crossed,
    horizon_before,
    singular_time,
)
from crosscheck.cli import main
from reference.errors import ModelInputError, SingularSystemError

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "examples" / "a02"))
from nfourbar import mjcf


@pytest.mark.parametrize(
    ("t_sing", "t_end", "expected"),
    [(0.714354, 10.0, 0.707), (5.11319, 10.0, 5.062), (12.0, 10.0, 10.0), (0.0005, 1.0, None)],
)
def test_horizon_is_whole_milliseconds_short_of_the_pose(t_sing, t_end, expected):
    got = horizon_before(t_sing, t_end)
    if expected is None:
        assert got is None
        return
    assert got == pytest.approx(expected, abs=1e-12)
    assert got <= t_sing * (1 - HORIZON_MARGIN) + 1e-12
    assert abs(got / HORIZON_QUANTUM - round(got / HORIZON_QUANTUM)) < 1e-9


def test_only_a_singular_pose_with_its_time_cuts_the_horizon():
    err = SingularSystemError("at t = 1: singular")
    assert singular_time(err) is None  # no time: not a run that reached a pose
    err.t_singular = 1.0
    assert singular_time(err) == 1.0
    other = ModelInputError("bad")
    other.t_singular = 1.0  # type: ignore[attr-defined]
    assert singular_time(other) is None


class _Run:
    def __init__(self, stats):
        self.stats = stats


def test_a_step_across_the_pose_counts_like_a_refusal():
    crossed(_Run({}))  # no crossing: nothing raised
    with pytest.raises(SingularSystemError, match="lost rank between two accepted steps") as e:
        crossed(_Run({"rank_crossings_t": [2.5, 4.0]}))
    assert e.value.t_singular == 2.5


def test_a02_one_cell_is_compared_up_to_its_first_flat_pose(tmp_path, capsys):
    """At rtol 1e-12 the one-cell four-bar reaches its first flat pose at t = 0.708 s (the
    constraint rows lose rank: rank 1 of 2); the run compares the engines on [0, 0.701] s."""
    path = tmp_path / "a02_1.xml"
    path.write_text(mjcf(1))
    argv = ["run", "--model-file", str(path), "--engines", "pinocchio", "--states", "1"]
    code = main([*argv, "--t-end", "3", "--no-report", "--out", str(tmp_path / "out")])
    assert code == 0, capsys.readouterr().err
    records = json.loads((tmp_path / "out" / "results.json").read_text())["records"]
    traj = [r for r in records if r["check"] == "trajectory"]
    (horizon,) = [r for r in traj if r["quantity"] == "horizon"]
    assert horizon["skipped"] and horizon["t_requested"] == 3.0
    assert "lose rank" in horizon["reason"] and "not unique" in horizon["reason"]
    assert all(r["t_end"] == horizon["t_end"] == 0.701 for r in traj)
    pin = next(r for r in traj if r["engine"] == "pinocchio" and r["quantity"] == "state_error")
    assert pin["passed"] is True
