"""Batched forward dynamics of NumericModel (a mixin): N states in one call.

The compiled path runs the serial (or threaded) batch kernel of reference.backends.c_build or
reference.backends.numba_backend; the Python path the generated vectorized code; models with
dependent rows one numeric solve per state.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from reference.backends import numba_backend as compiled
from reference.errors import ModelInputError, SingularSystemError


class BatchedForward:
    """NumericModel's batched forward (split out of reference/numeric/model.py for its size)."""

    model: Any
    n: int
    nq: int
    m: int
    p: tuple
    sref: tuple
    _k: Any
    _numeric: bool
    _batched: dict
    _no_db: tuple
    _pa: np.ndarray
    _db0: np.ndarray
    _nf: int
    _fail: Callable[..., None]  # NumericModel's methods used here
    _singular_message: Callable[..., str]
    _forward_redundant: Callable[..., Any]

    def forward_batch(
        self, Q: ArrayLike, U: ArrayLike, t: Any = 0.0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """u' and lambda for N states at once: Q (N x nq), U (N x n). Returns (UD, LAM, piv)."""
        Q = np.asarray(Q, dtype=float)
        U = np.asarray(U, dtype=float)
        if Q.ndim != 2 or Q.shape[1] != self.nq or U.shape != (Q.shape[0], self.n):
            raise ModelInputError(
                f"{self.model.name}: batched states must be (N, {self.nq}) and (N, {self.n}), "
                f"got {Q.shape} and {U.shape}"
            )
        N = Q.shape[0]
        compiled_path = self._k is not None and not self._numeric
        # the C batch tests each state's finiteness itself (status NOT_FINITE); numba's
        # inlined batch loop and the Python path do not
        kernel_checks = compiled_path and hasattr(self._k, "bind")
        if not kernel_checks and not (np.isfinite(Q).all() and np.isfinite(U).all()):
            raise self._not_finite_batch()
        if (
            self._numeric
        ):  # one rank-revealing numeric solve per state (reference.numeric.redundant)
            UD, LAM, piv = self._forward_batch_redundant(Q, U, t)
        elif compiled_path:
            UD, LAM, piv = self._forward_batch_compiled(Q, U, t)
        else:
            UD, LAM, piv = self._forward_batch_python(Q, U, t)
        from reference.numeric.model import (
            PIVOT_RATIO_MIN,  # defined beside the single-state pivot test
        )

        bad = ~(piv > PIVOT_RATIO_MIN)
        if bad.any():
            i = int(np.argmax(bad))
            raise SingularSystemError(
                f"{bad.sum()} of {N} states are singular; first: index {i}. "
                + self._singular_message(Q[i], float(piv[i]))
            )
        return UD, LAM, piv

    def _not_finite_batch(self) -> ModelInputError:
        return ModelInputError(f"{self.model.name}: batched states contain NaN or infinity")

    def _forward_batch_redundant(self, Q: np.ndarray, U: np.ndarray, t: Any) -> tuple:
        rows = [self._forward_redundant(Q[i].tolist(), U[i].tolist(), t) for i in range(len(Q))]
        UD = np.array([r[0] for r in rows], float).reshape(len(Q), self.n)
        LAM = np.array([r[1] for r in rows], float).reshape(len(Q), self.m)
        return UD, LAM, np.array([r[2] for r in rows], float)

    def _forward_batch_python(self, Q: np.ndarray, U: np.ndarray, t: Any) -> tuple:
        N = Q.shape[0]
        with np.errstate(invalid="ignore", divide="ignore"):
            ud, lam, piv = self._batched["forward"](Q.T, U.T, t, self.p, self.sref, self._no_db)
        UD = np.empty((N, self.n))
        for i, c in enumerate(ud):
            UD[:, i] = c
        LAM = np.empty((N, self.m))
        for i, c in enumerate(lam):
            LAM[:, i] = c
        return UD, LAM, np.broadcast_to(np.asarray(piv, float), (N,))

    def _forward_batch_compiled(self, Q: np.ndarray, U: np.ndarray, t: Any) -> tuple:
        """The serial (or, with CROSSCHECK_THREADS > 1, prange) batch kernel. The parameters,
        Schur references and t may be per-state arrays
        (crosscheck.commands.sweep.reference_batch)."""
        N = Q.shape[0]
        T = np.ascontiguousarray(np.atleast_1d(np.asarray(t, float)))
        cols = list(self.p) + list(self.sref)
        if any(np.ndim(c) for c in cols):
            P = np.empty((N, len(cols)))
            for j, c in enumerate(cols):
                P[:, j] = c
        else:
            P = self._pa[None]
        out = np.empty((N, self._nf))
        st = np.empty(N, np.int64)
        name = "forward_batch" if compiled.threads() == 1 else "forward_batch_parallel"
        if hasattr(self._k, "set_threads"):  # the C loop: OpenMP threads, set per call
            self._k.set_threads(compiled.threads())
        elif name != "forward_batch":
            import numba

            numba.set_num_threads(min(compiled.threads(), numba.config.NUMBA_NUM_THREADS))  # type: ignore[attr-defined]  # set at import, not in numba's stubs
        self._k.get(name)(
            np.ascontiguousarray(Q), np.ascontiguousarray(U), T, P, self._db0[None], out, st
        )
        bad = (st != compiled.OK) & (st != compiled.SINGULAR)
        if bad.any():
            if (st == compiled.NOT_FINITE).any() or not np.isfinite(T).all():
                raise self._not_finite_batch()
            i = int(np.argmax(bad))
            self._fail(int(st[i]), Q[i], U[i])
        n, nm = self.n, self.n + self.m
        return out[:, :n], out[:, n:nm], out[:, nm]
