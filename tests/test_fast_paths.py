"""Bad inputs on every fast single-state path of the forward dynamics.

The C kernels take one signature (float64 C-contiguous vectors and a float): their argument
checks reject anything else with a TypeError (the bound checked and fast calls hand such a
state to the Python method instead), which NumericModel turns into a conversion (then the same
answer as float64 vectors) or a one-line ModelInputError. The generated Python takes lists as
well; it writes into whatever `out` it is given, so NumericModel checks a caller's `out` before
any kernel writes it. Each test runs on both backends, each case compared with the answer at
the same state given as float64 vectors on the same model.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from reference import NumericModel, models
from reference.backends import c_build as cbuild
from reference.backends.kernels import OK
from reference.errors import ModelInputError
from reference.numeric.model import Forward
from tests.support import state

MODELS = ("slider_crank", "top_cartesian")
NEEDS = {
    "c": pytest.mark.skipif(not cbuild.available(), reason="no working C compiler"),
    "python": (),
}


@pytest.fixture(
    params=[pytest.param((m, b), marks=NEEDS[b], id=f"{m}-{b}") for m in MODELS for b in NEEDS]
)
def nm(request, monkeypatch):
    name, backend = request.param
    monkeypatch.setenv("CROSSCHECK_BACKEND", backend)
    nm = NumericModel(models.get(name))
    assert nm.backend == backend
    return nm


def _nf(nm):
    return nm.n + nm.m + 1


def _variants(x: np.ndarray) -> dict:
    """The same values as the inputs a caller might hand over instead of float64 vectors."""
    wide = np.zeros(2 * x.size)
    wide[::2] = x
    odd = np.frombuffer(b"\0" + x.tobytes(), dtype=np.float64, count=x.size, offset=1)
    ro = x.copy()
    ro.flags.writeable = False
    big_endian = x.astype(">f8")
    return {
        "list": x.tolist(),
        "tuple": tuple(x.tolist()),
        "strided view": wide[::2],
        "reversed view": x[::-1].copy()[::-1],
        "row of a 2-D array": x[None, :],
        "column": x[:, None],
        "read-only": ro,
        "misaligned": odd,
        "big-endian": big_endian,
    }


def _equal_variants(x: np.ndarray) -> dict:
    return _variants(x) | {"float32 of float32 values": x.astype(np.float32)}


def test_every_input_form_gives_the_float64_answer(nm):
    q, u = state(nm)
    q, u = (x.astype(np.float32).astype(float) for x in (q, u))  # values float32 holds
    ref, nf = nm.forward(q, u), _nf(nm)
    for what, qv in _equal_variants(q).items():
        for name, call in (
            ("forward", lambda qv=qv: nm.forward(qv, u).accelerations),
            ("forward_fast", lambda qv=qv: nm.forward_fast(qv, u, 0.0)[0]),
            ("forward_fast(out=)", lambda qv=qv: nm.forward_fast(qv, u, 0.0, out=np.empty(nf))),
        ):
            got = np.asarray(call(), float)[: nm.n]
            assert np.array_equal(got, ref.accelerations), f"{name} with q as {what}"
        for what_u, uv in _equal_variants(u).items():
            f = nm.forward(q, uv)
            assert np.array_equal(f.multipliers, ref.multipliers), f"u as {what_u}"


def test_integer_state_is_converted_not_misread(nm):
    q, u = state(nm)
    qi, ui = np.round(q).astype(np.int64), np.round(u).astype(np.int64)
    want = nm.forward(qi.astype(float), ui.astype(float))
    assert np.array_equal(nm.forward(qi, ui).accelerations, want.accelerations)
    assert np.array_equal(nm.forward_fast(qi, ui, 0)[1], want.multipliers)
    out = nm.forward_fast(qi, ui, 0, out=np.empty(_nf(nm)))
    assert np.array_equal(out[: nm.n], want.accelerations)
    assert nm.forward(q, u, 0).pivot_ratio == nm.forward(q, u, 0.0).pivot_ratio  # int t


@pytest.mark.parametrize("bad", ("short q", "long u", "nan", "inf t", "text", "empty"))
def test_bad_state_is_a_clear_error_on_every_path(nm, bad):
    q, u = state(nm)
    t = 0.0
    if bad == "short q":
        q, match = q[:-1], "expected .* coordinates"
    elif bad == "long u":
        u, match = np.append(u, 0.0), "expected .* speeds"
    elif bad == "nan":
        q, match = np.where(np.arange(q.size) == 1, math.nan, q), "NaN or infinite"
    elif bad == "inf t":
        t, match = math.inf, "NaN or infinite"
    elif bad == "text":
        q, match = ["a", *q.tolist()[1:]], "must be numbers"
    else:
        q, match = np.empty(0), "expected .* coordinates"
    with pytest.raises(ModelInputError, match=match):
        nm.forward(q, u, t)
    if bad in ("nan", "inf t"):  # the fast call: NaN in, NaN out (the caller's ratio test)
        assert np.isnan(nm.forward_fast(q, u, t)[0]).all()
        assert np.isnan(nm.forward_fast(q, u, t, out=np.zeros(_nf(nm)))).all()
        return
    with pytest.raises(ModelInputError, match=match):
        nm.forward_fast(q, u, t)
    with pytest.raises(ModelInputError, match=match):
        nm.forward_fast(q, u, t, out=np.empty(_nf(nm)))


def _bad_outs(nf: int) -> dict:
    ro = np.empty(nf)
    ro.flags.writeable = False
    return {
        "short": np.empty(nf - 1),
        "long": np.empty(nf + 1),
        "int64": np.zeros(nf, np.int64),
        "float32": np.zeros(nf, np.float32),
        "strided": np.empty(2 * nf)[::2],
        "2-D": np.empty((nf, 1)),
        "0-D": np.empty(()),
        "read-only": ro,
        "list": [0.0] * nf,
        "number": 1.0,
    }


def test_bad_out_is_a_clear_error_and_nothing_is_written(nm):
    q, u = state(nm)
    for what, out in _bad_outs(_nf(nm)).items():
        before = np.array(out, copy=True) if isinstance(out, np.ndarray) else None
        with pytest.raises(ModelInputError, match="out must be a writable C-contiguous") as e:
            nm.forward_fast(q, u, 0.0, out=out)
        assert "\n" not in str(e.value), what
        if before is not None and what not in ("short", "long"):  # those hold garbage
            assert np.array_equal(np.asarray(out), before, equal_nan=True), what


def test_the_kernel_refuses_what_it_cannot_read(nm):
    """The kernel layer beneath forward_fast: float64 vectors and a number in, a status out;
    on C anything else is a TypeError (nothing is read or written), the generated Python
    converts what holds numbers and refuses the rest with a TypeError too."""
    q, u = state(nm)
    kf, pa, db = nm.kernels.function("forward"), nm.kernel_parameters, nm.kernels.zero_db
    out = np.empty(_nf(nm))
    assert kf(q, u, 0.0, pa, db, out) == OK
    assert np.array_equal(out[: nm.n], nm.forward(q, u).accelerations)
    for what, qv in _variants(q).items():
        vector = (
            isinstance(qv, np.ndarray)
            and qv.ndim == 1
            and qv.flags.c_contiguous
            and qv.flags.aligned
            and qv.dtype == float
        )
        if vector or nm.kernels.takes_sequences:
            assert kf(qv, u, 0.0, pa, db, out) == OK, what
            assert np.array_equal(out[: nm.n], nm.forward(q, u).accelerations), what
            continue
        with pytest.raises(TypeError):
            kf(qv, u, 0.0, pa, db, out)
    with pytest.raises(TypeError):
        kf(["a", *q.tolist()[1:]], u, 0.0, pa, db, out)


def test_out_call_returns_the_callers_array_and_the_raw_triple_is_fresh(nm):
    q, u = state(nm)
    out = np.empty(_nf(nm))
    assert nm.forward_fast(q, u, 0.0, out=out) is out
    ud, lam, piv = nm.forward_fast(q, u, 0.0)
    ud2, _lam2, _ = nm.forward_fast(q + 0.01, u, 0.0)
    assert not np.shares_memory(ud, ud2)  # integrators keep stage results
    assert out[-1] == piv and isinstance(piv, float)
    assert np.array_equal(out[: nm.n], ud) and np.array_equal(out[nm.n : -1], lam)


def test_lists_on_the_fast_call_match_vectors(nm):
    q, u = state(nm)
    out = nm.forward_fast(q.tolist(), u.tolist(), 0.0, out=np.empty(_nf(nm)))
    ud, lam, piv = nm.forward_fast(q.tolist(), u.tolist(), 0.0)
    assert np.array_equal(out, np.r_[ud, lam, piv])
    assert np.array_equal(out, nm.forward_fast(q, u, 0.0, out=np.empty(_nf(nm))))
    with pytest.raises(ModelInputError, match="out must be"):
        nm.forward_fast(q.tolist(), u.tolist(), 0.0, out=np.empty(_nf(nm) - 1))


def test_forward_record_keeps_the_dataclass_behaviour(nm):
    q, u = state(nm)
    a, b = nm.forward(q, u), nm.forward(q, u)
    assert a.rank is None and isinstance(a.pivot_ratio, float)
    assert a == a  # the dataclass's equality: field by field, the same arrays compare equal
    same = Forward(
        accelerations=a.accelerations, multipliers=a.multipliers, pivot_ratio=a.pivot_ratio
    )
    assert same == a and repr(same) == repr(a)
    assert not np.shares_memory(a.accelerations, b.accelerations)  # fresh per call
    a.accelerations = np.zeros(nm.n)  # fields stay assignable
    assert not a.accelerations.any()


def test_bench_names_every_reference_call_and_the_out_ratio():
    from crosscheck.bench import forward as bench
    from crosscheck.engines.registry import get_engine

    recs = bench._model_forward_records("pendulum_xy", True, [get_engine("pinocchio")])
    by_path = {r["path"]: r for r in recs}
    for path, call in bench.PATHS.items():
        assert by_path[path]["call"] == call and by_path[path]["us_per_state"] > 0, path
    (row,) = bench.forward_ratios(recs)
    pin = by_path["engine:pinocchio"]["us_per_state"]
    assert row["raw_out_over_pinocchio"] == by_path["single-raw-out"]["us_per_state"] / pin
    assert row["raw_over_pinocchio"] == by_path["single-raw"]["us_per_state"] / pin
    assert "raw into the caller's out <= 0.25 x pinocchio" in row["met"]
