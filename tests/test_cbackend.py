"""The C backend's own behaviour (reference.backends.c_source, reference.backends.c_build): its
choice and refusal, its build cache, its fallback when the printer cannot translate a
model, the bound calls' lifetime and parameters, and the four-lane batch against the scalar kernel.
Equality with the Python path is tests/test_compiled.py's, bad inputs tests/test_fast_paths.py's
(both run on this backend too)."""

from __future__ import annotations

import gc
import math
import os
import shutil
import weakref
from pathlib import Path

import numpy as np
import pytest

from crosscheck.run.checks import consistent_states
from reference import NumericModel, models
from reference.backends import c_build as cbuild
from reference.backends import c_source as ckernels
from reference.backends import select
from reference.backends.kernels import SINGULAR, TIMINGS
from reference.errors import ModelInputError, SingularSystemError

pytestmark = pytest.mark.skipif(not cbuild.available(), reason="no working C compiler")


@pytest.fixture
def c_backend(monkeypatch):
    monkeypatch.setenv("CROSSCHECK_BACKEND", "c")


def test_auto_prefers_c_and_c_without_a_compiler_names_the_fix(monkeypatch, tmp_path):
    monkeypatch.delenv("CROSSCHECK_BACKEND", raising=False)
    assert NumericModel(models.get("pendulum_xy")).backend == "c"
    monkeypatch.setenv("CROSSCHECK_BACKEND", "c")
    monkeypatch.setenv("CROSSCHECK_CC", str(tmp_path / "no-such-cc"))
    with pytest.raises(ModelInputError, match=r"no working C compiler.*CROSSCHECK_CC"):
        NumericModel(models.get("pendulum_xy"))


def test_a_built_module_is_loaded_not_rebuilt(c_backend, fresh_cache):
    first = NumericModel(models.get("slider_crank"))
    stem = first.cache_path.stem
    assert TIMINGS[stem]["built"] is True
    (so,) = fresh_cache.glob(f"{stem}_c_*.so")
    before = so.stat().st_mtime_ns
    cbuild._LOADED.clear()  # as a new process would
    again = NumericModel(models.get("slider_crank"))
    assert TIMINGS[stem]["built"] is False and so.stat().st_mtime_ns == before
    q, u = first.model.initial_q, first.model.initial_u
    assert np.array_equal(first.forward(q, u).accelerations, again.forward(q, u).accelerations)


def test_a_checkout_elsewhere_finds_the_same_built_module(tmp_path, child):
    """A module's digest holds our headers by content, not the checkout's path: a copy of the
    package in another directory (a git worktree, a CI cache restored elsewhere) names the
    same module, so a shared cache loads it instead of building every module again."""
    shutil.copytree(
        Path(cbuild.__file__).parents[1],
        tmp_path / "reference",
        ignore=shutil.ignore_patterns("__pycache__"),
    )
    code = (
        "import sys; from pathlib import Path; from reference.backends import c_build as cbuild\n"
        f"assert cbuild.__file__.startswith({str(tmp_path)!r}), cbuild.__file__\n"
        "print(cbuild._target('double f(double x) { return x; }', 's', Path('.'))[1])\n"
    )
    out = child.python(code, env={"PYTHONPATH": tmp_path}, check=True)
    here = cbuild._target("double f(double x) { return x; }", "s", tmp_path)
    assert out.stdout.strip() == here[1]
    assert f"-I{os.path.dirname(cbuild.__file__)}" in here[2]  # the compiler still finds them


def test_two_processes_building_the_same_module_at_once_both_get_it(child, fresh_cache):
    """Each process compiles its own source and object file and renames the object into
    place: neither reads a file the other is writing."""
    code = (
        "import numpy as np\n"
        "from reference import NumericModel, models\n"
        "nm = NumericModel(models.get('slider_crank'))\n"
        "assert nm.backend == 'c', nm.backend\n"
        "print(nm.forward(np.array(nm.model.initial_q), np.array(nm.model.initial_u)))\n"
    )
    procs = [child.start("-c", code, env={"CROSSCHECK_BACKEND": "c"}) for _ in range(2)]
    outs = []
    for p in procs:
        with p:
            outs.append(p.communicate(timeout=600)[0])
    assert [p.returncode for p in procs] == [0, 0] and outs[0] == outs[1]
    assert len(list(fresh_cache.glob("*_c_*.so"))) == 1
    assert not list(fresh_cache.glob("*.tmp")) and not list(fresh_cache.glob("*_c_*.*.c"))


def test_prebuild_compiles_ahead_and_each_model_takes_its_module(c_backend, fresh_cache):
    cbuild._LOADED.clear()
    model = models.get("slider_crank")
    select.prebuild_model(model)
    built = [NumericModel(model, f) for f in model.formulations]
    assert all(nm.backend == "c" for nm in built)
    assert len(list(fresh_cache.glob("*_c_*.so"))) == len({nm.source for nm in built})
    assert not list(fresh_cache.glob("*.tmp"))
    assert not [t for t in cbuild._IN_FLIGHT if t.parent == fresh_cache]  # each one taken
    q, u = np.array(model.initial_q, float), np.array(model.initial_u, float)
    a, b = built[0].forward(q, u), built[-1].forward(q, u)
    assert np.allclose(a.accelerations, b.accelerations, rtol=1e-11, atol=1e-11)


def test_a_compiler_that_fails_in_a_prebuild_leaves_the_model_on_the_python_path(
    c_backend, monkeypatch, tmp_path, capsys, fresh_cache
):
    """Fault injection: a 'compiler' that answers --version and rejects every module. Each
    module runs on the Python path, and stderr says so in one line per module."""
    cc = tmp_path / "broken-cc"
    cc.write_text(
        '#!/bin/sh\nif [ "$1" = --version ]; then echo broken-cc 1.0; exit 0; fi\n'
        'echo "error: refusing on purpose" >&2; exit 1\n'
    )
    cc.chmod(0o755)
    monkeypatch.setenv("CROSSCHECK_CC", str(cc))
    cbuild._LOADED.clear()
    model = models.get("pendulum_xy")
    select.prebuild_model(model)
    for f in model.formulations:  # each takes (and so ends) its own failed build
        nm = NumericModel(model, f)
        stem = nm.cache_path.stem
        assert nm.backend == "python"
        assert "rejected the module (error: refusing on purpose" in TIMINGS[stem]["c_error"]
        (line,) = capsys.readouterr().err.splitlines()
        assert line.startswith(f"crosscheck: {stem} runs on the Python path"), line


def test_a_compiler_without_openmp_still_builds_every_module(
    c_backend, monkeypatch, tmp_path, fresh_cache
):
    """Fault injection: gcc refusing -fopenmp, as Apple's clang does. The probe finds it once,
    the modules build without it (the batch loops serial) and the answers are the same."""
    gcc = shutil.which("gcc") or shutil.which("cc")
    if gcc is None:
        pytest.skip("no gcc to wrap")
    cc = tmp_path / "cc-without-openmp"
    cc.write_text(
        '#!/bin/sh\nfor a in "$@"; do [ "$a" = -fopenmp ] && '
        "{ echo 'clang: error: unsupported option -fopenmp' >&2; exit 1; }; done\n"
        f'exec {gcc} "$@"\n'
    )
    cc.chmod(0o755)
    monkeypatch.setenv("CROSSCHECK_CC", str(cc))
    cbuild._openmp.cache_clear()
    cbuild._LOADED.clear()
    try:
        assert cbuild.openmp() is False
        assert "-fopenmp" not in cbuild.compile_flags()
        nm = NumericModel(models.get("slider_crank"))
        assert nm.backend == "c"
        stem = nm.cache_path.stem
        assert "c_error" not in TIMINGS[stem] and TIMINGS[stem]["built"]
        q, u = nm.model.initial_q, nm.model.initial_u
        batch = nm.forward_batch(np.array([q] * 9), np.array([u] * 9), 0.0)
        assert np.array_equal(batch[0][4], nm.forward(q, u).accelerations)
    finally:
        cbuild._openmp.cache_clear()
        cbuild._LOADED.clear()


def test_a_model_the_printer_cannot_translate_takes_the_python_path(
    c_backend, monkeypatch, fresh_cache
):
    """Fault injection: a printer without sqrt refuses every model's forward (its Cholesky)."""
    monkeypatch.setattr(ckernels, "_FUNCTIONS", ckernels._FUNCTIONS - {"sqrt"})
    cbuild._LOADED.clear()
    nm = NumericModel(models.get("pendulum_xy"))
    stem = nm.cache_path.stem
    assert nm.backend == "python"
    assert "function sqrt" in TIMINGS[stem]["c_error"]
    monkeypatch.setenv("CROSSCHECK_BACKEND", "python")
    ref = NumericModel(models.get("pendulum_xy"))
    q, u = nm.model.initial_q, nm.model.initial_u
    assert np.array_equal(nm.forward(q, u).accelerations, ref.forward(q, u).accelerations)


def test_bound_calls_do_not_keep_their_model_alive(c_backend):
    nm = NumericModel(models.get("pendulum_xy"))
    nm.forward(np.array(nm.model.initial_q, float), np.array(nm.model.initial_u, float))
    ref = weakref.ref(nm)
    del nm
    gc.collect()
    assert ref() is None


def test_with_params_rebinds_the_c_calls(c_backend, monkeypatch):
    nm = NumericModel(models.get("slider_crank"))
    heavy = nm.with_params({"m3": 5.0})
    monkeypatch.setenv("CROSSCHECK_BACKEND", "python")
    ref = NumericModel(models.get("slider_crank"), params={"m3": 5.0})
    q, u = np.array(nm.model.initial_q, float), np.array(nm.model.initial_u, float)
    assert np.array_equal(heavy.forward(q, u).multipliers, ref.forward(q, u).multipliers)
    assert not np.array_equal(nm.forward(q, u).multipliers, ref.forward(q, u).multipliers)
    _ud, lam, _piv = heavy.forward_fast(q, u, 0.0)
    assert np.array_equal(lam, ref.forward(q, u).multipliers)


def test_bound_fast_call_takes_keywords_and_number_types(c_backend):
    nm = NumericModel(models.get("slider_crank"))
    q, u = np.array(nm.model.initial_q, float), np.array(nm.model.initial_u, float)
    bound = nm._fast  # the C call forward_fast makes (CKernels.bind)
    assert type(bound).__name__ == "Bound"
    base = nm.forward_fast(q, u, 0.5)
    out = np.empty(nm.n + nm.m + 1)
    assert bound(q, u, 0.5, out=out) is out and np.array_equal(out[: nm.n], base[0])
    for t in (np.float64(0.5), 0.5, np.float32(0.5)):
        assert np.array_equal(nm.forward_fast(q, u, t)[1], base[1])
    shifted = bound(q, u, 0.5, db=np.full(nm.m, 0.1))  # Baumgarte: the Python path
    assert not np.array_equal(shifted[0], base[0])
    assert np.array_equal(shifted[0], nm.forward_fast(q, u, 0.5, np.full(nm.m, 0.1))[0])
    with pytest.raises(ModelInputError, match="db offsets"):
        nm.forward_fast(q, u, 0.5, db=np.zeros(nm.m - 1))


def test_four_lane_batch_equals_the_scalar_kernel_and_judges_each_lane(c_backend):
    """Slider-crank with l1 = l2: theta1 = pi/2 on the branch theta2 = -theta1 is singular.
    Ten states: two blocks of four on the vector body (one holding the singular state) and a
    tail of two on the scalar kernel; the same with one parameter row per state, and with rows
    that differ (a sweep), each state against the scalar kernel on its own row."""
    equal = {"l1": 0.3, "l2": 0.3, "r2": 0.15, "I_G2": 2.0 * 0.09 / 12}
    nm = NumericModel(models.get("slider_crank"), params=equal)
    states = consistent_states(nm, 10)
    Q = np.array([q for q, _ in states], float)
    U = np.array([u for _, u in states], float)
    UD, LAM, piv = nm.forward_batch(Q, U, 0.25)
    for i in range(len(Q)):
        one = nm.forward(Q[i], U[i], 0.25)
        assert np.array_equal(UD[i], one.accelerations) and np.array_equal(LAM[i], one.multipliers)
        assert piv[i] == one.pivot_ratio
    Q[5], U[5] = [math.pi / 2, -math.pi / 2], [8.0, -8.0]
    with pytest.raises(SingularSystemError, match="1 of 10 states are singular; first: index 5"):
        nm.forward_batch(Q, U, 0.25)
    k, pa, nf = nm.kernels, nm.kernel_parameters, nm.n + nm.m + 1
    kf = k.batch("forward")
    N = len(Q)
    out1, out2 = np.empty((N, nf)), np.empty((N, nf))
    st1, st2 = np.empty(N, np.int64), np.empty(N, np.int64)
    T, DB = np.array([0.25]), k.zero_db[None]
    kf(Q, U, T, pa[None], DB, out1, st1)  # shared parameters: splatted
    kf(Q, U, T, np.tile(pa, (N, 1)), DB, out2, st2)  # one row per state: gathered
    assert st1.tolist() == st2.tolist() and st1[5] == SINGULAR
    assert np.array_equal(out1, out2, equal_nan=True)
    P = np.tile(pa, (N, 1))
    P[:, 0] *= np.linspace(0.5, 2.0, N)  # a different first parameter in every lane
    kf(Q, U, T, P, np.tile(DB, (N, 1)), out2, st2)
    one, out = k.function("forward"), np.empty(nf)
    for i in range(N):
        assert one(Q[i], U[i], 0.25, P[i], k.zero_db, out) == st2[i]
        assert np.array_equal(out, out2[i], equal_nan=True)


def test_the_four_lane_printer_pairs_sin_and_cos_of_a_state_and_of_a_parameter():
    """A sin/cos pair of a coordinate becomes one sincos per lane, and so does one of a
    parameter: parameters are lanes too (a sweep gives each state its own)."""
    src = (
        "META = {'n': 1, 'm': 0}\n"
        "def forward(_q, _u, _t, _p, _sref, _db=None):\n"
        "    _q0, = _q\n    _u0, = _u\n    _p0, = _p\n"
        "    _a = sin(_p0)\n    _b = cos(_p0)\n    _c = cos(_q0)\n    _d = sin(_q0)\n"
        "    return [_a*_d + _b*_c*_u0], [], 1.0\n"
    )
    text, sizes = ckernels.c_source(src, 1, 1, 1, 0, 1e-12)
    lanes = text[text.index("forward_body4") :]
    assert "v_sincos(_p0, &_a, &_b);" in lanes and "const vd _p0 = pa[0];" in lanes
    assert "v_sincos(_q0, &_d, &_c);" in lanes and sizes == {"forward": [1, 0]}
