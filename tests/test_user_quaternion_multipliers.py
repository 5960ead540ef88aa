"""Multipliers and constraint forces of users' MJCF files with free and ball joints: the connect,
weld and joint rows compared with Pinocchio's and MuJoCo's (rigid recovery and soft
prediction, welds included), A^T lambda too, only the quaternions' unit-norm rows left out; the
mass matrix compared in the engine's own speeds. Real MuJoCo and Pinocchio, no mocks.

Files: tests/data/free_weld.xml (this project's: a free payload welded to a swinging arm), and
MuJoCo's own (tests/data/real/, provenance in their headers): soft_weld.xml (a free body welded
to the world, solimp clamped by MuJoCo), weld.xml (five free beams welded five ways, torquescale
0.002 and 0 among them) and connect.xml (three free beams on connects), the last two loaded
with --project.
"""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

from crosscheck.cli import main
from crosscheck.engines.mujoco.soft_prediction import documented_R
from crosscheck.engines.registry import get_engine
from crosscheck.user_models import load_all, register_all

DATA = Path(__file__).with_name("data")
REAL = DATA / "real"
FREE_WELD = DATA / "free_weld.xml"


def _run(tmp_path, path: Path, *extra: str) -> list[dict]:
    code = main(
        ["run", "--model-file", str(path), *extra, "--engines", "mujoco,pinocchio", "--states",
         "3", "--instantaneous", "--no-report", "--out", str(tmp_path)]
    )  # fmt: skip
    records = json.loads((tmp_path / "results.json").read_text())["records"]
    assert code == 0, [r for r in records if r["passed"] is False]
    return [r for r in records if r["check"] == "instantaneous"]


def _by(records, engine, quantity) -> dict:
    (rec,) = [r for r in records if (r["engine"], r["quantity"]) == (engine, quantity)]
    return rec


def test_a_free_body_held_by_a_weld(tmp_path):
    """free_weld: every engine's multipliers on the weld's six rows and A^T lambda pass, with
    the payload's norm row named as left out; MuJoCo's raw answer is judged against its
    prediction on the weld rows; the mass matrices are compared in the engines' speeds."""
    records = _run(tmp_path, FREE_WELD)
    for engine in ("mujoco", "pinocchio"):
        for quantity in ("multipliers", "constraint_forces"):
            rec = _by(records, engine, quantity)
            assert rec["passed"] and rec["rows_left_out"] == ["payload_norm"]
            assert "rows left out: payload_norm" in rec["reason"]
        mass = _by(records, engine, "mass_matrix")
        assert mass["passed"] and "engine's own speeds" in mass["answer"]
    for quantity in ("accelerations", "multipliers"):
        assert _by(records, "mujoco", f"{quantity}_soft_vs_predicted")["passed"]


@pytest.mark.parametrize(
    "path",
    [
        FREE_WELD,
        REAL / "mujoco_weld.xml",
        REAL / "mujoco_armature_equivalence.xml",
        REAL / "mujoco_soft_weld.xml",
    ],
)
def test_documented_R_is_mujocos_on_weld_and_joint_rows(path):
    """R = (1 - d)/d A_diag from solimp (clamped as MuJoCo clamps it) at the constraint's
    violation and the inverse weights equals MuJoCo's efc_R on weld rows (translational and
    rotational weights, torquescale 0.002 and 0) and joint rows (dof weights), and where
    MuJoCo clamps solimp (soft_weld.xml: "0 0.96 0.01" gives 0.0001 at rest)."""
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(3)
    for _ in range(3):
        d.qpos[:] = m.qpos0 + 0.1 * rng.standard_normal(m.nq)
        mujoco.mj_normalizeQuat(m, d.qpos)
        mujoco.mj_forward(m, d)
        assert np.allclose(documented_R(m, d), d.efc_R[: d.nefc], rtol=1e-12, atol=0)


@pytest.mark.slow  # a real file through the CLI: about 3 s warm (R: test_documented_R_...)
def test_soft_weld_with_mujocos_clamped_impedance(tmp_path):
    """MuJoCo's soft_weld.xml: solimp "0 0.96 0.01" gives an impedance of 0.0001 at rest, so
    the weld is nearly absent from the raw answer; the prediction still matches it, and the
    rigid recovery matches the reference."""
    records = _run(tmp_path, REAL / "mujoco_soft_weld.xml")
    judged = [r for r in records if not r["skipped"]]
    assert all(r["passed"] for r in judged)
    assert _by(records, "mujoco", "multipliers_soft_vs_predicted")["passed"]
    assert _by(records, "pinocchio", "multipliers")["rows_left_out"] == ["joint0_norm"]


@pytest.mark.slow  # five free bodies with 30 weld rows: about a minute's derivation cold
def test_mujocos_weld_file_projected(tmp_path):
    """MuJoCo's weld.xml with --project: the torquescale-0 weld's three rows (zero in MuJoCo,
    absent in the reference) and the torquescale-0.002 weld's (rows 1e-3 of the others, which
    the rigid recovery solves equilibrated) all pass."""
    records = _run(tmp_path, REAL / "mujoco_weld.xml", "--project")
    for engine in ("mujoco", "pinocchio"):
        assert _by(records, engine, "multipliers")["passed"]
        assert len(_by(records, engine, "multipliers")["rows_left_out"]) == 5


@pytest.mark.slow
def test_mujocos_connect_file_projected(tmp_path):
    records = _run(tmp_path, REAL / "mujoco_connect.xml", "--project")
    for engine in ("mujoco", "pinocchio"):
        for quantity in ("multipliers", "constraint_forces", "mass_matrix"):
            assert _by(records, engine, quantity)["passed"]


def test_constraint_forces_are_compared_in_the_engines_speeds():
    """A^T lambda in quaternion rates has a component along each quaternion that its norm row's
    multiplier absorbs (a weld anchored off the body's origin): in the engines' speeds, H^T
    A^T lambda, it is gone, and the engine's J^T f equals it."""
    from crosscheck.checks.instantaneous import reference_answer
    from crosscheck.checks.sampling import consistent_states
    from reference import NumericModel, models

    (um,) = load_all([FREE_WELD], entry_points=False)
    register_all([um])
    nm = NumericModel(models.get(um.name))
    q, u = consistent_states(nm, 2)[1]
    ref = reference_answer(nm, q, u)
    rows = [i for i, n in enumerate(nm.model.constraint_names) if not n.endswith("_norm")]
    in_rates = ref.constraint_matrix[rows].T @ ref.multipliers[rows]
    ef = get_engine("pinocchio").build(um.name, {}).forward(q, u)
    H = ef.speed_map
    assert np.max(np.abs(H.T @ in_rates - ef.constraint_forces)) < 1e-11
    quat = slice(4, 8)  # the payload's quaternion (after the hinge and its position)
    assert abs(np.asarray(q)[quat] @ in_rates[quat]) > 1e-2  # along q: what H^T removes


def test_a_quaternion_and_its_negative_give_the_same_weld_multipliers():
    """MuJoCo's weld rotation rows take the sign of the relative quaternion the state happens
    to have (q and -q are one rotation): with the payload's quaternion negated, its recovered
    multipliers still equal the reference's and Pinocchio's."""
    from crosscheck.checks.sampling import consistent_states
    from crosscheck.checks.tolerances import RIGID_RECOVERY, scaled_error
    from reference import NumericModel, models

    (um,) = load_all([FREE_WELD], entry_points=False)
    register_all([um])
    nm = NumericModel(models.get(um.name))
    q, u = (np.array(x, float) for x in consistent_states(nm, 2)[1])
    quat = slice(4, 8)  # the payload's quaternion, after the hinge and its position
    for sign in (1.0, -1.0):  # w > 0, then the same rotation with w < 0 (rates flipped too)
        flip = sign * np.sign(q[4])
        q[quat], u[quat] = flip * q[quat], flip * u[quat]
        assert np.sign(q[4]) == sign
        ref = nm.forward(q, u).multipliers[:6]
        mj = get_engine("mujoco").build(um.name, {}).forward(q, u).rigid_multipliers[:6]
        assert scaled_error(mj, ref) <= RIGID_RECOVERY.value, sign


def test_a_file_whose_only_rows_are_norm_rows_compares_no_multipliers(tmp_path):
    """A free body and a ball pendulum, no equality: every row is a quaternion's norm row, so
    the multipliers record is skipped (saying why), not judged on nothing."""
    from crosscheck.checks.instantaneous import engine_records
    from crosscheck.checks.sampling import consistent_states
    from reference import NumericModel, models

    path = tmp_path / "tumbling.xml"
    path.write_text("""<mujoco model="tumbling"><option><flag contact="disable"/></option>
      <worldbody><body name="b" pos="0 0 1"><freejoint/><geom type="box" size=".1 .2 .3"/></body>
      <body name="p" pos="1 0 1"><joint type="ball"/>
        <geom type="capsule" fromto="0 0 0 .3 0 -.3" size=".03"/></body></worldbody></mujoco>""")
    (um,) = load_all([path], entry_points=False)
    register_all([um])
    nm = NumericModel(models.get(um.name))
    states = consistent_states(nm, 2)
    for engine in ("mujoco", "pinocchio"):
        records = engine_records(um.name, nm, states, get_engine(engine), {})
        (lam,) = [r for r in records if r["quantity"] == "multipliers"]
        assert lam["skipped"] and lam["reason"].endswith("no other constraint rows")
        assert all(r["passed"] is not False for r in records)
