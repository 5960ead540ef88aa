"""The choice of backend, in one place: the setting (CROSSCHECK_BACKEND) resolved against this
machine, the kernels each generated module gets, and the C builds started ahead of their use.

C where a C compiler works (reference.backends.c_build); the generated Python code
(reference.backends.python_kernels) where none does, where the C printer or compiler refuses a
module, or where a model asks for it. Both run the same expressions, so the numbers are the
same (to the bit but for CPython's x**2, tests/test_backends.py); the Python path is slower
(benchmarks/reference_speed.md), and each time it stands in for C, stderr says so in one line.

Why no third backend: numba stood between the two until it was measured against them (same
four models, derivations cached): a cold build of 2.7-9.2 s per model against C's 0.5-0.7 s,
calls 3-5x slower than C's, and a whole `crosscheck run` on it as fast as on the Python path
(24.3 s warm, 68.1 s cold, against 26.6 s on Python and 20.8 s on C), because the engines,
not the reference, take a run's time.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

from reference.backends import c_build, codegen
from reference.backends.c_source import UnsupportedExpression, c_source
from reference.backends.kernels import PIVOT_RATIO_MIN, TIMINGS, Kernels
from reference.backends.python_kernels import PythonKernels
from reference.errors import ModelInputError
from reference.formulations import derive
from reference.system import Model

SETTINGS = ("auto", "c", "python")

# set once the no-compiler line is written: the worker processes a run starts inherit it
_TOLD = "CROSSCHECK_BACKEND_TOLD"


def setting() -> str:
    """CROSSCHECK_BACKEND: 'auto' (unset: C where a C compiler works, else Python), 'c' (an
    error without a working compiler) or 'python'."""
    want = os.environ.get("CROSSCHECK_BACKEND", "").strip().lower() or "auto"
    if want not in SETTINGS:
        removed = " (the numba backend was removed: C or Python)" if want == "numba" else ""
        raise ModelInputError(
            f"CROSSCHECK_BACKEND={want!r}: valid values are {', '.join(SETTINGS)}{removed}"
        )
    return want


def backend() -> str:
    """The backend models get on this machine: 'c' or 'python'. CROSSCHECK_BACKEND=c without a
    working C compiler is an error naming the way out; 'auto' then takes Python and says so."""
    want = setting()
    if want == "python":
        return "python"
    if c_build.available():
        return "c"
    fix = (
        f"install gcc and python3-dev, or point CROSSCHECK_CC at a compiler "
        f"(tried: {' '.join(c_build.compiler())})"
    )
    if want == "c":
        raise ModelInputError(
            f"CROSSCHECK_BACKEND=c: no working C compiler or no Python headers; {fix}, "
            f"or use CROSSCHECK_BACKEND=auto"
        )
    if not os.environ.get(_TOLD):
        os.environ[_TOLD] = "1"
        notice(
            f"no working C compiler: the reference runs its generated Python code (the same "
            f"numbers, slower); {fix}"
        )
    return "python"


def notice(message: str) -> None:
    """One line on stderr: the user is told where the Python path stands in for C."""
    print(f"crosscheck: {message}", file=sys.stderr, flush=True)


def threads() -> int:
    """Threads of the batch kernels (CROSSCHECK_THREADS, default 1: a serial loop measured
    faster than two threads on the 2-core machine under load, benchmarks/reference_speed.md)."""
    try:
        return max(1, int(os.environ.get("CROSSCHECK_THREADS", "1")))
    except ValueError:
        raise ModelInputError("CROSSCHECK_THREADS must be a whole number >= 1") from None


def kernels(python: PythonKernels, src: str, stem: str, want: str | None = None) -> Kernels:
    """The kernels of generated module `src` (cache entry `stem`, its Python kernels
    `python`) on backend `want` (None: backend()). On C, a module the printer or the compiler
    refuses runs on Python: TIMINGS[stem]['c_error'] (bench.json) and one line on stderr say
    why. A model past codegen.UNROLL_KKT_MAX stays on Python: compiling its long straight-line
    M and A costs more than it saves on a model evaluated a few thousand times per run
    (benchmarks/scaling.md; measured with numba, not yet with C), and its forward is the
    numeric solve either way. So does a module on the sums path, whose M and f are summed by
    numpy (reference.backends.body_sums), which the C printer does not take."""
    _nq, n, _npar, m = python.dims
    if (want or backend()) == "python" or codegen.numeric_kkt(n, m) or python.summed:
        return python
    try:
        return c_build.load_kernels(src, stem, codegen.cache_dir(), python.dims, PIVOT_RATIO_MIN)
    except (c_build.BuildError, UnsupportedExpression, RecursionError) as exc:
        reason = str(exc) or type(exc).__name__
        TIMINGS.setdefault(stem, {})["c_error"] = reason
        notice(f"{stem} runs on the Python path: the C backend refused it ({reason})")
        return python


def prebuild_model(model: Model, formulations: Sequence[str] | None = None) -> None:
    """Start the C builds of `formulations` of `model` (default all), deriving what the cache
    lacks, so that each compiles while the next is derived and the first is checked
    (crosscheck run calls this with the first formulation before it builds the model's
    NumericModels). Does nothing off the C backend; a module the printer refuses is left to
    NumericModel, which records why."""
    if backend() != "c":
        return
    # the declared defaults, as NumericModel derives with them (the code depends on the model
    # only; the values are arguments)
    defaults = {p.name: float(p.default) for p in model.parameters}
    for f in formulations or model.formulations:
        scalar, _batched, src = codegen.load_compiled(
            lambda f=f: derive(model, f), model, f, defaults
        )
        n, m = len(model.speeds), scalar["META"]["m"]
        if codegen.numeric_kkt(n, m) or scalar["META"].get("sums"):
            continue
        try:
            text, _sizes = c_source(
                src, len(model.coordinates), n, len(model.parameters), m, PIVOT_RATIO_MIN
            )
        except (UnsupportedExpression, RecursionError):
            continue
        c_build.prebuild(text, scalar["__cache_path__"].stem, codegen.cache_dir())
