"""Engine derivatives against the reference's exact ones (crosscheck.checks.derivatives):
Pinocchio's analytical derivatives, the other engines' central differences, the defect the
records find in Pinocchio 4.1 on closed planar loops, and a planted error in one block that
fails that block's record alone."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from benchmarks.pinocchio_loop_derivatives import measured
from crosscheck.checks.derivatives import tolerances as D
from crosscheck.checks.derivatives.engine import ReferenceAtState, compare_at_state
from crosscheck.checks.derivatives.faults import Fault
from crosscheck.checks.derivatives.records import engine_records, reference_records
from crosscheck.checks.instantaneous import build
from crosscheck.checks.sampling import consistent_states
from crosscheck.engines.registry import available_engines, get_engine
from crosscheck.user_models import load_model_file, register_all
from reference import NumericModel, models
from reference.derivatives import DerivativeModel
from tests.support import representative

DATA = Path(__file__).parent / "data"
# Pinocchio's models that use its constraint models (constraintDynamics): the derivative
# routine under test; the slider-cranks are the defect below
CONSTRAINED = [
    ("exercise_6_1", None),
    ("double_pendulum_3d", "free"),
    ("top_cartesian", "free"),
]
TREES = [("pendulum_angle", None), ("double_pendulum_3d", "tree"), ("top_euler", None)]
# Pinocchio 4.1's computeConstraintDynamicsDerivatives on a point constraint between two
# moving bodies: du'/dq and dlambda/dq wrong at order one in tangent column 0 (a revolute here)
LOOP_DEFECT = ("slider_crank", "slider_crank_split")


def _records(name, engine, variant=None, n_states=3, fault=None):
    nm = NumericModel(models.get(name))
    states = consistent_states(nm, n_states)
    dm = DerivativeModel(nm)
    recs = engine_records(name, nm, dm, states, get_engine(engine), nm.params, variant, fault)
    return {r["quantity"]: r for r in recs}


@pytest.mark.parametrize(("name", "variant"), CONSTRAINED + TREES)
def test_pinocchio_analytical_derivatives_agree_with_the_exact_ones(name, variant):
    """Every block of Pinocchio's analytical derivatives (computeConstraintDynamicsDerivatives,
    computeABADerivatives) mapped to the reference's terms: within the derived tolerance, at
    most 1e-8 (measured 2e-14..9e-12)."""
    recs = _records(name, "pinocchio", variant)
    judged = [r for r in recs.values() if not r["skipped"]]
    assert judged and all(r["passed"] for r in judged), [
        (r["quantity"], r["error"], r["tolerance"]) for r in judged if not r["passed"]
    ]
    assert all(r["tolerance"] <= 1e-8 for r in judged)
    assert all(r["derivative_method"].startswith("compute") for r in judged)
    assert max(r["error"] for r in judged) <= 1e-10


@pytest.mark.parametrize("name", LOOP_DEFECT)
def test_pinocchio_loop_closure_dq_derivatives_are_wrong(name):
    """The defect the records find: Pinocchio's analytical du'/dq and dlambda/dq along the
    loop's tangent miss the exact ones at order one, while its own central differences agree
    with the exact ones (so its forward answer is right, its derivative routine is not) and its
    du and dtau blocks agree to round-off. When an upgrade fixes it, this test says so."""
    recs = _records(name, "pinocchio")
    for qty in ("daccelerations_dq", "dmultipliers_dq"):
        r = recs[qty]
        assert r["passed"] is False and r["error"] > 1e-4, (qty, r["error"])
        assert r["differences_error"] < 1e-6, (qty, r["differences_error"])
    for qty in ("daccelerations_du", "dmultipliers_du", "daccelerations_dtau"):
        assert recs[qty]["passed"] and recs[qty]["error"] <= 1e-10


def test_pinocchio_loop_defect_is_column_zero_counted_nv_extra_times():
    """The loop defect's cause, with Pinocchio alone (benchmarks/pinocchio_loop_derivatives.py):
    RigidConstraintModel's loop_span_indexes starts with nv zeros, so tangent column 0's
    loop-closure term is added nv times too many. Taking those copies out leaves round-off;
    a slider as column 0 (no angular part) is right; the proximal mu does not change the
    error (not the regularization of the planar loop's dependent row), and a spatial loop
    with 3 independent rows and mu = 0 is as wrong. When an upgrade fixes it, this says so."""
    got = measured()
    crank = got["2R arm tip to a root slider (slider_crank)"]
    assert min(crank) > 1e-3, crank
    for mu in ("1e-04", "1e-02"):
        assert got[f"  ... proximal mu {mu}"] == pytest.approx(crank, rel=1e-3)
    assert max(got["  ... column 0's nv extra copies taken out"]) < 1e-8
    assert max(got["  ... the slider first (column 0 a translation)"]) < 1e-8
    assert min(got["spatial RX-RY-RZ arm to an RY rocker (3 rows, mu 0)"]) > 1e-2


def test_pinocchio_world_first_drift_is_its_constraint_jacobian_accumulating():
    """The drift's cause, with Pinocchio alone: with the world as joint1 the routine only
    subtracts joint2's part from data.dac_da, which it does not zero, so the constraint
    Jacobian it differentiates with is -k J on the k-th call; initConstraintDynamics zeros it
    (then the accelerations are right, the forces keep the column-0 defect above)."""
    got = measured()
    assert got["the same, the world first (3rd call)"][0] > 1.0
    fresh = got["  ... initConstraintDynamics before each call"]
    assert fresh[0] < 1e-8 and fresh[1] > 1e-2, fresh
    assert max(got["  ... and column 0's extra copies taken out"]) < 1e-8


def _file_records(file: str, engine: str = "pinocchio") -> dict:
    (name,) = register_all(load_model_file(DATA / file))
    return _records(name, engine)


def test_user_file_weld_six_d_constraint_derivatives_agree():
    """A user's file with a weld (Pinocchio's CONTACT_6D constraint model; five of six rows
    dependent): u' and the generalized constraint force A^T lambda, every block."""
    recs = _file_records("weld_sites.xml")
    judged = [r for r in recs.values() if not r["skipped"]]
    assert {r["quantity"] for r in judged} >= {"daccelerations_dq", "dconstraint_forces_dtau"}
    assert all(r["passed"] for r in judged), [(r["quantity"], r["error"]) for r in judged]
    assert all("constraint models" in r["derivative_method"] for r in judged)


def test_user_file_weld_on_a_free_body_agrees_along_the_quaternions_tangent():
    """A free body (quaternion coordinates) welded to a hinged arm: u''s derivatives along the
    unit quaternion's tangent space; A^T lambda is not compared (the quaternion's norm row
    has a multiplier no engine has), which its records say."""
    recs = _file_records("free_weld.xml")
    judged = {q: r for q, r in recs.items() if not r["skipped"]}
    assert set(judged) == {f"daccelerations_{b}" for b in ("dq", "du", "dtau")}
    assert all(r["passed"] and r["directions"] == "consistent directions" for r in judged.values())
    assert "quaternion" in recs["dconstraint_forces_dq"]["reason"]


@pytest.mark.parametrize("file", ["double_pendulum.xml", "pendulum_hinge.xml"])
def test_user_file_without_equalities_gets_pinocchio_derivatives(file):
    """No equality: no constraint models (constraintDynamics is ABA then), every u' block;
    one degree of freedom too (Pinocchio's empty constraint Jacobian is then a vector)."""
    recs = _file_records(file)
    judged = [r for r in recs.values() if not r["skipped"]]
    assert len(judged) == 3 and all(r["passed"] for r in judged), judged
    assert all(r["derivative_method"].startswith("computeConstraintDynamics") for r in judged)


def test_user_file_connect_loop_shows_the_defect():
    """A user's four-bar closed by a `connect` (CONTACT_3D between two moving bodies): the
    same defect as the slider-cranks, in du'/dq and d(A^T lambda)/dq only."""
    recs = _file_records("fourbar_connect.xml")
    for qty in ("daccelerations_dq", "dconstraint_forces_dq"):
        assert recs[qty]["passed"] is False and recs[qty]["error"] > 1e-2, recs[qty]
        assert recs[qty]["differences_error"] < 1e-6, recs[qty]
    for qty in ("daccelerations_du", "dconstraint_forces_du", "daccelerations_dtau"):
        assert recs[qty]["passed"] and recs[qty]["error"] <= 1e-10, recs[qty]


def test_a_planted_error_fails_its_block_alone():
    """Planted in Pinocchio's own Jacobians, before the maps: a sign flipped on one column of
    ddq_dq (a wrong sign), one column of dlambda_dv dropped (a missing term), a 1e-6 relative
    error in ddq_dtau. Each fails the record of its block and no other (Example 4's free
    bodies answer as the reference does off the manifold too, so whole Jacobians are compared,
    block by block)."""
    base = _records("double_pendulum_3d", "pinocchio", "free", 2)
    assert all(r["passed"] is not False for r in base.values())
    assert {r.get("directions") for r in base.values() if not r["skipped"]} == {"whole Jacobians"}
    for fault in (
        Fault("q", "accelerations", "sign", column=3),
        Fault("v", "forces", "drop", column=3),
        Fault("tau", "accelerations", "scale", 1e-6),
    ):
        recs = _records("double_pendulum_3d", "pinocchio", "free", 2, fault)
        failed = {q for q, r in recs.items() if r["passed"] is False}
        assert failed == {fault.quantity(("accelerations", "multipliers"))}, (fault, failed)


def test_a_planted_error_in_a_differenced_engine_fails_its_block_alone():
    """The same kinds of error in an engine whose derivatives are differenced (OpenSim)."""
    fault = Fault("q", "forces", "scale", 1e-5)
    recs = _records("slider_crank", "opensim", fault=fault)
    failed = {q for q, r in recs.items() if r["passed"] is False}
    assert failed == {"dmultipliers_dq"}


ENGINES = [e for e in ("mujoco", "exudyn", "opensim") if e in available_engines()]
DIFFERENCED = [(e, n) for e in ENGINES for n in models.names()]


@pytest.mark.parametrize(
    ("engine", "name"),
    representative(DIFFERENCED, {"slider_crank", "double_pendulum_3d"}, key=lambda c: c[1]),
)
def test_differenced_engines_agree_within_their_derived_tolerances(engine, name):
    """Central differences of the engine's answer on the manifold (its rigid recovery for
    MuJoCo) within the truncation measured with the reference plus the engine's error bound
    magnified by 1.5/h; MuJoCo's raw soft derivatives within the predicted soft effect's."""
    adapter = get_engine(engine)
    if name in adapter.unsupported():
        pytest.skip(adapter.unsupported()[name])
    for variant in adapter.variants(name):
        recs = _records(name, engine, variant, 2)
        judged = [r for r in recs.values() if not r["skipped"]]
        assert all(r["passed"] for r in judged), [
            (r["quantity"], r["error"], r["tolerance"]) for r in judged if not r["passed"]
        ]


def test_reference_records_hold_the_exact_derivatives_to_the_slow_path():
    nm = NumericModel(models.get("top_cartesian"))
    recs = reference_records("top_cartesian", nm, DerivativeModel(nm), consistent_states(nm, 2))
    assert len(recs) == 6 and all(r["passed"] for r in recs)
    assert max(r["error"] for r in recs) <= 1e-9


def test_mujoco_transition_fd_reads_the_soft_answer_at_the_models_step():
    """mjd_transitionFD is taken with the step 1, Euler's implicit damping and the solref
    clamp off: MuJoCo's qacc there is its qacc at the model's own settings (so its Jacobians
    are those of the answer the other records judge); its miss against the prediction is
    reported beside the soft records."""
    from crosscheck.engines.mujoco.derivatives import transition_jacobians

    nm = NumericModel(models.get("exercise_6_1"))
    em = get_engine("mujoco").build("exercise_6_1", nm.params)
    q, u = consistent_states(nm, 2)[1]
    qe, ve = em.to_engine_state(q, u)
    em._set(qe, ve)
    mujoco.mj_forward(em.m, em.d)
    qacc = em.d.qacc.copy()
    jac = transition_jacobians(em, qe, ve)
    assert np.array_equal(jac.accelerations, qacc)
    assert em.m.opt.timestep == 1e-3  # restored
    sd = compare_at_state(em, get_engine("mujoco"), DerivativeModel(nm), "exercise_6_1", q, u)
    assert "engine_differences_miss" in sd.reported["daccelerations_dq_soft_vs_predicted"]


def test_directions_follow_the_reference_state():
    nm = NumericModel(models.get("slider_crank"))
    q, u = consistent_states(nm, 2)[1]
    ref = ReferenceAtState(DerivativeModel(nm), q, u, 0.0)
    assert ref.dirs.dq.shape == (2, 1) and ref.dirs.du.shape == (2, 1)
    assert ref.kappa > 1


def test_pinocchio_derivatives_drift_with_the_world_as_first_joint():
    """MuJoCo's own test file of a slide held by a `connect` whose body1 is a static body
    (Pinocchio's constraint model with the universe as joint1): its du'/dtau and
    d(A^T lambda)/dtau grow from call to call on the same Data (0, -3, -8, ...: the first call
    is right), while du'/dq and du'/du stay exact (python
    benchmarks/pinocchio_loop_derivatives.py, "the world first"). When an upgrade fixes it,
    this test says so."""
    recs = _file_records("real/mujoco_force_slide_rotated.xml")
    for qty in ("daccelerations_dtau", "dconstraint_forces_dtau"):
        assert recs[qty]["passed"] is False and recs[qty]["error"] > 1.0, recs[qty]
    for qty in ("daccelerations_dq", "daccelerations_du", "dconstraint_forces_du"):
        assert recs[qty]["passed"] and recs[qty]["error"] <= 1e-10, recs[qty]


def test_mujoco_transition_fd_refusing_a_model_leaves_its_answer_differenced():
    """mjd_transitionFD refuses a model with sleeping enabled (MuJoCo's own test file): its
    records say so and judge the differenced answer instead of failing the run."""
    recs = _file_records("real/mujoco_sleep_equality.xml", "mujoco")
    judged = [r for r in recs.values() if not r["skipped"]]
    assert judged and all(r["passed"] for r in judged), judged
    rigid = [r for r in judged if not r["quantity"].endswith("_soft_vs_predicted")]
    assert all("mjd_transitionFD refuses" in r["derivative_method"] for r in rigid), rigid


def test_a_stencil_reaching_a_limit_shrinks_its_step_and_says_so():
    """A user's arm drawn where no limit acts, some states near the wrist's limit: a
    differenced engine's stencil there would reach it at the balanced step (other equations),
    so that block's step is halved until it clears and the state is judged, the records saying
    at which states and steps; Pinocchio's own derivatives, at the states themselves, are
    judged at every state with no step shrunk."""
    (name,) = register_all(load_model_file(DATA / "robot_arm.xml"))
    nm = NumericModel(models.get(name))
    states, dm = consistent_states(nm, 6), DerivativeModel(nm)
    for engine in ("mujoco", "pinocchio"):
        recs = engine_records(name, nm, dm, states, get_engine(engine), nm.params)
        judged = [r for r in recs if not r["skipped"]]
        assert judged and all(r["passed"] for r in judged), judged
        assert not any("not compared at" in r["reason"] for r in judged)
        shrunk = ["the difference step shrunk at" in r["reason"] for r in judged]
        assert all(shrunk) if engine == "mujoco" else not any(shrunk)


def _wrist_state(gap: float):
    """The arm's draw with the wrist slide `gap` inside its upper limit."""
    (name,) = register_all(load_model_file(DATA / "robot_arm.xml"))
    nm = NumericModel(models.get(name))
    q, u = consistent_states(nm, 1)[0]
    q = np.array(q, float)
    q[2] = 0.05 - gap  # the wrist's coordinate (its range is +-0.05 m)
    return name, nm, q, np.asarray(u, float)


def test_a_stencil_near_a_limit_is_judged_at_its_shrunk_step():
    """The wrist 5 mm from its stop: the dq stencil at the balanced 6.3e-3 reaches it, at a
    quarter of it (1.6e-3, 2h = 3.2 mm) it does not: judged there, the tolerance the formula's
    at that step, the step and why in the reason; the du block keeps the balanced step."""
    name, nm, q, u = _wrist_state(5e-3)
    adapter = get_engine("mujoco")
    em = build(adapter, name, nm.params, None)
    sd = compare_at_state(em, adapter, DerivativeModel(nm), name, q, u)
    dq, du = sd.judged["daccelerations_dq"], sd.judged["daccelerations_du"]
    assert dq.ratio <= 1 and du.ratio <= 1, (dq, du)
    assert sd.steps == {"dq": pytest.approx(D.step(1e-11) / 4)}
    assert dq.figures["step"] == sd.steps["dq"] and du.figures["step"] == D.step(1e-11)
    assert "step 1.6e-03, shrunk from 6.3e-03: at that step joint 'wrist' at its limit" in (
        dq.reason
    )
    f = dq.figures
    assert dq.tolerance == pytest.approx(
        D.DIFFERENCE_SLACK * f["truncation_estimate"] + f["round_off_estimate"]
    )


def test_a_stencil_reaching_a_limit_below_the_floor_leaves_its_state_out():
    """The wrist 1e-6 m from its stop: only a step below the floor (1.5 delta / 1e-5 =
    1.5e-6, the round-off bound's bar) would clear it, so the state is left out, the records
    saying why."""
    name, nm, q, u = _wrist_state(1e-6)
    far = consistent_states(nm, 1)[0]
    recs = engine_records(name, nm, DerivativeModel(nm), [far, (q, u)],
                          get_engine("mujoco"), nm.params)  # fmt: skip
    judged = [r for r in recs if not r["skipped"]]
    assert judged and all(r["passed"] for r in judged), judged
    assert (
        "not compared at 1 of 2 states (state 1: joint 'wrist' at its limit"
        in (judged[0]["reason"])
    )
    assert "(the floor 1.5e-06: below it the round-off bound" in judged[0]["reason"]


@pytest.mark.slow
def test_mujoco_derivatives_on_cassie_are_judged_at_shrunk_steps():
    """Cassie's 16 limits: every drawn state's dq stencil reaches one at the balanced step
    (1.6e-2, MuJoCo's rigid recovery); shrunk to clear them, every state is judged and
    passes."""
    (name,) = register_all(load_model_file(DATA / "real" / "pinocchio_cassie.xml"))
    nm = NumericModel(models.get(name))
    states, dm = consistent_states(nm, 6), DerivativeModel(nm)
    recs = engine_records(name, nm, dm, states, get_engine("mujoco"), nm.params)
    judged = {r["quantity"]: r for r in recs if not r["skipped"]}
    assert {"daccelerations_dq", "daccelerations_du"} <= set(judged), recs
    assert all(r["passed"] for r in judged.values()), judged
    assert all("not compared at" not in r["reason"] for r in judged.values())
    assert "the difference step shrunk at 6 of 6 states" in judged["daccelerations_dq"]["reason"]
