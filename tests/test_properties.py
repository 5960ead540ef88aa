"""Hypothesis property tests: physics that must hold for every model, parameter set and state.

For random parameters and consistent states of every model and formulation (drawn as plain
floats by tests/strategies.py, so a failure shrinks to a small case near the initial state):
- the KKT matrix is nonsingular and M is positive definite on the null space of A;
- the solution satisfies A u' = b;
- the constraint forces do no work on scleronomic constraints, lambda . (A u) = 0;
- the energy rate equals the power of the applied loads plus that of the constraint forces
  (which is zero unless the constraints move: rheonomic rows, Eq. 4's a0).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
from hypothesis import example, given
from hypothesis import strategies as st

from crosscheck.checks.sampling import draw_instance
from reference import NumericModel, models
from reference.backends.c_build import available
from reference.constraints import is_rheonomic
from reference.errors import SingularSystemError

from .strategies import Instance, build, instances

CASES = [(n, f) for n in models.names() for f in models.get(n).formulations]

# Round-off of sums of products of O(1..1e3) terms in double precision, relative to the sum of
# the magnitudes of the terms being balanced.
BALANCE_REL = 1e-9
# Round-off of the KKT solve's residuals, relative to the size of the products (18x18 at most).
KKT_REL = 1e-12


_models_cache: dict = {}


def _numeric(name, formulation=None):
    key = (name, formulation)
    if key not in _models_cache:
        _models_cache[key] = NumericModel(models.get(name), formulation)
    return _models_cache[key]


def _instance(name, formulation, seed):
    """The sweeps' seeded draw (crosscheck.checks.sampling): tests/test_sweep.py checks a sweep
    sample is this instance, so a worst case it reports can be replayed here."""
    nm, t, q, u = draw_instance(_numeric(name, formulation), np.random.default_rng(seed))
    return nm, q, u, t


def assert_kkt_properties(nm, q, u, t, rel=KKT_REL):
    """M symmetric, positive definite on null(A); A u' = b and M u' - f = A^T lambda hold to
    `rel` of the size of the products."""
    M, f, A, b = nm.matrices(q, u, t)
    fw = nm.forward(q, u, t)
    assert np.allclose(M, M.T, rtol=0, atol=rel * np.abs(M).max()), "M must be symmetric"
    Z = scipy.linalg.null_space(A) if A.shape[0] else np.eye(M.shape[0])
    ev = np.linalg.eigvalsh(Z.T @ M @ Z)
    assert ev[0] > 1e-12 * ev[-1], f"M is not positive definite on null(A): {ev}"
    scale = 1 + np.abs(A).max(initial=0) * np.abs(fw.accelerations).max() + np.abs(b).max(initial=0)
    assert np.abs(A @ fw.accelerations - b).max(initial=0) < rel * scale
    res = M @ fw.accelerations - f - A.T @ fw.multipliers
    scale = 1 + np.abs(M).max() * np.abs(fw.accelerations).max() + np.abs(f).max()
    assert np.abs(res).max() < rel * scale


@pytest.mark.parametrize("name,formulation", CASES)
@given(data=st.data())
def test_kkt_nonsingular_and_constraints_hold(name, formulation, data):
    base = _numeric(name, formulation)
    assert_kkt_properties(*build(base, data.draw(instances(base.model), label="instance")))


@pytest.mark.parametrize("name,formulation", CASES)
@given(data=st.data())
def test_work_energy_balance(name, formulation, data):
    base = _numeric(name, formulation)
    nm, q, u, t = build(base, data.draw(instances(base.model), label="instance"))
    pb = nm.power_balance(q, u, t)
    scale = 1 + abs(pb["dE_dt"]) + abs(pb["load_power"]) + abs(pb["constraint_power"])
    if not is_rheonomic(nm.model):
        # constraint forces do no work on fixed constraints: lambda . (A u) = -lambda . a0 = 0
        assert abs(pb["constraint_power"]) < BALANCE_REL * scale
    imbalance = pb["dE_dt"] - pb["load_power"] - pb["constraint_power"]
    assert abs(imbalance) < BALANCE_REL * scale, pb


def test_energy_rate_check_can_fail():
    """The balance detects a wrong force: the slider-crank's torque power counted twice."""
    base = _numeric("slider_crank", "lagrange")
    nm, q, u, t = build(
        base, Instance((1.0,) * len(base.model.parameters), 0.0, (0.1, 0.0), (0.2, 0.0))
    )
    nm = NumericModel(nm.model, "lagrange", {"T": 2.0})
    pb = nm.power_balance(q, u, t)
    assert abs(pb["dE_dt"] - 2 * pb["load_power"]) > 1e-3 * abs(pb["load_power"])


# ---- known edge cases, pinned with @example ------------------------------------------------
_DP = models.get("double_pendulum_3d")
_THETA12 = _DP.initial_q[1]  # link 1's second 3-1-3 angle: sin(theta12) = 0 is gimbal lock


@given(instance=instances(_DP))
@example(
    instance=Instance(
        (1.0,) * len(_DP.parameters),
        0.0,
        (0.0, (1e-7 - _THETA12) / 0.3, 0.0, 0.0, 0.0, 0.0),
        (0.5,) * 12,
    )
)
@example(
    instance=Instance(
        (1.0,) * len(_DP.parameters),
        0.0,
        (0.0, (2e-5 - _THETA12) / 0.3, 0.0, 0.0, 0.0, 0.0),
        (-0.5,) * 12,
    )
)
def test_example_4_dynamics_near_the_gimbal_pose(instance):
    """Example 4's speeds are body angular velocities, so its dynamics have no singularity at
    sin(theta2) = 0 (gimbal lock of the 3-1-3 angles); the derivation's chain rule through
    q' = N(q, u) (in A-dot u) brings in terms of size |u|^2 / sin(theta2) that cancel exactly
    but leave their round-off: the KKT equations hold to about eps / |sin(theta2)| of their
    size (measured: 0.3 eps / sin at sin = 1e-7), so the bound is 4 eps / |sin| over KKT_REL."""
    nm, q, u, t = build(_numeric("double_pendulum_3d"), instance)
    s = min(abs(math.sin(q[1])), abs(math.sin(q[4])))
    assert_kkt_properties(nm, q, u, t, rel=max(KKT_REL, 4 * np.finfo(float).eps / s))


@pytest.mark.parametrize(
    "backend",
    [
        pytest.param("c", marks=pytest.mark.skipif(not available(), reason="no C compiler")),
        "python",
    ],
)
@pytest.mark.parametrize("rate", [0.0, 0.7])
def test_example_4_at_the_exact_gimbal_pose_is_refused(monkeypatch, backend, rate):
    """At sin(theta12) = 0 exactly, the terms of size |u|^2 / sin(theta2) above are 0/0 or x/0:
    the C kernels return NaN or inf, the generated Python raises ZeroDivisionError. Both must
    refuse the state with the singularity named, never answer."""
    monkeypatch.setenv("CROSSCHECK_BACKEND", backend)
    nm = NumericModel(_DP)
    assert nm.backend == backend
    q = np.array([0.1, 0.0, 0.2, 0.3, 0.1, 0.2])
    u = np.full(nm.n, rate)
    for call in (nm.forward, nm.matrices):
        with pytest.raises(SingularSystemError, match=r"not defined .* gimbal lock"):
            call(q, u, 0.0)


# Slider-crank with l1 = l2: on the branch theta2 = -theta1 its one row A = (l1 C1, l2 C2)
# vanishes at theta1 = +-pi/2 (the rank-loss pose of the stress scene).
_EQUAL = {"l1": 0.3, "l2": 0.3, "r2": 0.15, "I_G2": 2.0 * 0.09 / 12}


@given(theta1=st.floats(-math.pi, math.pi), rate=st.floats(-10.0, 10.0))
@example(theta1=math.pi / 2, rate=8.0)
@example(theta1=-math.pi / 2, rate=-3.0)
@example(theta1=math.pi / 2 + 1e-6, rate=8.0)
def test_slider_crank_rank_loss_is_refused_never_answered(theta1, rate):
    """Where A loses rank (measured independently by its norm) the reference must refuse the
    state with SingularSystemError; where A is well away from it the answer must satisfy the KKT
    equations. In between either is acceptable, but an answer given must still be right."""
    nm = NumericModel(models.get("slider_crank"), params=_EQUAL)
    q, u = [theta1, -theta1], [rate, -rate]
    sigma = float(np.linalg.norm(nm.matrices(q, u)[2]))
    if sigma < 1e-12:
        with pytest.raises(SingularSystemError, match="singular"):
            nm.forward(q, u)
        return
    try:
        assert_kkt_properties(nm, q, u, 0.0)
    except SingularSystemError:
        assert sigma < 1e-4, f"refused a pose {sigma:.1e} away from the rank loss"
