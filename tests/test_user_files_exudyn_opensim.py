"""Exudyn and OpenSim on users' MJCF files: models built from MuJoCo's compiled model
(crosscheck.engines.exudyn.user_file, crosscheck.engines.opensim.user_file), checked against
the reference as the built-in models are: accelerations, multipliers and J^T lambda (dependent
rows: the minimum-norm multipliers), the mass matrix, energy, trajectories with the engines'
own integrators, fingerprints and --perturb, and a skip record naming what an engine's model
does not express."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from crosscheck.checks.instantaneous import engine_records
from crosscheck.checks.perturb import check_perturb_changes, perturbed
from crosscheck.engines.base import EngineModel, EngineUnsupported
from crosscheck.engines.registry import get_engine
from crosscheck.run.checks import consistent_states, run
from crosscheck.user_models import load_model_file, register_all
from reference import NumericModel, models
from reference.errors import ModelInputError
from tests.support import representative, scaled_error

DATA = Path(__file__).parent / "data"
ENGINES = ("exudyn", "opensim")
FILES = (
    "fourbar_connect.xml",  # a planar loop closed by a 3-D connect: one dependent row
    "weld_sites.xml",  # a site weld: 6 rows of rank 1
    "coupled_joints.xml",  # quadratic and linear joint equalities, springs, armature
    "mujoco_jdotv_connect_2d.xml",  # MuJoCo's test model: three joints on one body
    "mujoco_jdotv_weld_3d.xml",  # MuJoCo's test model: ball and free joints, a site weld
    "gripper.xml",  # two loops and two joint couplings, rank 6 of 8
)
QUICK = {"fourbar_connect.xml", "coupled_joints.xml"}
# Exudyn's bound for its extrapolated answer (EXUDYN_USER_FILES; measured 1.9e-12 on the
# four-bar), which holds OpenSim's (1e-11) too
EXACT = 1e-9


def _load(file: str):
    (name,) = register_all(load_model_file(DATA / file))
    return name, NumericModel(models.get(name))


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("file", representative(FILES, QUICK))
def test_user_file_passes_in_engine(file, engine):
    """Every judged instantaneous record passes at the run's seeded states, and the
    accelerations, multipliers, J^T lambda and the mass matrix are among them."""
    name, nm = _load(file)
    adapter = get_engine(engine)
    assert name in adapter.models()
    recs = engine_records(name, nm, consistent_states(nm, 3), adapter, nm.params)
    judged = {r["quantity"]: r for r in recs if r["passed"] is not None}
    expected = {"accelerations", "energy"}
    # with quaternions, M and lambda are compared where the checks take the engine's own
    # speeds and the rows it answers (EngineModel.mass_matrix_in_engine_speeds)
    if not nm.model.formulation_dependent_rows or hasattr(
        EngineModel, "mass_matrix_in_engine_speeds"
    ):
        expected |= {"mass_matrix", "multipliers"} if nm.m else {"mass_matrix"}
    assert expected <= set(judged), recs
    bad = [(r["quantity"], r["error"], r["tolerance"]) for r in judged.values() if not r["passed"]]
    assert not bad, bad


@pytest.mark.parametrize("engine", ENGINES)
def test_dependent_rows_give_the_minimum_norm_multipliers(engine):
    """The four-bar's connect has a dependent (out-of-plane) row: the engine reports rank 2
    of 3, and its multipliers are the minimum-norm ones (orthogonal to the null space of J^T,
    here the world Y row), equal to the reference's, with the same J^T lambda."""
    name, nm = _load("fourbar_connect.xml")
    em = get_engine(engine).build(name)
    for q, u in consistent_states(nm, 3):
        ef, ref = em.forward(q, u), nm.forward(q, u)
        assert ef.raw["rank"] == 2 and ref.rank == 2
        # the dependent row's share: round-off of the projection on forces of ~10 N
        assert abs(ef.multipliers[1]) < 1e-12
        assert scaled_error(ef.multipliers, ref.multipliers) < EXACT
        qpos, _ = em.mj_state(q, u)
        J = em.rows_jacobian(qpos)
        assert scaled_error(J.T @ ef.multipliers, J.T @ ref.multipliers) < EXACT
        # the engine's force lies in J^T's range: measured 8.9e-15 (OpenSim), 1.1e-14 (Exudyn)
        assert ef.raw["force_residual"] < EXACT
    if engine == "exudyn":  # Exudyn's KKT needs independent rows: two of three are kept
        assert ef.raw["rows_kept"] == 2


@pytest.mark.parametrize("engine", ENGINES)
def test_trajectory_follows_reference(engine):
    """Half a second of the four-bar with each engine's own first integrator, against the
    reference: generalized-alpha at 1 ms (second order, with numerical damping: measured
    3.8e-6 rad and an energy wobble of 5.4e-6 relative) and RungeKuttaMerson at rtol 1e-10; the
    loop stays closed (Exudyn solves its rows every step)."""
    from reference.integrate.driver import simulate

    name, nm = _load("fourbar_connect.xml")
    m = models.get(name)
    q0, u0 = np.array(m.initial_q), np.array(m.initial_u)
    t = np.linspace(0.0, 0.5, 6)
    ref = simulate(nm, q0, u0, 0.5, "projection", rtol=1e-12, atol=1e-12, t_eval=t)
    em = get_engine(engine).build(name)
    # bounds ~10x the measured figures: generalized-alpha 3.8e-6 rad, its rows solved to
    # 6.7e-16, energy 5.4e-6 relative; RungeKuttaMerson 8.4e-11 rad, Simbody's projection
    # to 1.1e-11, energy 1.1e-11
    if engine == "exudyn":
        tr = em.simulate(q0, u0, t, integrator="generalized-alpha", timestep=1e-3)
        bound, drift, energy = 1e-4, 1e-12, 5e-5
    else:
        tr = em.simulate(q0, u0, t, integrator="RungeKuttaMerson", rtol=1e-10)
        bound, drift, energy = 1e-9, 1e-10, 1e-10
    assert tr.failure is None and tr.q.shape == (6, 3)
    assert np.max(np.abs(tr.q - ref.q)) < bound
    assert np.max(tr.violation) < drift
    assert np.ptp(tr.energy) < energy * max(1.0, abs(tr.energy[0]))


@pytest.mark.parametrize("engine", ENGINES)
def test_perturbed_number_is_caught_and_maps_stay(engine):
    """--perturb ENGINE:crank.mass=1e-6 changes the engine's model (its fingerprint) and fails
    its accelerations against the reference, while the state maps do not move; a number that
    is 0 in the file, or that the engine's model does not hold, is refused before any work."""
    name, nm = _load("fourbar_connect.xml")
    adapter = get_engine(engine)
    params = perturbed(name, nm.params, {"crank.mass": 1e-6})
    nominal, faulty = adapter.build(name), adapter.build(name, params)
    assert nominal.fingerprint() != faulty.fingerprint()
    q, u = consistent_states(nm, 2)[1]
    for a, b in zip(nominal.to_engine_state(q, u), faulty.to_engine_state(q, u), strict=True):
        assert np.array_equal(a, b)
    records, _ = run([name], [engine], n_states=2, perturb={engine: {"crank.mass": 1e-6}},
                     trajectories=False)  # fmt: skip
    failed = {r["quantity"] for r in records if r["engine"] == engine and r["passed"] is False}
    assert "accelerations" in failed, failed
    with pytest.raises(ModelInputError, match=r"A\.damping is 0"):
        check_perturb_changes([name], [engine], {engine: {"A.damping": 1e-3}})
    with pytest.raises(ModelInputError, match=r"has no parameter 'crank\.length'"):
        perturbed(name, nm.params, {"crank.length": 1e-3})


@pytest.mark.parametrize("engine", ENGINES)
def test_fingerprint_follows_every_compiled_number(engine):
    """Every nonzero perturbable number of the four-bar (masses, principal inertias, gravity)
    changes the engine model's fingerprint at 1e-10 relative (Exudyn's lists of 3x3
    inertias are digested at full precision, not as their 8-digit str)."""
    from crosscheck.checks.perturb import parameter_defaults

    name, _nm = _load("fourbar_connect.xml")
    adapter = get_engine(engine)
    base = adapter.build(name).fingerprint()
    numbers = [p for p, v in parameter_defaults(name).items() if v != 0.0]
    assert len(numbers) == 13  # 3 bodies x (mass, I1..I3) and gravity
    for p in numbers:
        assert adapter.build(name, perturbed(name, {}, {p: 1e-10})).fingerprint() != base, p


def test_perturb_on_the_command_line_fails_the_run(tmp_path):
    """`crosscheck run --model-file F --perturb exudyn:crank.mass=1e-6`: the fault planted in
    Exudyn's model of the four-bar fails its records (exit 1), the other engine's pass."""
    from tests.support import cli

    out = cli(
        "run", "--model-file", DATA / "fourbar_connect.xml", "--engines", "exudyn,opensim",
        "--perturb", "exudyn:crank.mass=1e-6", "--states", "2", "--instantaneous",
        "--no-report", "--out", tmp_path,
    )  # fmt: skip
    assert out.returncode == 1, out.stderr
    records = json.loads((tmp_path / "results.json").read_text())["records"]
    failed = {(r["engine"], r["quantity"]) for r in records if r["passed"] is False}
    assert ("exudyn", "accelerations") in failed
    assert not {e for e, _ in failed} - {"exudyn"}


def test_static_body_is_no_part_of_exudyns_dynamics():
    """A body fixed to the world only adds a constant to Exudyn's potential, so perturbing
    its mass leaves Exudyn's model unchanged and is refused."""
    name, _nm = _load("gripper.xml")
    with pytest.raises(ModelInputError, match=r"does not contain base\.mass"):
        check_perturb_changes([name], ["exudyn"], {"exudyn": {"base.mass": 1e-3}})


@pytest.mark.parametrize(
    "engine, element",
    [("exudyn", "armature on ball joint 'ball'"), ("opensim", "armature on ball joint 'ball'")],
)
def test_an_element_not_expressed_is_named(engine, element):
    """spatial_mix has armature on a ball joint: each engine refuses the file naming it (the
    reference loads it; its derivation is not needed to build the engine's model)."""
    from reference.mjcf.loader import import_mjcf

    imp = import_mjcf(DATA / "spatial_mix.xml")
    models.register(imp.model, "spatial_mix.xml (MJCF)", imp)
    with pytest.raises(EngineUnsupported, match=element):
        get_engine(engine).build(imp.model.name)


def test_python_file_reason_is_one_for_every_engine():
    """A Python model file has no MJCF: every engine that builds users' files from MuJoCo's
    compiled model skips it with the same words."""
    (name, *_) = register_all(load_model_file(DATA / "user_mechanism.py"))
    reasons = set()
    for engine in ("mujoco", "pinocchio", *ENGINES):
        with pytest.raises(EngineUnsupported) as exc:
            get_engine(engine).build(name)
        reasons.add(str(exc.value))
    (reason,) = reasons
    assert "a Python model" in reason and "write the mechanism as MJCF" in reason


def test_run_lists_four_engines_in_the_agreement_matrix(tmp_path):
    """`crosscheck run --model-file` on the gripper (two loops, two joint couplings): passing
    Exudyn and OpenSim records, and the agreement matrix lists the reference and four
    engines."""
    from tests.support import cli

    out = cli(
        "run", "--model-file", DATA / "gripper.xml", "--states", "2", "--instantaneous",
        "--no-report", "--out", tmp_path,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    results = json.loads((tmp_path / "results.json").read_text())
    mine = [r for r in results["records"] if r["engine"] in ENGINES and r["passed"] is not None]
    assert {r["engine"] for r in mine} == set(ENGINES) and all(r["passed"] for r in mine)
    (acc,) = [a for a in results["agreement"] if a["quantity"] == "accelerations"]
    assert acc["sides"] == ["reference", "pinocchio", "mujoco", "exudyn", "opensim"]


@pytest.mark.slow
def test_opensim_keeps_a_spinning_bodys_quaternion_on_one_branch():
    """MuJoCo's jdotv_weld_3d over 5 s: its free body turns by more than pi from its initial
    rotation, where a quaternion read back from OpenSim's X-Y-Z angles would flip sign; the
    run is read back on one branch and follows the reference (measured 9e-10)."""
    from reference.integrate.driver import simulate

    name, nm = _load("mujoco_jdotv_weld_3d.xml")
    m = models.get(name)
    q0, u0 = np.array(m.initial_q), np.array(m.initial_u)
    t = np.linspace(0.0, 5.0, 11)
    ref = simulate(nm, q0, u0, 5.0, "projection", rtol=1e-12, atol=1e-12, t_eval=t)
    tr = get_engine("opensim").build(name).simulate(q0, u0, t, integrator="RungeKuttaMerson",
                                                    rtol=1e-10)  # fmt: skip
    # RungeKuttaMerson at rtol 1e-10 over 5 s: 9e-10 measured; a flipped quaternion is O(1)
    assert scaled_error(tr.q, ref.q) < 1e-7 and scaled_error(tr.u, ref.u) < 1e-7
