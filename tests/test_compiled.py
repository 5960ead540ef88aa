"""The compiled backend (C) against the pure-Python path it replaces.

Both run the same generated straight-line code (reference.backends.c_source prints it as C), so
they agree to the bit but where CPython's x**2 (libm's pow) rounds differently from the x*x gcc
computes for pow(x, 2.0): measured, 9 of double_pendulum_3d's 4272 outputs at 16 consistent
states differ, by at most 2.8e-15 relative, and every output of pendulum_xy, slider_crank,
top_cartesian and knife_edge is equal (benchmarks/reference_speed.md, "Equality of the
backends"). EQUAL_REL leaves room for that; tests/test_backends.py holds every kernel of the
models without it equal to the bit on every backend.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from crosscheck.run.checks import consistent_states
from reference import NumericModel, models
from reference.backends import c_build as cbuild
from reference.errors import ModelInputError, SingularSystemError

NEEDS_CC = pytest.mark.skipif(not cbuild.available(), reason="no working C compiler")
BACKENDS = [pytest.param("c", marks=NEEDS_CC)]

# a few ulps of the largest entry
EQUAL_REL = 1e-14

MODELS = ("pendulum_xy", "slider_crank", "double_pendulum_3d", "top_cartesian")


def _pair(monkeypatch, name, backend, params=None):
    monkeypatch.setenv("CROSSCHECK_BACKEND", backend)
    fast = NumericModel(models.get(name), params=params)
    monkeypatch.setenv("CROSSCHECK_BACKEND", "python")
    slow = NumericModel(models.get(name), params=params)
    assert (fast.backend, slow.backend) == (backend, "python")
    return fast, slow


def _same(x, y, what):
    x, y = np.atleast_1d(np.asarray(x, float)), np.atleast_1d(np.asarray(y, float))
    assert x.shape == y.shape, what
    if np.array_equal(x, y):
        return
    scale = max(float(np.max(np.abs(y))), 1e-300)
    assert float(np.max(np.abs(x - y))) <= EQUAL_REL * scale, what


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", MODELS)
def test_compiled_equals_fallback(monkeypatch, name, backend):
    fast, slow = _pair(monkeypatch, name, backend)
    for q, u in consistent_states(slow, 8):
        a, b = fast.forward(q, u), slow.forward(q, u)
        _same(a.accelerations, b.accelerations, "u'")
        _same(a.multipliers, b.multipliers, "lambda")
        _same(a.pivot_ratio, b.pivot_ratio, "pivot ratio")
        for what, x, y in zip("MfAb", fast.matrices(q, u), slow.matrices(q, u), strict=True):
            _same(x, y, what)
        for what, x, y in zip(
            ("f(q)", "A u + a0"), fast.residuals(q, u), slow.residuals(q, u), strict=True
        ):
            _same(x, y, what)
        _same(fast.energy(q, u), slow.energy(q, u), "energy")
        _same(fast.kinematics(q, u), slow.kinematics(q, u), "q'")
        buf = np.empty(fast.n + fast.m + 1)
        kf, pa, db = fast.kernels.function("forward"), fast.kernel_parameters, fast.kernels.zero_db
        assert kf(np.asarray(q, float), np.asarray(u, float), 0.0, pa, db, buf) == 0
        _same(buf[: fast.n], b.accelerations, "u' written into a preallocated array")
        raw = fast.forward_fast(q, u, 0.3, db=np.full(max(fast.m, 1), 0.1))
        ref = slow.forward_fast(list(q), list(u), 0.3, db=[0.1] * max(slow.m, 1))
        _same(raw[0], ref[0], "raw u' with a b offset")
        _same(raw[1], ref[1], "raw lambda with a b offset")


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", ("slider_crank", "top_cartesian"))
def test_compiled_batch_equals_single_and_fallback_batch(monkeypatch, name, backend):
    fast, slow = _pair(monkeypatch, name, backend)
    states = consistent_states(slow, 8)
    Q = np.array([q for q, _ in states])
    U = np.array([u for _, u in states])
    UD, LAM, _piv = fast.forward_batch(Q, U, 0.2)
    UDs, LAMs, _pivs = slow.forward_batch(Q, U, 0.2)
    _same(UD, UDs, "batched u'")
    _same(LAM, LAMs, "batched lambda")
    for i in range(len(Q)):
        one = fast.forward(Q[i], U[i], 0.2)
        _same(UD[i], one.accelerations, "batch row vs single")
        _same(LAM[i], one.multipliers, "batch row vs single")


@pytest.mark.parametrize("backend", BACKENDS)
def test_singular_and_bad_states_raise_the_same_errors(monkeypatch, backend):
    """Slider-crank with l1 = l2 at theta1 = pi/2 on the branch theta2 = -theta1: A vanishes."""
    equal = {"l1": 0.3, "l2": 0.3, "r2": 0.15, "I_G2": 2.0 * 0.09 / 12}
    fast, slow = _pair(monkeypatch, "slider_crank", backend, equal)
    q, u = [math.pi / 2, -math.pi / 2], [8.0, -8.0]
    for nm in (fast, slow):
        with pytest.raises(SingularSystemError, match="singular at q"):
            nm.forward(q, u)
        with pytest.raises(SingularSystemError, match="1 of 2 states are singular"):
            nm.forward_batch(np.array([[0.5, -0.5], q]), np.array([[1.0, -1.0], u]))
        assert not nm.forward_fast(q, u, 0.0)[2] > 1e-12  # fast: the caller tests the ratio
        Q, U = np.array([[0.5, -0.5], q, [0.4, -0.4]]), np.array([[1.0, -1.0], u, [0.0, 0.0]])
        for bad in (Q, U):  # a NaN anywhere outranks the singular state before it
            bad[2, 1] = math.nan
            with pytest.raises(ModelInputError, match="batched states contain NaN or infinity"):
                nm.forward_batch(Q, U)
            bad[2, 1] = 0.0
    for bad, match in (
        ([[0.1], [0.0, 0.0]], "expected 2 coordinates"),
        ([[0.1, 0.2], [0.0]], "expected 2 speeds"),
        ([[0.1, math.nan], [0.0, 0.0]], "NaN or infinite"),
        ([[0.1, 0.2], [math.inf, 0.0]], "NaN or infinite"),
        ([["a", 0.2], [0.0, 0.0]], "must be numbers"),
    ):
        msgs = []
        for nm in (fast, slow):
            with pytest.raises(ModelInputError, match=match) as exc:
                nm.forward(*bad)
            msgs.append(str(exc.value))
        assert msgs[0] == msgs[1]


def test_backend_setting(monkeypatch):
    monkeypatch.setenv("CROSSCHECK_BACKEND", "python")
    assert NumericModel(models.get("pendulum_angle")).backend == "python"
    monkeypatch.setenv("CROSSCHECK_BACKEND", "fortran")
    with pytest.raises(ModelInputError, match="CROSSCHECK_BACKEND"):
        NumericModel(models.get("pendulum_angle"))


def test_without_a_compiler_auto_runs_python_and_says_so_once(monkeypatch, tmp_path, capsys):
    """'auto' without a working C compiler: the Python path, the same numbers, and one line on
    stderr the first time (the worker processes of a run inherit that it was said)."""
    from reference.backends import select

    monkeypatch.delenv("CROSSCHECK_BACKEND", raising=False)
    monkeypatch.setenv("CROSSCHECK_CC", str(tmp_path / "no-such-cc"))
    monkeypatch.setenv(select._TOLD, "")  # restored (unset) after the test
    nm = NumericModel(models.get("pendulum_xy"))
    again = NumericModel(models.get("slider_crank"))
    assert (nm.backend, again.backend) == ("python", "python")
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "no working C compiler" in err[0] and "CROSSCHECK_CC" in err[0]
    monkeypatch.setenv("CROSSCHECK_BACKEND", "numba")
    with pytest.raises(ModelInputError, match="numba backend was removed"):
        NumericModel(models.get("pendulum_xy"))


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_model_can_stay_on_the_python_path(monkeypatch, backend):
    """NumericModel(..., backend="python") keeps one model uncompiled whatever the setting
    (crosscheck run evaluates the second and third formulations at a few states that way):
    equal to the compiled model of the same formulation, and any other name is an error
    that says what can be asked for."""
    monkeypatch.setenv("CROSSCHECK_BACKEND", backend)
    model = models.get("slider_crank")
    other = model.formulations[1]
    fast = NumericModel(model, other)
    slow = NumericModel(model, other, backend="python")
    assert (fast.backend, slow.backend) == (backend, "python")
    for q, u in consistent_states(slow, 4):
        a, b = fast.forward(q, u), slow.forward(q, u)
        _same(a.accelerations, b.accelerations, "u'")
        _same(a.multipliers, b.multipliers, "lambda")
    with pytest.raises(ModelInputError, match="can ask for 'python'"):
        NumericModel(model, other, backend="c")
