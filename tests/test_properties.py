"""Hypothesis property tests: physics that must hold for every model, parameter set and state.

For random parameters (each scaled by a factor in [0.8, 1.25] so the geometry stays valid)
and random consistent states of every model and formulation:
- the KKT matrix is nonsingular and M is positive definite on the null space of A;
- the solution satisfies A u' = b;
- the constraint forces do no work on scleronomic constraints, lambda . (A u) = 0;
- the energy rate equals the power of the applied loads plus that of the constraint forces
  (which is zero unless the constraints move: rheonomic rows, Eq. 4's a0).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg
from hypothesis import given, strategies as st

import pytest

from reference import NumericModel, models
from reference.constraints import is_rheonomic
# the same generator draws the sweeps' samples (crosscheck sweep)
from crosscheck.sampling import draw_instance

CASES = [(n, f) for n in models.names() for f in models.get(n).formulations]

# Round-off of sums of products of O(1..1e3) terms in double precision, relative to the sum of
# the magnitudes of the terms being balanced.
BALANCE_REL = 1e-9


_models_cache: dict = {}


def _numeric(name, formulation):
    key = (name, formulation)
    if key not in _models_cache:
        _models_cache[key] = NumericModel(models.get(name), formulation)
    return _models_cache[key]


def _instance(name, formulation, seed):
    nm, t, q, u = draw_instance(_numeric(name, formulation), np.random.default_rng(seed))
    return nm, q, u, t


@pytest.mark.parametrize("name,formulation", CASES)
@given(seed=st.integers(0, 2**32 - 1))
def test_kkt_nonsingular_and_constraints_hold(name, formulation, seed):
    nm, q, u, t = _instance(name, formulation, seed)
    M, f, A, b = nm.matrices(q, u, t)
    fw = nm.forward(q, u, t)
    assert np.allclose(M, M.T, rtol=0, atol=1e-12 * np.abs(M).max()), "M must be symmetric"
    Z = scipy.linalg.null_space(A) if A.shape[0] else np.eye(M.shape[0])
    ev = np.linalg.eigvalsh(Z.T @ M @ Z)
    assert ev[0] > 1e-12 * ev[-1], f"M is not positive definite on null(A): {ev}"
    # A u' = b to round-off of the products (entries of A and u' up to ~1e3)
    scale = 1 + np.abs(A).max(initial=0) * np.abs(fw.accelerations).max() + np.abs(b).max(initial=0)
    assert np.abs(A @ fw.accelerations - b).max(initial=0) < 1e-12 * scale
    # the dynamic equations hold with the returned multipliers
    res = M @ fw.accelerations - f - A.T @ fw.multipliers
    scale = 1 + np.abs(M).max() * np.abs(fw.accelerations).max() + np.abs(f).max()
    assert np.abs(res).max() < 1e-12 * scale


@pytest.mark.parametrize("name,formulation", CASES)
@given(seed=st.integers(0, 2**32 - 1))
def test_work_energy_balance(name, formulation, seed):
    nm, q, u, t = _instance(name, formulation, seed)
    pb = nm.power_balance(q, u, t)
    scale = 1 + abs(pb["dE_dt"]) + abs(pb["load_power"]) + abs(pb["constraint_power"])
    if not is_rheonomic(nm.model):
        # constraint forces do no work on fixed constraints: lambda . (A u) = -lambda . a0 = 0
        assert abs(pb["constraint_power"]) < BALANCE_REL * scale
    imbalance = pb["dE_dt"] - pb["load_power"] - pb["constraint_power"]
    assert abs(imbalance) < BALANCE_REL * scale, pb


def test_energy_rate_check_can_fail():
    """The balance detects a wrong force: the slider-crank's torque power counted twice."""
    nm, q, u, t = _instance("slider_crank", "lagrange", 1)
    nm = NumericModel(nm.model, "lagrange", {"T": 2.0})
    pb = nm.power_balance(q, u, t)
    assert abs(pb["dE_dt"] - 2 * pb["load_power"]) > 1e-3 * abs(pb["load_power"])
