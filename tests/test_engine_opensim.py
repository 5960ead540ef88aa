"""What only the OpenSim adapter does, with the real OpenSim 4.6 (no mocks).

What every engine does (state maps, accelerations, multipliers and energy against the
reference, the fingerprint, the nominal maps, faults seen, the timing hook, refusals) is
tests/test_engine_contract.py. Here: what OpenSim declares, the sign its maps keep, Simbody's
direct solve and its own residuals, each multiplier map against the forces the constraint
applies (Constraint.calcConstraintForces, an independent OpenSim route), the double
pendulum's measured floor, and short Manager trajectories.

States: tests.support.states, seeded, so every run draws the same states.
"""

from __future__ import annotations

import math
import tomllib
from functools import cache

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from crosscheck.engines.building import resolve_params
from crosscheck.engines.opensim import OpenSimAdapter
from crosscheck.engines.opensim.engine_model import INTEGRATORS
from reference.models import get
from reference.numeric.model import NumericModel
from tests.support import QUICK_MODELS, ROOT, representative, scaled_error, states

ADAPTER = OpenSimAdapter()
# Accelerations and multipliers: both sides solve the same KKT system with backward-stable
# factorizations; measured worst over 50 states per model 2.7e-12 relative (slider_crank_split's
# multipliers, T = 0.7), most models ~1e-15..1e-13 (docs/engines/opensim.md). The adapter's
# tolerance is the suite's exact-KKT bound (1e-11).
EXACT = ADAPTER.exact_tolerance("slider_crank").value
# State map of the Euler parameters: quaternion <-> rotation conversions of O(1) numbers, a
# few ulp; the states are consistent to round-off (tests.support.states).
STATE_MAP_ATOL = 1e-12
# Simbody's own acceleration-level residual |G u' - b| after its solve: round-off of terms
# up to ~1e3 (the slider-crank's omega^2 l at 10-20 rad/s).
UDOTERR_ATOL = 1e-9

PARAMS = {
    "slider_crank": {"T": 0.7},
    "slider_crank_split": {"T": 0.7},
    "slider_crank_free": {"T": 0.7},
    "exercise_6_4": {"M_phi": 0.3, "M_theta": -0.2},
}
MODELS = representative(ADAPTER.models(), QUICK_MODELS)


# The top's normalization row has no engine force (its multiplier is formulation-dependent).
NO_ENGINE_MULTIPLIERS = {"top_euler"}
# Models whose q ends with Euler parameters: eps and -eps are one engine rotation.
EULER_PARAMETERS = {"top_euler", "top_cartesian"}


@cache
def reference(model_name: str, formulation: str | None = None) -> NumericModel:
    return NumericModel(get(model_name), formulation, PARAMS.get(model_name, {}))


@cache
def engine(model_name: str, perturb=(), variant=None):
    params = dict(PARAMS.get(model_name, {}))
    params.update(dict(perturb))
    return ADAPTER.build(model_name, params, variant=variant)


# ---- the adapter -------------------------------------------------------------------------
def test_declares_exact_multipliers_and_simbodys_integrators():
    """What docs/engines/opensim.md says OpenSim gives: exact multipliers (Simbody's direct
    KKT solve), no velocity-level rows, the Manager's integrators; the package pinned."""
    assert (ADAPTER.name, ADAPTER.distribution) == ("opensim", "opensim")
    caps = ADAPTER.capabilities
    assert caps.multipliers and caps.exact and not caps.nonholonomic
    assert set(caps.integrators) == set(INTEGRATORS)
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "opensim==4.6" in meta["project"]["dependencies"]


@pytest.mark.parametrize("model_name", sorted(EULER_PARAMETERS))
def test_euler_parameters_keep_their_sign(model_name):
    """eps and -eps are one engine rotation; the map keeps the branch of the eps it was
    given, so the round trip is the identity on both branches, to the letter (the contract
    compares the state both readings encode)."""
    em = engine(model_name)
    for q, u in states(reference(model_name), 5, seed=0):
        for sign in (1.0, -1.0):  # (eps, eps') and (-eps, -eps'): the same motion
            q1, u1 = q.copy(), u.copy()
            q1[-4:] *= sign
            u1[-4:] *= sign
            q2, u2 = em.from_engine_state(*em.to_engine_state(q1, u1))
            assert scaled_error(q2, q1) <= STATE_MAP_ATOL and scaled_error(u2, u1) <= STATE_MAP_ATOL


@pytest.mark.parametrize("model_name", MODELS)
def test_simbody_solves_directly_and_meets_its_rows(model_name):
    """Simbody's answer is one direct KKT factorization (iterations 1) that meets its own
    acceleration-level rows (udoterr); the top's normalization row, whose multiplier depends
    on the formulation, has no engine force, and forward() says so."""
    em = engine(model_name)
    for q, u in states(reference(model_name), 5, seed=0):
        got = em.forward(q, u)
        assert got.iterations == 1
        if model_name in NO_ENGINE_MULTIPLIERS:
            assert got.multipliers is None and got.multipliers_note
            assert got.raw["multipliers_note"] == got.multipliers_note
        if em.n_multipliers:
            assert got.raw["udoterr"] <= UDOTERR_ATOL


def test_fingerprint_reads_the_built_model():
    """The digest is of the model OpenSim writes back (its XML), not of the parameter dict: an
    entry the model does not use leaves it unchanged; a body's mass changed in the built
    model changes it."""
    params = resolve_params("slider_crank", None)
    em = ADAPTER.build("slider_crank", params)
    before = em.fingerprint()
    assert type(em)("slider_crank", dict(params, unused=1.0)).fingerprint() == before
    body = em.model.getBodySet().get("rod")
    body.setMass(body.getMass() * (1 + 1e-12))
    assert em.fingerprint() != before


@pytest.mark.slow
def test_double_pendulum_floor():
    """The measurement behind OPENSIM_DOUBLE_PENDULUM, the model's tolerance (the contract
    holds both variants to it): the ball-joint tree on 200 sampler states (seed 0), worst
    relative error 2.0e-11 in the accelerations (axial w_12', w_22'), 6.5e-13 in lambda; the
    free-body variant, 4.3e-13 and 8.4e-14, stays within the suite's exact bound."""
    nm = reference("double_pendulum_3d")
    tree, free = (engine("double_pendulum_3d", variant=v) for v in ("tree", "free"))
    worst = dict.fromkeys(("tree_a", "tree_l", "free_a", "free_l"), 0.0)
    for q, u in states(nm, 200, seed=0):
        ref = nm.forward(q, u)
        for key, em in (("tree", tree), ("free", free)):
            got = em.forward(q, u)
            worst[key + "_a"] = max(
                worst[key + "_a"], scaled_error(got.accelerations, ref.accelerations)
            )
            worst[key + "_l"] = max(
                worst[key + "_l"], scaled_error(got.multipliers, ref.multipliers)
            )
    assert EXACT < worst["tree_a"] <= ADAPTER.exact_tolerance("double_pendulum_3d").value / 2
    assert max(worst["tree_l"], worst["free_a"], worst["free_l"]) <= EXACT, worst


def test_double_pendulum_free_multipliers_are_the_point_constraints():
    """Free variant: lambda[3:6] is the force of link 1 on link 2 at A = the A constraint's
    force on link 2 (calcConstraintForces, body 2); F_O = the O constraint's force on link 1."""
    em = engine("double_pendulum_3d", variant="free")
    q, u = states(reference("double_pendulum_3d"), 1, seed=0)[0]
    f = em.forward(q, u)
    (_, _), (_, on_link1) = em.constraint_forces()[0]
    (_, _), (_, on_link2) = em.constraint_forces()[1]
    assert np.allclose(f.multipliers[3:6], on_link2, rtol=1e-13, atol=1e-13)
    assert np.allclose(f.multipliers[0:3], on_link1 - on_link2, rtol=1e-13, atol=1e-13)


def test_ball_joint_coordinates_are_xyz_euler_angles():
    """What the double pendulum's map assumes: a BallJoint's coordinates are body-fixed X-Y-Z
    angles (R = Rx Ry Rz) and its speeds the child's angular velocity in parent axes."""
    from crosscheck.engines.kinematics import rotation_xyz

    em = engine("double_pendulum_3d", variant="tree")
    qe, ve = np.array([0.3, -0.5, 0.7, 0.2, 0.4, -0.9]), np.array([0.2, -0.4, 0.9, 0, 0, 0])
    em._set_state(qe, ve)
    em.model.realizeVelocity(em.state)
    T = em.links[0].getTransformInGround(em.state).R()
    R = np.array([[T.get(i, j) for j in range(3)] for i in range(3)])
    assert np.allclose(R, rotation_xyz(*qe[0:3]), rtol=0, atol=1e-15)
    w = em.links[0].getAngularVelocityInGround(em.state)
    assert np.allclose([w.get(i) for i in range(3)], ve[0:3], rtol=0, atol=1e-15)


# ---- the multiplier maps against the forces the constraints apply ------------------------
def _forward(model_name, k=0):
    em = engine(model_name)
    q, u = states(reference(model_name), k + 1, seed=0)[k]
    return em, q, u, em.forward(q, u)


def test_pendulum_xy_multiplier_is_the_rod_force():
    """The rod's force on the bob (OpenSim's calcConstraintForces, body 2) is A^T lambda =
    lambda p in the reference's axes (p_ref = (x, y down); the engine's y is flipped)."""
    em, q, _u, f = _forward("pendulum_xy")
    (_, on_ground), (_, on_bob) = em.constraint_forces()[0]
    assert np.allclose(on_bob[:2], f.multipliers[0] * np.array([q[0], -q[1]]), rtol=1e-13)
    assert np.allclose(on_ground, -on_bob, rtol=1e-13)
    assert math.isclose(f.raw["rod_tension"], -f.multipliers[0] * em.params["L"], rel_tol=1e-12)


def test_moving_support_rod_multiplier():
    """The rod's slot among Simbody's multipliers (after the prescribed coordinate's row): its
    force on the bob (calcConstraintForces, body 2) is lambda (p - p_s), reference axes."""
    em = engine("pendulum_moving_support")
    nm = reference("pendulum_moving_support", "lagrange")
    t = 0.7
    ((q, u),) = states(nm, 1, seed=3, t=t)
    f = em.forward(q, u, t)
    assert scaled_error(f.multipliers, nm.forward(q, u, t).multipliers) <= EXACT
    (_, _), (_, on_bob) = em.constraint_forces()[0]
    xs = em.params["a"] * math.sin(em.params["Omega"] * t)
    assert np.allclose(on_bob[:2], f.multipliers[0] * np.array([q[0] - xs, -q[1]]), rtol=1e-12)


def test_slider_crank_multiplier_is_the_guide_force_on_C():
    """The guide's force on the slider (calcConstraintForces) is lambda along Y and nothing
    along X: Simbody's point-on-line row is the textbook's row with its sign."""
    em, _q, _u, f = _forward("slider_crank")
    (_, _on_ground), (_, on_slider) = em.constraint_forces()[0]
    assert math.isclose(on_slider[1], f.multipliers[0], rel_tol=1e-13)
    assert abs(on_slider[0]) < 1e-13 and abs(f.raw["engine_multipliers"][0]) < 1e-13


def test_slider_crank_split_multipliers_are_the_force_on_the_crank():
    """Note 2's multipliers are the force of the rod on the crank at B (calcConstraintForces,
    the crank's side), and the rod gets its opposite."""
    em, _q, _u, f = _forward("slider_crank_split")
    (_, on_crank), (_, on_rod) = em.constraint_forces()[0]
    assert np.allclose(on_crank[:2], f.multipliers, rtol=1e-13)
    assert np.allclose(on_rod, -on_crank, rtol=1e-13)


def test_exercise_6_1_end_forces():
    """F_B from the closure's applied force on the bar; F_A from the bar joint's reaction equals
    the massless slider's spring-damper force along X."""
    em, _q, _u, f = _forward("exercise_6_1")
    (_, on_bar), _ = em.constraint_forces()[0]
    assert np.allclose(f.raw["force_on_bar_at_B"], on_bar, rtol=1e-13)
    assert math.isclose(
        f.raw["force_on_bar_at_A"][0], f.raw["spring_damper_force"], rel_tol=1e-12, abs_tol=1e-12
    )


def test_top_normalization_values_in_raw():
    """The normalization row has no engine force; raw carries Lagrange's value of its
    multiplier, 2V - 4K from OpenSim's own energies (Exercise 6.6), equal to the reference's."""
    em, q, u, f = _forward("top_euler")
    K, V = em.energy(q, u)
    lam_lagrange = reference("top_euler", "lagrange").forward(q, u).multipliers[0]
    assert math.isclose(f.raw["normalization_lambda_lagrange"], 2 * V - 4 * K, rel_tol=1e-13)
    assert math.isclose(f.raw["normalization_lambda_lagrange"], lam_lagrange, rel_tol=1e-11)


def test_top_upright_socket_force():
    """The top at rest, upright: the socket carries its weight, lambda = (0, 0, m g, 2 L m g)."""
    em = ADAPTER.build("top_cartesian")
    p = em.params
    f = em.forward(np.array([0, 0, p["L"], 0, 0, 0, 1.0]), np.zeros(7))
    mg = p["m"] * p["g"]
    assert np.allclose(f.multipliers, [0, 0, mg, 2 * p["L"] * mg], rtol=0, atol=1e-14)


def test_hanging_bar_reaction_static():
    """Exercise 6.2 at rest, bar hanging, no loads on the block: the pin holds the bar's weight,
    lambda = (0, -m2 g) in the reference's y-DOWN axes."""
    em = ADAPTER.build("exercise_6_2", {"F": 0.0})
    f = em.forward(np.array([0.0, 0.0, 0.0, em.params["l"] / 2]), np.zeros(4))
    assert np.allclose(f.multipliers, [0.0, -em.params["m2"] * em.params["g"]], atol=1e-12)


# ---- trajectories ---------------------------------------------------------
# Manager's RungeKuttaMerson at accuracy 1e-10 over 0.5 s against the reference's DOP853 at
# 1e-12: measured differences 1e-10..1e-9 in q and u (docs/engines/opensim.md); 1e-7 bounds
# them while an error in the engine's dynamics (1e-6 of a parameter: ~1e-7 relative in the
# accelerations) is the forward test's job, not this one's.
SIM_TOL = 1e-7


@pytest.mark.parametrize(
    "model_name", ["pendulum_xy", "slider_crank", "exercise_6_1", "pendulum_moving_support"]
)
def test_simulate_matches_reference_trajectory(model_name):
    """OpenSim's Manager (RungeKuttaMerson at accuracy 1e-10) against the reference's forward
    dynamics under scipy's DOP853 at 1e-12, 0.5 s: within SIM_TOL, on the constraint
    manifold (Simbody projects every step)."""
    em, nm = engine(model_name), reference(model_name, "lagrange")
    mod = get(model_name)
    q0, u0 = nm.project(np.array(mod.initial_q, float), np.array(mod.initial_u, float))
    t = np.linspace(0.0, 0.5, 6)
    tr = em.simulate(q0, u0, t, integrator="RungeKuttaMerson", rtol=1e-10)
    n = len(q0)

    def rhs(t, y):
        return np.concatenate([y[n:], nm.forward(y[:n], y[n:], t).accelerations])

    sol = solve_ivp(
        rhs, (0.0, 0.5), np.concatenate([q0, u0]), method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t
    )
    assert np.allclose(tr.t, t, rtol=0, atol=1e-12)
    assert np.max(np.abs(tr.q - sol.y[:n].T)) < SIM_TOL
    assert np.max(np.abs(tr.u - sol.y[n:].T)) < SIM_TOL
    assert tr.steps and tr.steps > 0 and tr.wall_s > 0
    assert np.max(tr.violation) < 1e-8  # Simbody projects onto the manifold every step


def test_simulate_arguments():
    """An integrator the Manager does not have is refused, a fixed-step one needs its
    timestep, and the trajectory records the setting it ran with."""
    em = engine("pendulum_angle")
    with pytest.raises(ValueError, match="unknown opensim integrator"):
        em.simulate([0.3], [1.0], [0.0, 0.1], integrator="RK45")
    with pytest.raises(ValueError, match="fixed-step"):
        em.simulate([0.3], [1.0], [0.0, 0.1], integrator="ExplicitEuler")
    tr = em.simulate([0.3], [1.0], [0.0, 0.01], integrator="ExplicitEuler", timestep=1e-3)
    assert tr.setting == {"integrator": "ExplicitEuler", "timestep": 1e-3}
    assert tr.q.shape == (2, 1) and tr.q[0, 0] == 0.3


# The 3-D models have no q' = u to hand to solve_ivp here: their trajectories are checked by
# energy, which they conserve (no loads but gravity). RungeKuttaMerson at 1e-10 over 0.5 s:
# measured drift 8.9e-11 J (double pendulum, E ~ 6 J) and 5.6e-11 J (top); 1e-9 J bounds it.
ENERGY_DRIFT_ATOL = 1e-9


@pytest.mark.parametrize("model_name", ["double_pendulum_3d", "top_cartesian"])
def test_simulate_3d_conserves_energy(model_name):
    """The 3-D models (no q' = u to hand to solve_ivp) conserve energy under the Manager to
    ENERGY_DRIFT_ATOL, and the mapped states carry the same energy in the reference."""
    em, nm = engine(model_name), reference(model_name, get(model_name).formulations[0])
    mod = get(model_name)
    q0, u0 = nm.project(np.array(mod.initial_q, float), np.array(mod.initial_u, float))
    tr = em.simulate(q0, u0, np.linspace(0.0, 0.5, 3), integrator="RungeKuttaMerson", rtol=1e-10)
    E0 = sum(nm.energy(q0, u0))
    assert np.max(np.abs(tr.energy - E0)) < ENERGY_DRIFT_ATOL
    # the mapped states carry the same energy in the reference
    for q, u, E in zip(tr.q, tr.u, tr.energy, strict=True):
        assert abs(sum(nm.energy(q, u)) - E) < ENERGY_DRIFT_ATOL
