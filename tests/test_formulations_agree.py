"""Formulations agree with each other and with independent reductions (DESIGN practice 7/8).

- Lagrange = d'Alembert = Kane on every model that declares several of them;
- Example 1(a) = 1(b) in motion, and the Addendum's T = -lambda L;
- Example 2(b) = Note 2 / Exercise 6.3 = the one-coordinate reduction in theta1;
- the compiled fast path = a slow sympy subs/evalf path; batched = per-state.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from reference import NumericModel, models
from reference.formulations import derive
from reference.minimal import slider_crank_one_coordinate
from reference.models.pendulum import rod_tension
from tests.support import scaled_error, states

# Two evaluations of the same equations through differently ordered arithmetic differ by
# round-off: a few hundred ulps of the largest term (|terms| up to ~1e3 in these models).
ROUNDOFF_REL = 1e-11

MULTI = [n for n in models.names() if len(models.get(n).formulations) > 1]


@pytest.mark.parametrize("name", MULTI)
def test_formulations_agree_numerically(name):
    model = models.get(name)
    ref = NumericModel(model, model.formulations[0])
    others = [NumericModel(model, f) for f in model.formulations[1:]]
    for q, u in states(ref, 10, seed=7):
        r0 = ref.forward(q, u)
        # rows whose multiplier depends on the formulation (the model says which and why:
        # the Euler-parameter normalization of the top, Exercise 6.6); the motion does not
        dependent = dict(model.formulation_dependent_rows)
        keep = [
            j for j, c in enumerate(model.constraint_names or [""] * ref.m) if c not in dependent
        ]
        for nm in others:
            r = nm.forward(q, u)
            assert scaled_error(r.accelerations, r0.accelerations) < ROUNDOFF_REL, (
                nm.formulation,
                q,
                u,
            )
            assert scaled_error(r.multipliers[keep], r0.multipliers[keep]) < ROUNDOFF_REL, (
                nm.formulation,
                q,
                u,
            )


def test_pendulum_1a_equals_1b_and_tension():
    a, b = NumericModel(models.get("pendulum_angle")), NumericModel(models.get("pendulum_xy"))
    m, L, g = (a.params[k] for k in ("m", "L", "g"))
    rng = np.random.default_rng(1)
    for _ in range(20):
        th, w = rng.uniform(-math.pi, math.pi), rng.uniform(-4, 4)
        thdd = a.forward([th], [w]).accelerations[0]
        q = [L * math.sin(th), L * math.cos(th)]
        u = [L * w * math.cos(th), -L * w * math.sin(th)]
        rb = b.forward(q, u)
        expected = [
            L * (thdd * math.cos(th) - w**2 * math.sin(th)),
            -L * (thdd * math.sin(th) + w**2 * math.cos(th)),
        ]
        assert scaled_error(rb.accelerations, expected) < ROUNDOFF_REL
        # Addendum: T = -lambda L equals the radial balance m L w^2 + m g cos(theta)
        T = rod_tension(rb.multipliers[0], L)
        assert abs(T - (m * L * w**2 + m * g * math.cos(th))) < ROUNDOFF_REL * max(1, abs(T))


def test_slider_crank_three_ways():
    params = {"T": 1.7}
    ex2 = NumericModel(models.get("slider_crank"), params=params)
    split = NumericModel(models.get("slider_crank_split"), params=params)
    one = NumericModel(slider_crank_one_coordinate(), params=params)
    l1, l2 = ex2.params["l1"], ex2.params["l2"]
    rng = np.random.default_rng(3)
    for _ in range(15):
        th1, w1 = rng.uniform(-math.pi, math.pi), rng.uniform(-10, 10)
        th2 = math.asin(-l1 * math.sin(th1) / l2)
        w2 = -l1 * math.cos(th1) * w1 / (l2 * math.cos(th2))
        r2 = ex2.forward([th1, th2], [w1, w2])
        x = l1 * math.cos(th1) + l2 * math.cos(th2)
        xd = -l1 * math.sin(th1) * w1 - l2 * math.sin(th2) * w2
        r3 = split.forward([th1, x, th2 + math.pi], [w1, xd, w2])
        r1 = one.forward([th1], [w1])
        assert scaled_error(r3.accelerations[[0, 2]], r2.accelerations) < ROUNDOFF_REL
        assert scaled_error(r1.accelerations, r2.accelerations[:1]) < ROUNDOFF_REL
        # slider acceleration from Example 2's angles: x'' = d2/dt2 (l1 C1 + l2 C2)
        a1, a2 = r2.accelerations
        xdd = -l1 * (a1 * math.sin(th1) + w1**2 * math.cos(th1)) - l2 * (
            a2 * math.sin(th2) + w2**2 * math.cos(th2)
        )
        assert abs(r3.accelerations[1] - xdd) < ROUNDOFF_REL * max(1, abs(xdd))


@pytest.mark.parametrize("name", ["pendulum_xy", "slider_crank", "slider_crank_split"])
def test_fast_path_equals_slow_sympy_path(name):
    """Compiled straight-line Cholesky/Schur solve vs sympy subs/evalf + a dense KKT solve."""
    model = models.get(name)
    nm = NumericModel(model, "lagrange")
    eom = derive(model, "lagrange")
    for q, u in states(nm, 3, seed=5):
        subs = {s: v for s, v in zip(model.coordinates, q, strict=True)}
        subs.update({s: v for s, v in zip(model.speeds, u, strict=True)})
        subs.update({p.symbol: nm.params[p.name] for p in model.parameters})
        subs[model.t] = 0.0
        M = np.array(eom.M.subs(subs).evalf(30), dtype=float)
        f = np.array(eom.f.subs(subs).evalf(30), dtype=float).ravel()
        A = np.array(eom.A.subs(subs).evalf(30), dtype=float)
        b = np.array(eom.b.subs(subs).evalf(30), dtype=float).ravel()
        n, m = M.shape[0], A.shape[0]
        K = np.block([[M, -A.T], [A, np.zeros((m, m))]])
        sol = np.linalg.solve(K, np.concatenate([f, b]))
        r = nm.forward(q, u)
        assert scaled_error(r.accelerations, sol[:n]) < ROUNDOFF_REL
        assert scaled_error(r.multipliers, sol[n:]) < ROUNDOFF_REL


@pytest.mark.parametrize("name", MULTI)
def test_batched_equals_single(name):
    model = models.get(name)
    nm = NumericModel(model)
    drawn = states(nm, 8, seed=11)
    Q = np.array([s[0] for s in drawn])
    U = np.array([s[1] for s in drawn])
    UD, LAM, _ = nm.forward_batch(Q, U)
    for i, (q, u) in enumerate(drawn):
        r = nm.forward(q, u)
        # same code on numpy arrays: numpy's sin/cos may differ from math's by an ulp
        assert scaled_error(UD[i], r.accelerations) < ROUNDOFF_REL
        assert scaled_error(LAM[i], r.multipliers) < ROUNDOFF_REL
