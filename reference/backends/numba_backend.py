"""Numba backend for the generated code of reference.backends.codegen, and the choice of
backend (the C one is reference.backends.c_source and reference.backends.c_build).

The generated Python module (straight-line functions of lists, returning lists) is rewritten,
with the `ast` module, into a numba module: every function becomes a kernel that reads its inputs
from float64 arrays by index and writes its outputs, group after group, into one preallocated
array, and returns a status code (STATUS). The size and finiteness checks and the KKT pivot test
run inside the kernel, so the checked public call costs one compiled call; Python only turns a
nonzero status into the same error as the pure-Python path (reference/errors.py).

Why a file: numba's cache=True keys its on-disk cache on the source file's path and
modification time (and the CPU), so the module is written once into the derivation cache
directory next to the generated Python, and rewritten only when its content changes (which
would otherwise recompile every kernel in every process).

Pitfalls handled here: math.sqrt of a negative pivot gives NaN silently with
error_model="numpy" (no ValueError as in CPython), and Python's min() drops a NaN that is not
its first argument, so the pivot ratio is reduced with _nmin, which propagates NaN, and the test
is `not (piv > PIVOT_RATIO_MIN)`, which is true for NaN.

Backend choice (`setting`, `backend`): C where a compiler works, else numba, else the
pure-Python path, which stays the fallback and the cross-check of both.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import json
import os
import sys
import time
from pathlib import Path

# status codes returned by every kernel (0: ok); NOT_DEFINED: finite input, non-finite output
# (a division by zero in the derived expressions, e.g. gimbal lock of Euler angles: numba's
# numpy error model returns inf or NaN there where Python raises ZeroDivisionError)
OK, BAD_Q_SIZE, BAD_U_SIZE, NOT_FINITE, SINGULAR, NOT_DEFINED = 0, 1, 2, 3, 4, 5

FUNCTIONS = ("forward", "matrices", "kinematics", "residuals", "position_jacobian", "energy")

# compile/load times of the kernels in this process, per cache entry (bench.json reports them)
TIMINGS: dict[str, dict] = {}


def numba_available() -> bool:
    return importlib.util.find_spec("numba") is not None


def setting() -> str:
    """CROSSCHECK_BACKEND: 'auto' (unset: the C kernels where a C compiler works, built in the
    process in about a second per model; else the numba kernels where numba's cache holds
    them, else the Python path now and a numba compile in the background after the process
    ends), 'c', 'numba' (compile here when needed) or 'python' (the fallback only)."""
    want = os.environ.get("CROSSCHECK_BACKEND", "").strip().lower() or "auto"
    if want not in ("auto", "c", "numba", "python"):
        from reference.errors import ModelInputError

        raise ModelInputError(
            f"CROSSCHECK_BACKEND={want!r}: valid values are auto, c, numba, python"
        )
    if want == "numba" and not numba_available():
        return "python"
    return want


def backend() -> str:
    """The compiled backend models get: 'c', 'numba' or 'python' (the setting, resolved
    against what this machine has). CROSSCHECK_BACKEND=c without a working C compiler is an
    error naming the way out; 'auto' then takes numba."""
    want = setting()
    if want in ("auto", "c"):
        from reference.backends import c_build as cbuild

        if cbuild.available():
            return "c"
        if want == "c":
            from reference.errors import ModelInputError

            raise ModelInputError(
                f"CROSSCHECK_BACKEND=c: no working C compiler ({' '.join(cbuild.compiler())}) "
                f"or no Python headers; install gcc and python3-dev, point CROSSCHECK_CC at a "
                f"compiler, or use CROSSCHECK_BACKEND=auto"
            )
    if want == "python" or not numba_available():
        return "python"
    return "numba"


def threads() -> int:
    """Threads of the batched kernels (CROSSCHECK_THREADS, default 1: a serial loop measured
    faster than prange with 2 threads on the 2-core machine under load, docs/compiled.md)."""
    try:
        return max(1, int(os.environ.get("CROSSCHECK_THREADS", "1")))
    except ValueError:
        from reference.errors import ModelInputError

        raise ModelInputError("CROSSCHECK_THREADS must be a whole number >= 1") from None


# ---- source transformation -----------------------------------------------------------------
def output_groups(ret: ast.Return) -> tuple[list[list[ast.expr]], ast.expr | None]:
    """The returned list groups of a generated function, and forward's pivot expression."""
    elts = ret.value.elts if isinstance(ret.value, ast.Tuple) else [ret.value]
    groups = [e.elts for e in elts if isinstance(e, ast.List)]
    rest = [e for e in elts if not isinstance(e, ast.List)]
    return groups, (rest[0] if rest else None)


def _pivot_code(e: ast.expr) -> str:
    """_min(a, b, ...) as a NaN-propagating chain of _nmin."""
    if isinstance(e, ast.Call) and isinstance(e.func, ast.Name) and e.func.id == "_min":
        code = ast.unparse(e.args[0])
        for a in e.args[1:]:
            code = f"_nmin({code}, {ast.unparse(a)})"
        return code
    return ast.unparse(e)


class _Sref(ast.NodeTransformer):
    """_sref[k] -> _pa[npar + k]: the Schur references travel after the parameters."""

    def __init__(self, npar: int):
        self.npar = npar

    def visit_Subscript(self, node):
        if isinstance(node.value, ast.Name) and node.value.id == "_sref":
            k = node.slice.value
            return ast.Subscript(
                ast.Name("_pa", ast.Load()), ast.Constant(self.npar + k), ast.Load()
            )
        return self.generic_visit(node)


def _kernel(
    fn: ast.FunctionDef, nq: int, n: int, npar: int, pmin: float
) -> tuple[list[str], list[int]]:
    """Lines of `<name>_body` (reads arrays, writes _out, returns a status) and group sizes."""
    fn = _Sref(npar).visit(fn)
    forward = fn.name == "forward"
    args = "_qa, _ua, _t, _pa, _db, _out" if forward else "_qa, _ua, _t, _pa, _out"
    lines = ["@njit(cache=True, error_model='numpy', nogil=True)", f"def {fn.name}_body({args}):"]
    lines += [f"    _q{i} = _qa[{i}]" for i in range(nq)]
    lines += [f"    _u{i} = _ua[{i}]" for i in range(n)]
    lines += [f"    _p{i} = _pa[{i}]" for i in range(npar)]
    ret = None
    for st in fn.body:
        if isinstance(st, ast.Return):
            ret = st
        elif isinstance(st, ast.Assign) and isinstance(st.targets[0], ast.Tuple):
            continue  # the unpacking of _q, _u, _p, done above by index
        else:
            lines.append("    " + ast.unparse(st))
    if ret is None:
        raise ValueError(f"generated function {fn.name} has no return statement")
    groups, piv = output_groups(ret)
    k = 0
    for g in groups:
        for e in g:
            lines.append(f"    _out[{k}] = {ast.unparse(e)}")
            k += 1
    lines.append("    _fin = True")  # one test per output: a NaN never passes silently
    lines += [f"    _fin = _fin and isfinite(_out[{j}])" for j in range(k)]
    if forward:
        lines.append(f"    _piv = {_pivot_code(piv)}" if piv is not None else "    _piv = 1.0")
        lines.append(f"    _out[{k}] = _piv")
        lines.append(
            f"    return ({OK} if _fin else {NOT_DEFINED}) if _piv > {pmin!r} else {SINGULAR}"
        )
    else:
        lines.append(f"    return {OK} if _fin else {NOT_DEFINED}")
    return lines, [len(g) for g in groups]


_PRELUDE = """from math import sin, cos, tan, sqrt, exp, log, atan2, pi, isfinite
import numpy as np
from numba import njit, prange

NQ, NU, NP, M = {nq}, {n}, {npar}, {m}


@njit(cache=True, error_model='numpy', inline='always')
def _nmin(a, b):
    if a != a or b != b:
        return a + b  # NaN
    return a if a < b else b


@njit(cache=True, error_model='numpy', nogil=True)
def _check(_qa, _ua, _t):
    if _qa.shape[0] != NQ:
        return {BAD_Q_SIZE}
    if _ua.shape[0] != NU:
        return {BAD_U_SIZE}
    s = _t
    for i in range(NQ):
        s += _qa[i]
    for i in range(NU):
        s += _ua[i]
    # one sum is finite exactly when every term is, unless finite terms overflow: then look
    if not isfinite(s):
        if not isfinite(_t):
            return {NOT_FINITE}
        for i in range(NQ):
            if not isfinite(_qa[i]):
                return {NOT_FINITE}
        for i in range(NU):
            if not isfinite(_ua[i]):
                return {NOT_FINITE}
    return {OK}
"""


def _batch_forward(body: list[str]) -> list[str]:
    """forward_batch with the body inside the loop: reads _Q[i, k] and writes _OUT[i, k]
    directly, so no row views and no call per state (measured: the per-state overhead of a
    loop calling the single-state kernel bounded the batch, docs/compiled.md)."""
    lines = [
        "@njit(cache=True, error_model='numpy', nogil=True)",
        "def forward_batch(_Q, _U, _T, _P, _DB, _OUT, _ST):",
        "    nt, np_, nd = _T.shape[0] > 1, _P.shape[0] > 1, _DB.shape[0] > 1",
        "    for _i in range(_Q.shape[0]):",
        "        _t = _T[_i if nt else 0]",
        "        _jp = _i if np_ else 0",
        "        _jd = _i if nd else 0",
    ]
    for ln in body[2:]:
        ln = (
            ln.replace("_qa[", "_Q[_i, ")
            .replace("_ua[", "_U[_i, ")
            .replace("_pa[", "_P[_jp, ")
            .replace("_db[", "_DB[_jd, ")
            .replace("_out[", "_OUT[_i, ")
        )
        if ln.startswith("    return "):
            ln = "    _ST[_i] = " + ln[len("    return ") :]
        lines.append("    " + ln)
    return lines


_WRAPPERS = """

@njit(cache=True, error_model='numpy', nogil=True)
def {name}({args}):
    st = _check(_qa, _ua, _t)
    if st != {OK}:
        return st
    return {name}_body({args})


@njit(cache=True, error_model='numpy', nogil=True)
def {name}_batch(_Q, _U, _T, _P, _DB, _OUT, _ST):
    nt, np_, nd = _T.shape[0] > 1, _P.shape[0] > 1, _DB.shape[0] > 1
    for i in range(_Q.shape[0]):
        _ST[i] = {name}({bargs})


@njit(cache=True, error_model='numpy', parallel=True)
def {name}_batch_parallel(_Q, _U, _T, _P, _DB, _OUT, _ST):
    nt, np_, nd = _T.shape[0] > 1, _P.shape[0] > 1, _DB.shape[0] > 1
    for i in prange(_Q.shape[0]):
        _ST[i] = {name}({bargs})
"""


def numba_source(src: str, nq: int, n: int, npar: int, m: int, pmin: float) -> tuple[str, dict]:
    """The numba module for a generated Python module, and each function's group sizes."""
    tree = ast.parse(src)
    out = [
        _PRELUDE.format(
            nq=nq,
            n=n,
            npar=npar,
            m=m,
            OK=OK,
            BAD_Q_SIZE=BAD_Q_SIZE,
            BAD_U_SIZE=BAD_U_SIZE,
            NOT_FINITE=NOT_FINITE,
        )
    ]
    sizes = {}
    for fn in tree.body:
        if not isinstance(fn, ast.FunctionDef):
            continue
        lines, sizes[fn.name] = _kernel(fn, nq, n, npar, pmin)
        out += ["", "", *lines]
        fwd = fn.name == "forward"
        if fwd:
            out += ["", "", *_batch_forward(lines)]
        args = "_qa, _ua, _t, _pa, _db, _out" if fwd else "_qa, _ua, _t, _pa, _out"
        bargs = (
            "_Q[i], _U[i], _T[i if nt else 0], _P[i if np_ else 0], "
            + ("_DB[i if nd else 0], " if fwd else "")
            + "_OUT[i]"
        )
        wrappers = _WRAPPERS.format(name=fn.name, args=args, bargs=bargs, OK=OK)
        if fwd:  # forward_batch is the inlined loop above
            head = "@njit(cache=True, error_model='numpy', nogil=True)\ndef forward_batch("
            a = wrappers.index(head)
            wrappers = wrappers[:a] + wrappers[wrappers.index("@njit", a + 1) :]
        out.append(wrappers)
    totals = {k: sum(g) + (1 if k == "forward" else 0) for k, g in sizes.items()}
    out.append(f"OUT_SIZES = {totals!r}")
    return "\n".join(out) + "\n", sizes


# ---- loading ---------------------------------------------------------------------------------
def _write_if_changed(path: Path, text: str) -> bool:
    """Write `text` atomically unless the file already holds it (numba keys on the file)."""
    if path.exists() and path.read_text() == text:
        return False
    tmp = path.with_suffix(f".{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)
    return True


class Kernels:
    """The kernels of one cache entry, compiled (or loaded from numba's cache) on first use,
    and the output layout of each function. `get(name)` returns the checked single-state
    kernel, `get(name + "_batch")` the serial batch, `get(name + "_batch_parallel")` prange."""

    def __init__(self, module, sizes: dict, stem: str, nq: int, n: int, npar: int, m: int):
        self.module = module
        self.sizes = sizes
        self.stem = stem
        self.dims = (nq, n, npar, m)
        self.offsets = {}
        for name, gs in sizes.items():
            offs, k = [], 0
            for g in gs:
                offs.append((k, k + g))
                k += g
            self.offsets[name] = offs
        self.total = {name: sum(gs) + (1 if name == "forward" else 0) for name, gs in sizes.items()}
        self.ready: dict = {}

    def get(self, kname: str):
        f = self.ready.get(kname)
        if f is None:
            f = self.ready[kname] = self._compile(kname)
        return f

    def _compile(self, kname: str):
        """Compile or load `kname` with a first call on dummy inputs; record how long it took."""
        import numpy as np

        nq, n, npar, m = self.dims
        name = kname.split("_batch")[0]
        f = getattr(self.module, kname)
        q, u, p = np.zeros(nq), np.zeros(n), np.ones(npar + m)
        db, out = np.zeros(max(m, 1)), np.empty(self.total[name])
        t0 = time.perf_counter()
        if kname == name:
            f(q, u, 0.0, p, db, out) if name == "forward" else f(q, u, 0.0, p, out)
        else:
            f(q[None], u[None], np.zeros(1), p[None], db[None], out[None], np.empty(1, np.int64))
        # one signature only: other argument types raise TypeError and are converted by the
        # caller, instead of compiling a new specialization for seconds mid-run
        f.disable_compile()
        st = f.stats
        TIMINGS.setdefault(self.stem, {})[kname] = {
            "seconds": time.perf_counter() - t0,
            "from_cache": sum(st.cache_hits.values()) > 0 and not sum(st.cache_misses.values()),
        }
        return f


_LOADED: dict[tuple, Kernels] = {}


def load_kernels(
    src: str, stem: str, directory: Path, nq: int, n: int, npar: int, m: int, pmin: float
) -> Kernels | None:
    """The kernels of `src`, once per process (see _load); None on the 'auto' setting while
    numba's cache does not hold them yet (the caller takes the Python path; the compile is
    queued for a background process that starts when this one exits)."""
    key = (stem, str(directory), hashlib.sha256(src.encode()).hexdigest(), pmin)
    hit = _LOADED.get(key)
    if hit is None:
        text, sizes = numba_source(src, nq, n, npar, m, pmin)
        path = directory / f"{stem}_numba.py"
        written = _write_if_changed(path, text)
        if setting() == "auto" and not _ready(path, text):
            _queue_warm(path)
            return None
        hit = _LOADED[key] = _load(text, sizes, path, written, stem, (nq, n, npar, m))
    return hit


# ---- background compilation (the 'auto' setting) ------------------------------------------
# Compiling every kernel of every model costs minutes of CPU (numba's type inference of the
# straight-line code, docs/compiled.md); a fresh cache must not make `crosscheck run` slower.
# So a cold module runs on the Python path (bit-identical, tests/test_compiled.py) and one
# detached process compiles the queued modules into numba's cache after this process exits;
# it writes <module>.ready (the module text's digest) when every kernel is cached.
_PENDING: list[Path] = []
WARM_LOCK_S = 900.0  # a lock older than this is stale (a worker killed mid-compile)


def _digest(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


def _ready(path: Path, text: str) -> bool:
    marker = path.with_suffix(".ready")
    return marker.exists() and marker.read_text() == _digest(text)


def _queue_warm(path: Path) -> None:
    if os.environ.get("CROSSCHECK_BACKGROUND_COMPILE", "1") == "0":
        return
    if not _PENDING:
        import atexit

        atexit.register(_spawn_warm)
    if path not in _PENDING:
        _PENDING.append(path)


def _spawn_warm() -> None:
    """Start one detached worker for the queued modules nobody else is compiling."""
    import subprocess

    todo = []
    for path in _PENDING:
        lock = path.with_suffix(".warming")
        try:
            if lock.exists() and time.time() - lock.stat().st_mtime > WARM_LOCK_S:
                lock.unlink()
            os.close(os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            todo.append(str(path))
        except OSError:  # another process is compiling it
            continue
    if not todo:
        return
    env = dict(os.environ)
    root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = root + os.pathsep + env.get("PYTHONPATH", "")
    subprocess.Popen(
        [sys.executable, "-m", "reference.backends.numba_backend", *todo],
        env=env,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )


def warm(path: Path) -> dict:
    """Compile every kernel of a written module into numba's cache; mark it ready."""
    import numpy as np

    text = path.read_text()
    mod = _import(path, text)
    times = {}
    try:
        nq, n, npar, m = mod.NQ, mod.NU, mod.NP, mod.M
        q, u, p, db = np.zeros(nq), np.zeros(n), np.ones(npar + m), np.zeros(max(m, 1))
        for name, total in mod.OUT_SIZES.items():
            t0 = time.perf_counter()
            out = np.empty(total)
            f = getattr(mod, name)
            f(q, u, 0.0, p, db, out) if name == "forward" else f(q, u, 0.0, p, out)
            times[name] = time.perf_counter() - t0
        if "forward" in mod.OUT_SIZES:  # no forward where the solve is numeric (codegen)
            t0 = time.perf_counter()
            mod.forward_batch(
                q[None],
                u[None],
                np.zeros(1),
                p[None],
                db[None],
                np.empty((1, mod.OUT_SIZES["forward"])),
                np.empty(1, np.int64),
            )
            times["forward_batch"] = time.perf_counter() - t0
        path.with_suffix(".times.json").write_text(json.dumps(times))
        path.with_suffix(".ready").write_text(_digest(text))
    finally:
        path.with_suffix(".warming").unlink(missing_ok=True)
    return times


def worker_times(stem: str, directory: Path) -> dict | None:
    """Seconds the background worker spent compiling each kernel of a module (None: no
    worker has compiled it)."""
    f = directory / f"{stem}_numba.times.json"
    return json.loads(f.read_text()) if f.exists() else None


def import_file(path: Path, modname: str):
    """The module in file `path` (Python source or a built extension) under `modname`, once
    per process."""
    mod = sys.modules.get(modname)
    if mod is None:
        spec = importlib.util.spec_from_file_location(modname, path)
        if spec is None or spec.loader is None:
            raise ImportError(f"cannot load the kernel module {path}")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[modname] = mod
        try:
            spec.loader.exec_module(mod)
        except BaseException:
            del sys.modules[modname]
            raise
    return mod


def _import(path: Path, text: str):
    stem = path.stem.replace("-", "_")
    return import_file(path, f"_crosscheck_numba_{stem}_{_digest(text)[:12]}")


def _load(text, sizes, path, written, stem, dims) -> Kernels:
    """Import the numba module. Its kernels compile (or load from numba's cache) on first
    use, Kernels.get: a process pays only for what it calls."""
    t0 = time.perf_counter()
    mod = _import(path, text)
    TIMINGS.setdefault(stem, {}).update({"written": written, "import_s": time.perf_counter() - t0})
    return Kernels(mod, sizes, stem, *dims)


if (
    __name__ == "__main__"
):  # the background worker: python -m reference.backends.numba_backend MODULE...
    for arg in sys.argv[1:]:
        warm(Path(arg))
