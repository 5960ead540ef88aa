"""An MJCF file whose initial state is off its constraint manifold: refused with the option that
projects it named, projected with --project (positions and velocities), and the records say by
how much. Real MuJoCo and Pinocchio, no mocks.

Files: tests/data/loop_keyframe.xml (this project's four-bar with a keyframe off the manifold
in qpos and qvel) and MuJoCo's connect.xml (tests/data/real/mujoco_connect.xml, provenance in
its header: three free beams whose qpos0 violates the connects by 0.3).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from crosscheck.cli import main
from reference.errors import OffManifoldError
from reference.mjcf.checks import violation
from reference.mjcf.loader import import_mjcf, qvel_from_rates

DATA = Path(__file__).with_name("data")
LOOP = DATA / "loop_keyframe.xml"
CONNECT = DATA / "real" / "mujoco_connect.xml"
# a projected state is on the manifold to the projection's own tolerance (1e-14 (1 + |q|)
# in reference.mjcf.checks.project_state), far below the 1e-9 a file is checked against
ON_MANIFOLD = 1e-12


def test_an_initial_state_off_the_manifold_names_the_option(tmp_path, capsys):
    with pytest.raises(OffManifoldError, match=r"by 6\.967e-01 .*--project on the command line"):
        import_mjcf(LOOP)
    out = tmp_path / "out"
    assert main(["run", "--model-file", str(LOOP), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--project" in err
    assert not out.exists()


@pytest.mark.parametrize(
    "path, violated", [(LOOP, 0.6967), (CONNECT, 0.3)], ids=["loop", "connect"]
)
def test_project_moves_positions_and_velocities_onto_the_manifold(path, violated):
    imp = import_mjcf(path, project=True)
    m = imp.mj
    q = np.asarray(imp.model.initial_q)
    v = qvel_from_rates(imp.joints, q, np.asarray(imp.model.initial_u), m.nv)
    assert violation(m, q, v) <= ON_MANIFOLD
    assert imp.projection["violation"] == pytest.approx(violated, rel=1e-4)
    assert imp.projection["position_change"] > 0
    if path == LOOP:  # the keyframe's velocities violate the loop's velocity rows too
        assert imp.projection["velocity_change"] == pytest.approx(0.5135, rel=1e-3)


def test_the_records_say_by_how_much(tmp_path):
    """--project on `run`: every record of the four-bar passes and its model_file record
    carries the projection."""
    code = main(
        ["run", "--model-file", str(LOOP), "--project", "--engines", "mujoco,pinocchio",
         "--states", "3", "--t-end", "0.5", "--no-report", "--out", str(tmp_path)]
    )  # fmt: skip
    assert code == 0
    records = json.loads((tmp_path / "results.json").read_text())["records"]
    (note,) = [r for r in records if r["quantity"] == "model_file"]
    assert note["projection"] == pytest.approx(
        {"violation": 0.6967, "position_change": 0.07334, "velocity_change": 0.5135}, rel=1e-3
    )
    assert "initial state projected onto the constraint manifold (--project)" in note["reason"]


@pytest.mark.parametrize(
    "command", [["sweep"], ["bench"], ["sensitivity"], ["models"], ["eval", "loop_keyframe"]]
)
def test_every_command_that_loads_files_refuses_without_project(command, tmp_path, capsys):
    """run, sweep, bench, sensitivity, models and eval refuse the file alike, naming the
    option (eval's own --project, which projects the evaluated state, does it there)."""
    assert main([*command, "--model-file", str(LOOP)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--project" in err


def test_sweep_with_project(tmp_path):
    assert main(
        ["sweep", "--model-file", str(LOOP), "--project", "--engines", "mujoco,pinocchio",
         "--samples", "5", "--out", str(tmp_path)]
    ) == 0  # fmt: skip
    status = json.loads((tmp_path / "sweep.json").read_text())["status"]
    assert status["completed"] == {"loop_keyframe": 5} and status["passed"]
