"""Every backend implements the whole kernel interface (reference.backends.kernels) and gives
the same answers to the bit; the fast calls answer as the slow obvious ones.

The C kernels (reference.backends.c_build) and the generated Python
(reference.backends.python_kernels) run the same expressions in the same order. One way they
can part, and the reason the models below are these: CPython computes x**2 with libm's pow,
which rounds differently from x*x in about 7 of 10^4 squares (measured with ctypes against
glibc, 149 of 200 000 uniform x in [-10, 10]), where gcc (and numpy's batched code) computes
x*x. Measured at 16 seeded consistent states: every output of every kernel of the models here
equal to the bit on both backends, single and batched; double_pendulum_3d's forward differs at
one state of 16, by 3e-15 relative (tests/test_compiled.py holds every model within 1e-14).
"""

from __future__ import annotations

import inspect
import math

import numpy as np
import pytest

from crosscheck.checks.sampling import consistent_states
from reference import NumericModel, models
from reference.backends import c_build as cbuild
from reference.backends.kernels import (
    BAD_Q_SIZE,
    BAD_U_SIZE,
    FUNCTIONS,
    NOT_DEFINED,
    NOT_FINITE,
    OK,
    SINGULAR,
    Kernels,
)
from reference.numeric.model import Forward

BACKENDS = [
    pytest.param("c", marks=pytest.mark.skipif(not cbuild.available(), reason="no C compiler")),
    "python",
]
MODELS = ("pendulum_xy", "slider_crank", "top_cartesian", "knife_edge", "pendulum_moving_support")
T = 0.3  # a time where the rheonomic model's constraint moves


def _same(a, b) -> bool:
    """Two Forward records, or two (u', lambda, ratio) triples, equal to the bit."""
    if isinstance(a, Forward):
        a, b = (
            (a.accelerations, a.multipliers, a.pivot_ratio, a.rank),
            (
                b.accelerations,
                b.multipliers,
                b.pivot_ratio,
                b.rank,
            ),
        )
    return all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


def _nm(monkeypatch, name, backend, params=None):
    monkeypatch.setenv("CROSSCHECK_BACKEND", backend)
    nm = NumericModel(models.get(name), params=params)
    assert nm.backend == nm.kernels.name == backend
    return nm


def _single(nm, fname, Q, U):
    """Each state through the single-state kernel: outputs (N x total) and statuses."""
    k, pa = nm.kernels, nm.kernel_parameters
    f, out, st = k.function(fname), np.empty((len(Q), k.total[fname])), []
    for i in range(len(Q)):
        args = (k.zero_db, out[i]) if fname == "forward" else (out[i],)
        st.append(f(Q[i], U[i], T, pa, *args))
    return out, st


def _batch(nm, fname, Q, U, threads=1):
    k = nm.kernels
    out, st = np.empty((len(Q), k.total[fname])), np.empty(len(Q), np.int64)
    k.set_threads(threads)
    try:
        k.batch(fname)(Q, U, np.array([T]), nm.kernel_parameters[None], k.zero_db[None], out, st)
    finally:
        k.set_threads(1)
    return out, st.tolist()


@pytest.mark.parametrize("backend", BACKENDS)
def test_every_backend_implements_the_whole_interface(monkeypatch, backend):
    nm = _nm(monkeypatch, "slider_crank", backend)
    k = nm.kernels
    assert isinstance(k, Kernels) and not inspect.isabstract(type(k))
    assert set(k.sizes) == set(FUNCTIONS) and all(k.has(f) for f in FUNCTIONS)
    for fname in FUNCTIONS:
        assert callable(k.function(fname)) and callable(k.batch(fname))
        ends = [b for _a, b in k.offsets[fname]]
        assert k.total[fname] == (ends[-1] if ends else 0) + (fname == "forward")
    with pytest.raises(KeyError, match="no generated function 'nope'"):
        k.function("nope")
    k.set_threads(2)  # every backend takes it (the Python one has no threads: a no-op)
    k.set_threads(1)
    assert np.array_equal(k.pack(nm.p, nm.sref), nm.kernel_parameters)
    assert k.zero_db.shape == (max(nm.m, 1),) and not k.zero_db.any()
    # the optional whole-run stepper is declared, not probed: C has one, Python none
    assert (k.stepper is not None) == (backend == "c")
    checked, fast = k.bind(
        nm.kernel_parameters, k.zero_db, Forward, nm._forward_checked, nm._forward_fast_checked
    )
    q, u = np.array(nm.model.initial_q, float), np.array(nm.model.initial_u, float)
    a, b = checked(q, u, T), nm._forward_checked(q, u, T)
    assert isinstance(a, Forward) and _same(a, b)
    assert _same(fast(q, u, T), nm._forward_fast_checked(q, u, T))


@pytest.mark.parametrize("name", MODELS)
def test_every_kernel_agrees_to_the_bit_on_every_backend(monkeypatch, name):
    """Each function's single-state kernel on each backend, its batch (serial, and with two
    threads where the backend has them): the same statuses and the same bits."""
    if not cbuild.available():
        pytest.skip("no C compiler: one backend only")
    c, py = _nm(monkeypatch, name, "c"), _nm(monkeypatch, name, "python")
    states = consistent_states(py, 8)
    Q, U = (np.array([s[i] for s in states], float) for i in (0, 1))
    for fname in FUNCTIONS:
        if not c.kernels.has(fname):
            continue
        ref, st = _single(py, fname, Q, U)
        assert st == [OK] * len(Q), (fname, st)
        for nm in (c, py):
            for got, status in (_single(nm, fname, Q, U), _batch(nm, fname, Q, U)):
                assert status == st and np.array_equal(got, ref), (nm.backend, fname)
        assert np.array_equal(_batch(c, fname, Q, U, threads=2)[0], ref), fname


@pytest.mark.parametrize("backend", BACKENDS)
def test_every_backend_returns_the_same_statuses(monkeypatch, backend):
    """Bad sizes, NaN, a singular pose (slider-crank with l1 = l2 at theta1 = pi/2) and a pose
    where the expressions are not defined (3-1-3 angles at gimbal lock): one status each."""
    equal = {"l1": 0.3, "l2": 0.3, "r2": 0.15, "I_G2": 2.0 * 0.09 / 12}
    nm = _nm(monkeypatch, "slider_crank", backend, equal)
    k, pa, out = nm.kernels, nm.kernel_parameters, np.empty(nm.n + nm.m + 1)
    f = k.function("forward")
    q, u = np.array([0.5, -0.5]), np.array([1.0, -1.0])
    cases = {
        OK: (q, u),
        BAD_Q_SIZE: (q[:1], u),
        BAD_U_SIZE: (q, np.r_[u, 0.0]),
        NOT_FINITE: (np.array([0.5, math.nan]), u),
        SINGULAR: (np.array([math.pi / 2, -math.pi / 2]), np.array([8.0, -8.0])),
    }
    for status, (qs, us) in cases.items():
        assert f(qs, us, 0.0, pa, k.zero_db, out) == status, status
        assert k.function("matrices")(qs, us, 0.0, pa, np.empty(k.total["matrices"])) == (
            status if status != SINGULAR else OK
        )
    dp = _nm(monkeypatch, "double_pendulum_3d", backend)
    k, pa = dp.kernels, dp.kernel_parameters
    gimbal, u = np.array([0.1, 0.0, 0.2, 0.3, 0.1, 0.2]), np.full(dp.n, 0.7)
    assert k.function("forward")(gimbal, u, 0.0, pa, k.zero_db, np.empty(dp.n + dp.m + 1)) == (
        NOT_DEFINED
    )
    assert k.function("matrices")(gimbal, u, 0.0, pa, np.empty(k.total["matrices"])) == (
        NOT_DEFINED
    )


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", ("slider_crank", "top_cartesian", "pendulum_moving_support"))
def test_the_fast_calls_answer_as_the_slow_obvious_ones(monkeypatch, backend, name):
    """forward (on C one bound C call) equals its Python path, forward_fast too, and both a
    plain numpy solve of the KKT system assembled from `matrices` (within its round-off)."""
    nm = _nm(monkeypatch, name, backend)
    for q, u in consistent_states(nm, 4):
        q, u = np.asarray(q, float), np.asarray(u, float)
        fw = nm.forward(q, u, T)
        assert _same(fw, nm._forward_checked(q, u, T))
        ud, lam, piv = nm.forward_fast(q, u, T)
        assert _same((ud, lam, piv), nm._forward_fast_checked(q, u, T))
        assert _same((ud, lam, piv), (fw.accelerations, fw.multipliers, fw.pivot_ratio))
        M, f, A, b = nm.matrices(q, u, T)
        n, m = nm.n, nm.m
        K = np.block([[M, -A.T], [A, np.zeros((m, m))]])
        x = np.linalg.solve(K, np.r_[f, b])
        scale = max(1.0, float(np.max(np.abs(x))))
        assert np.max(np.abs(x[:n] - fw.accelerations)) <= 1e-9 * scale
        assert np.max(np.abs(x[n:] - fw.multipliers)) <= 1e-9 * scale
