"""Build and load the C kernels of reference.backends.c_source: one CPython extension per
derivation cache entry, compiled by the system's C compiler into the cache directory.

The built file is named by a digest of everything that decides its machine code (the C text,
the runtime header, the compiler and its flags, Python's and numpy's versions), so a change to
any of them builds a new file and two checkouts never overwrite each other's. It is written
to a temporary name and renamed into place, so processes that build the same module at once
each get a complete file.

The compiler is CROSSCHECK_CC, else CC, else `cc`. Where none works the models run on the
Python path (reference.backends.select); bench.json's `compiled` says which backend ran and why.
"""

from __future__ import annotations

import hashlib
import os
import shlex
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from functools import cache
from pathlib import Path

from reference.backends import cache as derivation_cache
from reference.backends.c_source import (
    HEADERS,
    MODULE_NAME,
    RUNTIME,
    c_source,
)
from reference.backends.kernels import TIMINGS, Kernels, import_file

# -O2: gcc builds the largest built-in model in about a second (benchmarks/reference_speed.md).
# -fno-math-errno: sqrt compiles to the instruction (the result is the same; only errno,
#   which nothing reads, is not set). -ffp-contract=off: no fused multiply-add, so every
#   operation rounds as the Python path's does. No -ffast-math: it would drop NaN tests.
CFLAGS = (
    "-O2",
    "-fPIC",
    "-shared",
    "-fno-math-errno",
    "-ffp-contract=off",
    "-fopenmp",
    "-Wno-unknown-pragmas",
)


class BuildError(RuntimeError):
    """The C compiler is missing or rejected a module."""


def compiler() -> list[str]:
    """The compiler command (CROSSCHECK_CC, CC or cc), split like a shell would."""
    cmd = os.environ.get("CROSSCHECK_CC") or os.environ.get("CC") or "cc"
    return shlex.split(cmd)


@cache
def _compiler_identity(cmd: tuple[str, ...]) -> str:
    """The compiler's own version line (part of the built file's digest), or '' if absent."""
    if not cmd or shutil.which(cmd[0]) is None:
        return ""
    try:
        r = subprocess.run([*cmd, "--version"], capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return ""
    return r.stdout.splitlines()[0] if r.returncode == 0 and r.stdout else ""


# an OpenMP loop that must compile and link into a shared object (the batch loop's pragma)
_OPENMP_PROBE = """int probe(int n)
{
    int s = 0;
#pragma omp parallel for reduction(+ : s)
    for (int i = 0; i < n; ++i) s += i;
    return s;
}
"""


def openmp() -> bool:
    """Whether the compiler builds -fopenmp into a shared object (gcc does; Apple's clang does
    not). Without it the batch loops are serial (the pragma is ignored) instead of every
    module failing to build. Tried once per compiler, the answer kept in the cache directory."""
    from reference.backends.codegen import cache_dir

    return _openmp(tuple(compiler()), cache_dir())


@cache
def _openmp(cmd: tuple[str, ...], directory: Path) -> bool:
    ident = _compiler_identity(cmd)
    if not ident:
        return False
    tag = hashlib.sha256(f"{' '.join(cmd)}\0{ident}".encode()).hexdigest()[:16]
    known = directory / f"openmp-{tag}.txt"
    try:
        return known.read_text().strip() == "1"
    except OSError:
        pass
    with tempfile.TemporaryDirectory() as d:
        src, out = Path(d) / "probe.c", Path(d) / "probe.so"
        src.write_text(_OPENMP_PROBE)
        try:
            r = subprocess.run(
                [*cmd, "-fopenmp", "-fPIC", "-shared", str(src), "-o", str(out)],
                capture_output=True,
                timeout=60,
            )
            ok = r.returncode == 0
        except (OSError, subprocess.SubprocessError):
            ok = False
    try:
        directory.mkdir(parents=True, exist_ok=True)
        tmp = known.with_name(f"{known.name}.{os.getpid()}.tmp")
        tmp.write_text("1" if ok else "0")
        os.replace(tmp, known)
    except OSError:
        pass  # a read-only cache: the probe runs again next time
    return ok


def compile_flags() -> list[str]:
    """CFLAGS, without -fopenmp where the compiler has no OpenMP (openmp())."""
    return [f for f in CFLAGS if f != "-fopenmp" or openmp()]


def available() -> bool:
    """True when a C compiler answers and Python's and numpy's headers are installed."""
    include = Path(sysconfig.get_paths()["include"]) / "Python.h"
    return bool(_compiler_identity(tuple(compiler()))) and include.exists()


# our headers' directory as the digest writes it: the headers enter the digest by content
# (HEADERS), so the path of the checkout they sit in stays out of it
OWN_HEADERS = "<reference>"


def _include_dirs(own: str | None = None) -> list[str]:
    import numpy as np

    return [sysconfig.get_paths()["include"], np.get_include(), own or str(RUNTIME.parent)]


def _digest(text: str, cmd: list[str]) -> str:
    import numpy as np

    h = hashlib.sha256()
    for part in (
        text,
        *(header.read_text() for header in HEADERS),
        " ".join(cmd),
        _compiler_identity(tuple(compiler())),
        sys.version,
        np.__version__,
        sysconfig.get_config_var("EXT_SUFFIX") or "",
    ):
        h.update(part.encode())
        h.update(b"\0")
    return h.hexdigest()[:16]


def _target(text: str, stem: str, directory: Path) -> tuple[Path, str, list[str]]:
    """Where module `text` is built, its module name and the compiler's flags."""
    flags = [*compile_flags(), *(f"-I{d}" for d in _include_dirs())]
    # keyed without the checkout's path: a cache shared by two checkouts (git worktrees, a CI
    # cache restored under another path) would otherwise build every module again in each
    digest = _digest(text, [*compile_flags(), *(f"-I{d}" for d in _include_dirs(OWN_HEADERS))])
    suffix = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
    return directory / f"{stem}_c_{digest}{suffix}", f"_crosscheck_c_{digest}", flags


def _compile(text: str, stem: str, target: Path, modname: str, flags: list[str]) -> float:
    """Run the compiler into `target`; the seconds it took."""
    # this process's own source and object names: another process building the same module
    # at once must not truncate the file this compiler is reading
    kept = target.with_name(target.name.split(".", 1)[0] + ".c")  # <stem>_c_<digest>.c
    src = kept.with_suffix(f".{os.getpid()}.c")
    tmp = target.with_name(f"{target.name}.{os.getpid()}.tmp")
    try:
        src.write_text(text.replace(MODULE_NAME, modname))
    except OSError as exc:  # a full disk: the module runs on Python, and stderr says why
        src.unlink(missing_ok=True)
        raise BuildError(f"{stem}: cannot write its C source ({exc.strerror or exc})") from None
    t0 = time.perf_counter()
    try:
        r = subprocess.run(
            [*compiler(), *flags, str(src), "-o", str(tmp), "-lm"],
            capture_output=True,
            text=True,
            timeout=600,
        )
    except (OSError, subprocess.SubprocessError) as exc:
        src.unlink(missing_ok=True)
        raise BuildError(f"{stem}: the C compiler could not run ({exc})") from None
    os.replace(src, kept)  # kept beside the module to read
    if r.returncode != 0:
        tmp.unlink(missing_ok=True)
        lines = r.stderr.strip().splitlines() or ["no message"]
        first = next((ln for ln in lines if "error" in ln), lines[0])
        raise BuildError(f"{stem}: the C compiler rejected the module ({first}; source {kept})")
    os.replace(tmp, target)
    derivation_cache.record_built(target)  # what load_kernels verifies before it loads the file
    return time.perf_counter() - t0


# Builds started ahead of their first use (prebuild), by target: one worker thread, so the
# compiler runs on the second core while this process derives or checks something else.
_IN_FLIGHT: dict[Path, Future] = {}
_POOL: list[ThreadPoolExecutor] = []
_LOCK = threading.Lock()


def prebuild(text: str, stem: str, directory: Path) -> None:
    """Start building module `text` in the background unless it is built or building."""
    target, modname, flags = _target(text, stem, directory)
    with _LOCK:
        if target in _IN_FLIGHT or derivation_cache.built_intact(target):
            return
        if not _POOL:
            _POOL.append(ThreadPoolExecutor(max_workers=1, thread_name_prefix="cbuild"))
        _IN_FLIGHT[target] = _POOL[0].submit(_compile, text, stem, target, modname, flags)


def build(text: str, stem: str, directory: Path) -> tuple[Path, str, float]:
    """The extension of C module `text` in `directory`, built unless present (or waited for,
    if a prebuild is compiling it): (path, module name, build seconds; 0 when it was there)."""
    target, modname, flags = _target(text, stem, directory)
    with _LOCK:
        pending = _IN_FLIGHT.pop(target, None)
    if pending is not None:
        return target, modname, pending.result()  # its BuildError, if any, raised here
    if derivation_cache.built_intact(target):  # a damaged file (a truncated .so) is never loaded
        return target, modname, 0.0
    return target, modname, _compile(text, stem, target, modname, flags)


class CKernels(Kernels):
    """The C module's kernels (ckernel_runtime.h): the single-state and batch kernels, the
    bound forward calls and the whole-run stepper."""

    name = "c"

    def __init__(self, module, sizes: dict, dims: tuple[int, int, int, int]):
        super().__init__(sizes, dims)
        self.module = module

    def function(self, fname: str):
        self._known(fname)
        return getattr(self.module, fname)

    def batch(self, fname: str):
        """The batch loop: OpenMP threads as set_threads set them (serial by default)."""
        self._known(fname)
        return getattr(self.module, fname + "_batch")

    def set_threads(self, k: int) -> None:
        self.module.set_threads(k)

    def bind(self, pa, db, record, checked, fast):
        """The checked and fast forward calls in one C call each, the parameters and offsets
        copied in; a state they cannot take on their fast path goes to `checked` or `fast`
        with the same arguments (ckernel_runtime.h, Bound)."""
        bind = self.module.bind
        return bind("forward", pa, db, record, checked), bind("forward", pa, db, None, fast)

    @property
    def stepper(self):
        """The module's whole-run DOP853 stepper (ckernel_stepper.h)."""
        return self.module.step


_LOADED: dict[tuple, CKernels] = {}


def load_kernels(
    src: str, stem: str, directory: Path, dims: tuple[int, int, int, int], pmin: float
) -> CKernels:
    """The C kernels of generated module `src` (dims: coordinates, speeds, parameters,
    constraint rows), built if needed, once per process. Raises BuildError (compiler missing
    or failing) or c_source.UnsupportedExpression."""
    key = (stem, str(directory), hashlib.sha256(src.encode()).hexdigest(), pmin)
    hit = _LOADED.get(key)
    if hit is None:
        t0 = time.perf_counter()
        text, sizes = c_source(src, *dims, pmin)
        t1 = time.perf_counter()
        path, modname, build_s = build(text, stem, directory)
        t2 = time.perf_counter()
        try:
            mod = import_file(path, modname)
        except ImportError as exc:  # a damaged or foreign file under the digest's name
            raise BuildError(f"{stem}: cannot load {path} ({exc})") from None
        TIMINGS.setdefault(stem, {}).update(
            {
                "backend": "c",
                "c_source_s": t1 - t0,
                "c_build_s": build_s,
                "built": build_s > 0,
                "import_s": time.perf_counter() - t2,
            }
        )
        hit = _LOADED[key] = CKernels(mod, sizes, dims)
    return hit
