"""MuJoCo's soft trajectories are judged against the rigid limit (crosscheck.checks.trajectory.soft,
SOFT_LIMIT_*): its runs at solref tc and tc/2 extrapolated to tc -> 0 agree with the reference
within the extrapolation's own bound, and a 1 % mass error, which the soft effect used to hide
(state error 2.8e-4 under a one-size tolerance of 5e-2), fails there."""

from __future__ import annotations

import json

from crosscheck.checks.trajectory.check import trajectory_records
from crosscheck.cli import main
from crosscheck.engines.mujoco.adapter import MujocoAdapter
from reference import models
from reference.numeric.model import NumericModel


def _mujoco_trajectory(records):
    return {
        r["quantity"]: r for r in records if r["engine"] == "mujoco" and r["check"] == "trajectory"
    }


def test_unperturbed_slider_crank_passes_its_rigid_limit():
    nm = NumericModel(models.get("slider_crank"))
    records, _ = trajectory_records("slider_crank", nm, [MujocoAdapter()])
    traj = _mujoco_trajectory(records)
    limit = traj["state_error_rigid_limit"]
    assert limit["passed"] and traj["state_error"]["passed"], limit
    # the tolerance is the model's own (derived in the run), not one value for all models
    assert limit["tolerance"] < 1e-3 and "correction" in limit["reason"]


def test_one_percent_mass_error_fails_a_trajectory_record(tmp_path, capsys):
    """The command that once failed: `crosscheck run slider_crank --engines mujoco --perturb
    mujoco:m3=1e-2` exits non-zero, and a trajectory record is among its failures."""
    code = main(
        [
            "run",
            "slider_crank",
            "--engines",
            "mujoco",
            "--perturb",
            "mujoco:m3=1e-2",
            "--no-report",
            "--out",
            str(tmp_path),
        ]
    )
    capsys.readouterr()
    assert code != 0
    records = json.loads((tmp_path / "results.json").read_text())["records"]
    failed = [q for q, r in _mujoco_trajectory(records).items() if r["passed"] is False]
    assert "state_error_rigid_limit" in failed, failed
