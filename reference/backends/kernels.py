"""The interface every backend's kernels implement, and what the backends share: the status
codes, the pivot bound, the output layout of the generated functions and the build timings.

A backend turns one generated module (reference.backends.codegen: forward, matrices,
kinematics, residuals, position_jacobian, energy) into kernels, one object per module:

    function(name)(q, u, t, pa, out) -> status      one state (forward: q, u, t, pa, db, out)
    batch(name)(Q, U, T, P, DB, OUT, ST)            N states; ST[i] is state i's status
    set_threads(k)                                  threads of the batch loops (1: serial)
    bind(pa, db, record, checked, fast)             forward calls bound to one parameter set
    stepper                                         the whole-run DOP853 function, or None
    name                                            'c' or 'python'

Arguments: q, u float64 vectors of the model's sizes (where `takes_sequences` is False, a list
or another dtype is a TypeError and the caller converts), t a number, pa the parameters then
the Schur references (`pack`), db the offsets of the constraint rows' right side (`zero_db`:
none), out a writable float64 vector of `total[name]` entries, the function's output groups
one after the other (`offsets`), forward's followed by its pivot ratio. In a batch, row i of
Q, U, OUT is state i's, and T, P, DB hold one row for every state or one row per state.

Every backend runs the same generated expressions in the same order, so they agree to the
last bit (tests/test_backends.py), and every kernel checks what it reads: sizes and
finiteness of the state, the pivot ratio, the finiteness of what it computed (STATUS).
"""

from __future__ import annotations

import ast
import importlib.util
import sys
from abc import ABC, abstractmethod
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

# status codes returned by every kernel (0: ok). NOT_DEFINED: a finite state whose outputs are
# not finite, a division by zero in the derived expressions (gimbal lock of Euler angles: the
# compiled code returns inf or NaN there, the Python code raises ZeroDivisionError)
OK, BAD_Q_SIZE, BAD_U_SIZE, NOT_FINITE, SINGULAR, NOT_DEFINED = 0, 1, 2, 3, 4, 5

# the generated functions, in the order of the generated module
FUNCTIONS = ("forward", "matrices", "kinematics", "residuals", "position_jacobian", "energy")

# A pivot of M or of the Schur complement S below this fraction of its original diagonal entry
# means the KKT matrix is singular to working precision: 1e-12 leaves 4 digits of a double's 16
# for the answer, the least a validation suite can call a number. The kernels test it.
PIVOT_RATIO_MIN = 1e-12

# build and load times of each generated module in this process, by cache entry (the C
# source's printing and build, a refusal's reason: bench.json's `compiled`)
TIMINGS: dict[str, dict] = {}


def output_groups(ret: ast.Return) -> tuple[list[list[ast.expr]], ast.expr | None]:
    """The returned list groups of a generated function, and forward's pivot expression."""
    elts = ret.value.elts if isinstance(ret.value, ast.Tuple) else [ret.value]
    groups = [e.elts for e in elts if isinstance(e, ast.List)]
    rest = [e for e in elts if not isinstance(e, ast.List)]
    return groups, (rest[0] if rest else None)


def layout(src: str) -> dict[str, list[int]]:
    """Each generated function's output group sizes, read from its one return statement (the
    last line of the function: codegen writes no other return)."""
    sizes: dict[str, list[int]] = {}
    name = None
    for line in src.splitlines():
        if line.startswith("def "):
            name = line[4 : line.index("(")]
        elif line.startswith("    return ") and name is not None:
            ret = ast.parse(line.strip()).body[0]
            assert isinstance(ret, ast.Return)
            sizes[name] = [len(g) for g in output_groups(ret)[0]]
    return sizes


def import_file(path: Path, modname: str) -> Any:
    """The module in file `path` (a built extension) under `modname`, once per process."""
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


class Kernels(ABC):
    """The kernels of one generated module on one backend (see the module docstring), and the
    layout of their outputs: `sizes[name]` the group sizes, `offsets[name]` each group's
    (start, end) in `out`, `total[name]` the length of `out`."""

    name: ClassVar[str]  # the backend: 'c' or 'python'
    # q and u may be lists or tuples of numbers (else float64 vectors only, a TypeError for
    # anything else: the caller converts)
    takes_sequences: ClassVar[bool] = False

    def __init__(self, sizes: dict[str, list[int]], dims: tuple[int, int, int, int]):
        self.sizes = sizes
        self.dims = dims  # coordinates, speeds, parameters, constraint rows
        self.offsets: dict[str, list[tuple[int, int]]] = {}
        for fname, groups in sizes.items():
            offs, k = [], 0
            for g in groups:
                offs.append((k, k + g))
                k += g
            self.offsets[fname] = offs
        self.total = {f: sum(g) + (f == "forward") for f, g in sizes.items()}
        self.zero_db = np.zeros(max(dims[3], 1))  # no offsets of the rows' right side

    def has(self, fname: str) -> bool:
        """Whether the module has function `fname` (no forward where the KKT solve is
        numeric: dependent rows, or a model past codegen.UNROLL_KKT_MAX)."""
        return fname in self.sizes

    def pack(self, p: tuple, sref: tuple) -> np.ndarray:
        """The kernels' `pa`: the parameters, then the Schur references."""
        return np.array(p + sref, float)

    @abstractmethod
    def function(self, fname: str) -> Callable[..., int]:
        """The single-state kernel of generated function `fname`."""

    @abstractmethod
    def batch(self, fname: str) -> Callable[..., Any]:
        """The batch kernel of generated function `fname` (on set_threads' threads)."""

    @abstractmethod
    def set_threads(self, k: int) -> None:
        """Threads of the batch kernels from now on (1: serial)."""

    def bind(
        self, pa: np.ndarray, db: np.ndarray, record: type, checked: Callable, fast: Callable
    ) -> tuple[Callable, Callable]:
        """The checked forward `checked(q, u, t) -> record` and the fast one `fast(q, u, t,
        db=None, out=None)`, bound to parameters `pa` and offsets `db`: here the callers' own
        Python functions; a backend may answer with calls of its own that take the common
        case in one step and hand any other to `checked` or `fast` unchanged."""
        return checked, fast

    @property
    def stepper(self) -> Callable[..., Any] | None:
        """The whole-run DOP853 stepper over the forward kernel (reference.integrate.compiled),
        or None where the backend has none."""
        return None

    def load(self) -> None:
        """Compile or load every single-state kernel now: not inside a timed or
        wall-bounded call later."""
        for fname in self.sizes:
            self.function(fname)

    def _known(self, fname: str) -> None:
        if fname not in self.sizes:
            raise KeyError(
                f"no generated function {fname!r} in this module; it has {', '.join(self.sizes)}"
            )
