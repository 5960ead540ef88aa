"""Actuators of users' MJCF files at a stated control: MuJoCo's gain and bias force, a load on
the joint (reference.mjcf.actuators), held to mj_forward's qfrc_actuator; the controls
(default 0, keyframe 0's ctrl, --ctrl NAME=VALUE); what is refused, by name. Real MuJoCo and
Pinocchio, no mocks.

TOL_QFRC = 1e-14 relative to max(1, |qfrc_actuator|): the same products and sums as MuJoCo's
mj_fwdActuation in another order, a few ulps. Measured (this file's first test, 20 random states
and controls per file): robot_arm 6.7e-16, MuJoCo's armature_equivalence 0, its
tendon_dampratio 2.2e-16 (python -m pytest -q tests/test_actuators.py -k qfrc -s prints them).
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from crosscheck.cli import main
from crosscheck.user_models import load_all, register_all
from reference.errors import ModelFileError, UnsupportedModelError
from reference.mjcf.actuators import actuation, stated_controls
from reference.mjcf.loader import import_mjcf

DATA = Path(__file__).with_name("data")
REAL = DATA / "real"
ARM = DATA / "robot_arm.xml"
TOL_QFRC = 1e-14


@pytest.mark.parametrize(
    "path",
    [ARM, REAL / "mujoco_armature_equivalence.xml", REAL / "mujoco_tendon_dampratio.xml"],
    ids=lambda p: p.stem,
)
def test_qfrc_is_mujocos_at_any_state_and_control(path):
    """Position and velocity servos, a geared motor, an affine general actuator through a fixed
    tendon, dampratio servos through fixed tendons: gear F(L, V) on each joint equals MuJoCo's
    qfrc_actuator (no clamp reached at these states)."""
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(20):
        lo, hi = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
        ctrl = np.where(m.actuator_ctrllimited, rng.uniform(lo, hi), rng.normal(size=m.nu))
        names = [m.actuator(a).name for a in range(m.nu)]
        act, refused = actuation(m, stated_controls(m, dict(zip(names, ctrl, strict=True))))
        assert refused == []
        d.qpos[:] = m.qpos0 + 0.3 * rng.standard_normal(m.nq)
        d.qvel[:] = 0.5 * rng.standard_normal(m.nv)
        d.ctrl[:] = ctrl
        mujoco.mj_forward(m, d)
        ours = act.qfrc(d.qpos, d.qvel, m.nv)
        scale = max(1.0, float(np.max(np.abs(d.qfrc_actuator))))
        worst = max(worst, float(np.max(np.abs(ours - d.qfrc_actuator))) / scale)
    print(f"\n{path.stem}: worst relative qfrc_actuator difference {worst:.1e}")
    assert worst <= TOL_QFRC


def test_controls_default_keyframe_and_stated(tmp_path):
    """0 without a keyframe, keyframe 0's ctrl with one, a stated control over both; a name the
    file has no actuator of, or a control outside a limited ctrlrange, is one line."""
    m = mujoco.MjModel.from_xml_path(str(ARM))
    assert stated_controls(m) == {
        "shoulder_servo": 0.2,
        "elbow_damper": 0.0,
        "wrist_motor": 0.5,
        "tendon_drive": 0.1,
    }
    assert stated_controls(m, {"wrist_motor": -1.0})["wrist_motor"] == -1.0
    bare = mujoco.MjModel.from_xml_path(str(REAL / "mujoco_armature_equivalence.xml"))
    assert stated_controls(bare) == {"link1": 0.0, "link2": 0.0}
    with pytest.raises(ModelFileError, match=r"--ctrl knee: no such actuator.*shoulder_servo"):
        stated_controls(m, {"knee": 1.0})
    with pytest.raises(ModelFileError, match=r"'wrist_motor': the control 3 \(--ctrl\) is outside"):
        stated_controls(m, {"wrist_motor": 3.0})


def test_actuators_the_reference_cannot_express_are_named(tmp_path):
    """MuJoCo's slider_crank.xml drives its cranks with position servos through slider-crank
    transmissions: refused in one line naming the three; a motor on such a transmission at
    control 0 applies no force and is left out with a note."""
    with pytest.raises(UnsupportedModelError) as err:
        import_mjcf(REAL / "mujoco_slider_crank.xml")
    assert "3 actuators have a slidercrank transmission: forward, backward, broken" in str(
        err.value
    )
    path = tmp_path / "idle.xml"
    path.write_text(
        (REAL / "mujoco_slider_crank.xml")
        .read_text()
        .replace('<position name="forward"', '<motor name="forward"')
        .replace('<position name="backward"', '<motor name="backward"')
        .replace('<position name="broken"', '<motor name="broken"')
    )
    imp = import_mjcf(path)
    assert imp.actuation.joint == ()
    assert "actuator 'forward' applies no force at its control 0" in imp.notes


def test_engines_agree_at_a_stated_control():
    """robot_arm with every actuator pushing (keyframe controls, the wrist's stated): MuJoCo
    computes its own actuator forces, Pinocchio is given the same load, and every record passes;
    the model_file record lists the controls."""
    from crosscheck.checks.instantaneous import engine_records
    from crosscheck.checks.sampling import draws
    from crosscheck.checks.user_file import file_record
    from crosscheck.engines.registry import get_engine
    from reference import NumericModel, models

    (um,) = load_all([ARM], entry_points=False, ctrl={"wrist_motor": -0.3})
    register_all([um])
    nm = NumericModel(models.get(um.name))
    drawn = draws(nm, 3)
    note = file_record(um.name, nm.formulation, drawn)
    assert note["controls"] == {
        "shoulder_servo": 0.2,
        "elbow_damper": 0.0,
        "wrist_motor": -0.3,
        "tendon_drive": 0.1,
    }
    for engine in ("mujoco", "pinocchio"):
        records = engine_records(um.name, nm, drawn.states, get_engine(engine), {})
        assert all(r["passed"] is not False for r in records), engine
        (acc,) = [r for r in records if r["quantity"] == "accelerations"]
        assert acc["passed"]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--ctrl", "knee=1"], "--ctrl knee: no actuator of that name in the model files"),
        (["--ctrl", "knee"], "argument --ctrl: 'knee': expected NAME=VALUE"),
        (["--ctrl", "wrist_motor=inf"], "the control must be finite"),
        (["--ctrl", "wrist_motor=1", "--ctrl", "wrist_motor=2"], "given more than once"),
    ],
)
def test_bad_controls_are_one_line_exit_2_and_nothing_written(tmp_path, capsys, args, message):
    out = tmp_path / "out"
    try:
        code = main(["run", "--model-file", str(ARM), *args, "--out", str(out)])
    except SystemExit as exc:  # argparse's own refusal, one line through OneLineParser
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count("\n") == 1
    assert not out.exists()


def test_a_control_needs_a_model_file(tmp_path, capsys):
    assert main(["run", "--ctrl", "a=1", "--out", str(tmp_path / "out")]) == 2
    assert "--ctrl sets the control of an actuator in a --model-file" in capsys.readouterr().err


def test_each_file_takes_the_controls_of_its_own_actuators():
    """With two files, a control goes to the file that has the actuator."""
    found = load_all(
        [ARM, REAL / "mujoco_armature_equivalence.xml"],
        entry_points=False,
        ctrl={"link1": 0.5, "wrist_motor": 0.25},
    )
    register_all(found)
    controls = {um.name: um.mjcf.actuation.controls for um in found}
    assert controls["robot_arm"]["wrist_motor"] == 0.25
    assert controls["mujoco_armature_equivalence"] == {"link1": 0.5, "link2": 0.0}
