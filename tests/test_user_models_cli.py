"""`--model-file` on the commands: user models beside the built-in ones."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from crosscheck.cli import main

DATA = Path(__file__).parent / "data"
FOURBAR = str(DATA / "fourbar_connect.xml")
PYFILE = str(DATA / "user_mechanism.py")


def test_models_lists_user_models_with_origin(capsys):
    assert main(["models", "--model-file", FOURBAR, "--model-file", PYFILE]) == 0
    out = capsys.readouterr().out
    rows = {line.split()[0]: line for line in out.splitlines()[1:]}
    assert "pendulum_angle" in rows and "built-in" in rows["pendulum_angle"]
    assert "fourbar_connect.xml (MJCF)" in rows["fourbar_connect"]
    assert "user_mechanism.py:models()" in rows["driven_pendulum"]


def test_models_json_has_origin(capsys):
    assert main(["models", "--json", "--model-file", FOURBAR]) == 0
    described = {d["name"]: d for d in json.loads(capsys.readouterr().out)}
    assert described["fourbar_connect"]["origin"] == "fourbar_connect.xml (MJCF)"
    assert described["fourbar_connect"]["coordinates"] == ["A", "P", "B"]
    assert described["slider_crank"]["origin"] == "built-in"


def test_run_with_model_file_runs_only_its_models(tmp_path, capsys):
    code = main(
        [
            "run",
            "--model-file",
            FOURBAR,
            "--engines",
            "mujoco",
            "--states",
            "2",
            "--instantaneous",
            "--no-report",
            "--out",
            str(tmp_path),
        ]
    )
    assert code == 0, capsys.readouterr().err
    records = json.loads((tmp_path / "results.json").read_text())["records"]
    assert {r["model"] for r in records} == {"fourbar_connect"}
    formulations = [
        r for r in records if r["check"] == "formulations" and r["quantity"] == "accelerations"
    ]
    assert formulations and all(r["passed"] for r in formulations)


def test_eval_user_model(capsys):
    assert main(["eval", "fourbar_connect", "--model-file", FOURBAR, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"] == "fourbar_connect" and len(out["accelerations"]) == 3


def test_bad_xml_is_one_line_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body")
    assert main(["run", "--model-file", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("crosscheck: error:") and "MuJoCo rejects" in err
    assert len(err.splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_same_file_twice_is_a_name_clash(capsys):
    assert main(["models", "--model-file", FOURBAR, "--model-file", FOURBAR]) == 2
    err = capsys.readouterr().err
    assert "already used" in err and len(err.strip().splitlines()) == 1


def test_python_file_without_hook(tmp_path, capsys):
    f = tmp_path / "nothing.py"
    f.write_text("x = 1\n")
    assert main(["models", "--model-file", str(f)]) == 2
    assert "defines no models() function" in capsys.readouterr().err


def test_unknown_model_name_lists_user_models(capsys):
    assert main(["run", "nope", "--model-file", FOURBAR, "--out", "/tmp/unused"]) == 2
    assert "fourbar_connect" in capsys.readouterr().err


@pytest.mark.slow  # three formulations of a 9-coordinate model derived cold: a minute or two
def test_gripper_compared_up_to_its_dead_centre(tmp_path, capsys):
    """The ten-body gripper reaches a dead centre at t = 0.72 s, where its constraint
    rows lose rank and the motion past it is not unique. The trajectories are compared up to
    just before it, and a skipped record says where and why the requested second was cut."""
    code = main(
        [
            "run",
            "--model-file",
            str(DATA / "gripper.xml"),
            "--engines",
            "mujoco",
            "--states",
            "1",
            "--t-end",
            "1",
            "--no-report",
            "--out",
            str(tmp_path),
        ]
    )
    assert code == 0, capsys.readouterr().err
    records = json.loads((tmp_path / "results.json").read_text())["records"]
    traj = [r for r in records if r["check"] == "trajectory"]
    (horizon,) = [r for r in traj if r["quantity"] == "horizon"]
    assert horizon["skipped"] and horizon["t_requested"] == 1.0
    assert "singular pose at t = 0.72" in horizon["reason"], horizon["reason"]
    assert 0.7 <= horizon["t_end"] < 0.72
    compared = [r for r in traj if r["quantity"] == "state_error"]
    assert {r["engine"] for r in compared} == {"reference", "mujoco"}
    assert all(r["t_end"] == horizon["t_end"] for r in traj)
    ref = next(r for r in compared if r["engine"] == "reference")
    assert ref["passed"] is True
    instantaneous = [r for r in records if r["check"] != "trajectory"]
    assert instantaneous and all(r["passed"] is not False for r in instantaneous)
