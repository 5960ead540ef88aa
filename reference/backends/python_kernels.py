"""The generated Python code behind the kernel interface (reference.backends.kernels): the
backend that needs no build, the fallback where no C compiler works or the C printer refuses a
model, and the reference the C kernels are held equal to (the same expressions, to the bit).

The single-state kernels run the generated functions on Python floats (their fastest input:
lists in, lists out) and copy the result into `out`; the batch kernels run the same source on
numpy arrays of states (codegen's batched namespace). What the C kernels test, these test too,
with the same status codes: sizes and finiteness of the state, the pivot ratio, and a division
by zero in the derived expressions (ZeroDivisionError here, inf or NaN in C: NOT_DEFINED).
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from itertools import chain
from math import isfinite, nan
from typing import Any

import numpy as np

from reference.backends.kernels import (
    BAD_Q_SIZE,
    BAD_U_SIZE,
    NOT_DEFINED,
    NOT_FINITE,
    OK,
    PIVOT_RATIO_MIN,
    SINGULAR,
    Kernels,
    layout,
)

_ND = np.ndarray
_F64 = np.dtype(np.float64)


def as_floats(x: Any) -> list[float]:
    """Values as a list of Python floats (the generated code is fastest on plain floats)."""
    if type(x) is _ND:
        if x.ndim == 1 and x.dtype == np.float64:  # the common case, kept cheap
            return x.tolist()  # type: ignore[no-any-return]
        return x.astype(float, copy=False).reshape(-1).tolist()  # type: ignore[no-any-return]
    return [float(v) for v in x]


def state_status(q: list, u: list, t: float, nq: int, n: int) -> int:
    """The kernels' state test: sizes, then finiteness (one sum is finite exactly when every
    term is, unless finite terms overflow: only then are the terms looked at one by one)."""
    if len(q) != nq:
        return BAD_Q_SIZE
    if len(u) != n:
        return BAD_U_SIZE
    if not isfinite(sum(q) + sum(u) + t) and not (
        all(map(isfinite, q)) and all(map(isfinite, u)) and isfinite(t)
    ):
        return NOT_FINITE
    return OK


def _inputs(q: Any, u: Any, t: Any) -> tuple[list, list, float]:
    """(q, u, t) as Python floats; TypeError for what is not numbers (the caller converts or
    words the error, as for the C kernels)."""
    try:
        return as_floats(q), as_floats(u), float(t)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"the state must be numbers ({exc})") from None


def _finite(values: list) -> bool:
    return isfinite(sum(values)) or all(map(isfinite, values))


def _writer(size: int) -> Callable[[Any, list], None]:
    """write(out, values): `size` values into `out`, a float64 vector of at least that many
    (one struct call: a numpy slice assignment from a list costs twice as much); anything
    else is a TypeError, as the C kernels refuse it."""
    pack = struct.Struct(f"{size}d").pack_into

    def write(out: Any, values: list) -> None:
        # (`is`: the cheap common case; `!=`: a float64 dtype object of its own)
        if type(out) is not _ND or out.ndim != 1 or (out.dtype is not _F64 and out.dtype != _F64):
            raise TypeError(f"out must be a float64 vector of {size}, got {type(out).__name__}")
        try:  # the buffer protocol refuses a read-only or strided array; struct a short one
            pack(out, 0, *values)  # type: ignore[arg-type]  # an ndarray is a buffer
        except (BufferError, ValueError, struct.error) as exc:
            raise TypeError(f"out must be a writable contiguous float64 vector ({exc})") from None

    return write


class PythonKernels(Kernels):
    """The generated module's functions (codegen.load_compiled's scalar and batched
    namespaces) as kernels."""

    name = "python"
    takes_sequences = True

    def __init__(self, scalar: dict, batched: dict, src: str, dims: tuple[int, int, int, int]):
        super().__init__(layout(src), dims)
        self._scalar, self._batched = scalar, batched
        self._made: dict[str, Callable[..., int]] = {}
        self._split: tuple = (None, (), ())  # the last `pa` and its parameters, references

    @property
    def summed(self) -> bool:
        """True for a module on the sums path (reference.backends.summed_source)."""
        return bool(self._scalar["META"].get("sums"))

    def generated(self, fname: str) -> Callable[..., tuple]:
        """The generated function itself, in the batched namespace (numpy: complex arrays go
        through, as reference.derivatives.complex_step needs)."""
        self._known(fname)
        return self._batched[fname]  # type: ignore[no-any-return]

    def function(self, fname: str) -> Callable[..., int]:
        f = self._made.get(fname)
        if f is None:
            self._known(fname)
            f = self._made[fname] = self._forward() if fname == "forward" else self._single(fname)
        return f

    def set_threads(self, k: int) -> None:
        """The batch kernels are numpy's vectorized code: no threads of their own."""

    def _params(self, pa: Any) -> tuple[tuple, tuple]:
        """`pa` as the generated code takes it: (parameters, Schur references) as tuples of
        floats, kept for the `pa` last seen (one model calls with one array)."""
        hit = self._split
        if hit[0] is pa:
            return hit[1], hit[2]
        vals = as_floats(pa)
        npar = self.dims[2]
        p, sref = tuple(vals[:npar]), tuple(vals[npar:])
        self._split = (pa, p, sref)
        return p, sref

    def _forward(self) -> Callable[..., int]:
        f, matrices, params = self._scalar["forward"], self._scalar["matrices"], self._params
        nq, n, _npar, m = self.dims
        write, singular = _writer(n + m + 1), [nan] * (n + m) + [-1.0]
        zero_db, no_db = self.zero_db, self.zero_db.tolist()

        def kernel(q: Any, u: Any, t: Any, pa: Any, db: Any, out: Any) -> int:
            ql, ul, t = _inputs(q, u, t)
            st = state_status(ql, ul, t, nq, n)
            if st:
                return st
            p, sref = params(pa)
            try:
                ud, lam, piv = f(ql, ul, t, p, sref, no_db if db is zero_db else as_floats(db))
            except (ValueError, ZeroDivisionError):
                # sqrt of a negative pivot or a zero pivot: singular, unless M, f, A, b are
                # not defined at this state themselves
                try:
                    matrices(ql, ul, t, p)
                except (ValueError, ZeroDivisionError, OverflowError):
                    return NOT_DEFINED
                write(out, singular)
                return SINGULAR
            values = ud + lam
            write(out, [*values, piv])
            if not piv > PIVOT_RATIO_MIN:
                return SINGULAR
            return OK if _finite(values) else NOT_DEFINED

        return kernel

    def _single(self, fname: str) -> Callable[..., int]:
        f, write, (nq, n, _npar, _m) = self._scalar[fname], _writer(self.total[fname]), self.dims
        params = self._params

        def kernel(q: Any, u: Any, t: Any, pa: Any, out: Any) -> int:
            ql, ul, t = _inputs(q, u, t)
            st = state_status(ql, ul, t, nq, n)
            if st:
                return st
            try:
                values = list(chain.from_iterable(f(ql, ul, t, params(pa)[0])))
            except (ValueError, ZeroDivisionError, OverflowError):
                return NOT_DEFINED
            write(out, values)
            return OK if _finite(values) else NOT_DEFINED

        return kernel

    def batch(self, fname: str) -> Callable[..., Any]:
        self._known(fname)
        g, forward, npar = self._batched[fname], fname == "forward", self.dims[2]

        def run(Q: _ND, U: _ND, T: _ND, P: _ND, DB: _ND, OUT: _ND, ST: _ND) -> None:
            t = T[0] if T.shape[0] == 1 else T
            cols = P[0].tolist() if P.shape[0] == 1 else list(P.T)
            p = tuple(cols[:npar])
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                if forward:
                    db = DB[0].tolist() if DB.shape[0] == 1 else list(DB.T)
                    *groups, piv = g(Q.T, U.T, t, p, tuple(cols[npar:]), db)
                else:
                    groups = g(Q.T, U.T, t, p)
            k = 0
            for grp in groups:
                for e in grp:
                    OUT[:, k] = e
                    k += 1
            good = np.isfinite(OUT[:, :k]).all(axis=1)
            status = np.where(good, OK, NOT_DEFINED)
            if forward:
                OUT[:, k] = piv
                status = np.where(OUT[:, k] > PIVOT_RATIO_MIN, status, SINGULAR)
            given = np.isfinite(Q).all(axis=1) & np.isfinite(U).all(axis=1) & np.isfinite(T)
            ST[:] = np.where(given, status, NOT_FINITE)

        return run
