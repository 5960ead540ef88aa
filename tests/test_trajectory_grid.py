"""Short horizons: the reference, Pinocchio and both MuJoCo rungs share one output grid for
every t_end > 0."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from crosscheck.checks.trajectory.check import FIXED_STEPS, N_OUT, output_grid, step_ladder
from crosscheck.cli import main


@pytest.mark.parametrize("t_end", [5.0, 1.0, 0.13, 0.1, 0.01, 0.1234, 1.009, 1e-3, 1e-9, 999.9])
def test_grid_lies_on_both_mujoco_rungs(t_end):
    h0, h1 = step_ladder(t_end)
    assert h0 <= FIXED_STEPS[0] and h1 == pytest.approx(h0 / 2, rel=1e-15)
    grid = output_grid(t_end)
    assert grid[0] == 0.0 and grid[-1] == pytest.approx(t_end, rel=1e-12)
    assert 2 <= len(grid) <= N_OUT and np.all(np.diff(grid) > 0)
    for h in (h0, h1):  # every output time is a whole number of steps of either rung
        steps = grid / h
        assert np.max(np.abs(steps - np.round(steps))) < 1e-6
        assert round(t_end / h) == round(steps[-1])  # and the rung ends at t_end


def test_five_seconds_keeps_the_20_ms_grid():
    grid = output_grid(5.0)
    assert step_ladder(5.0) == FIXED_STEPS
    assert np.array_equal(grid, np.linspace(0.0, 5.0, N_OUT))


@pytest.mark.parametrize("t_end", ["0.13", "1e-9"])
def test_short_horizon_runs_with_mujoco(tmp_path, capsys, t_end):
    out = tmp_path / "o"
    code = main(
        [
            "run",
            "pendulum_angle",
            "--engines",
            "mujoco,pinocchio",
            "--t-end",
            t_end,
            "--out",
            str(out),
            "--no-report",
        ]
    )
    assert code == 0, capsys.readouterr().err
    res = json.loads((out / "results.json").read_text())
    traj = [r for r in res["records"] if r["check"] == "trajectory" and r["engine"] == "mujoco"]
    assert traj and all(r["passed"] for r in traj)
    h0 = step_ladder(float(t_end))[0]
    assert traj[0]["label"] == f"RK4 h={h0:g}"  # the step actually used is named
    series = [s for s in res["series"] if s["engine"] == "mujoco"]
    assert len(series) == 2  # MuJoCo's clock sums its steps: equal to round-off
    assert np.allclose(series[0]["t"], series[1]["t"], rtol=0, atol=1e-12 * float(t_end))
    assert math.isclose(series[0]["t"][-1], float(t_end), rel_tol=1e-9)
