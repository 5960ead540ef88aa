"""Batched forward dynamics of NumericModel (a mixin): N states in one call.

The backend's batch kernel runs every state (reference.backends.kernels: C's serial or OpenMP
loop, or the generated code on numpy arrays); a model whose KKT solve is numeric runs its
solve state by state.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from reference.backends import select
from reference.backends.kernels import NOT_FINITE, OK, PIVOT_RATIO_MIN, SINGULAR, Kernels
from reference.errors import ModelInputError, SingularSystemError
from reference.system import Model


class BatchedForward:
    """NumericModel's batched forward (split out of reference/numeric/model.py for its size)."""

    model: Model
    n: int
    nq: int
    m: int
    p: tuple
    sref: tuple
    _k: Kernels
    _kf: Callable[..., int]
    _numeric: bool
    _pa: np.ndarray
    _db0: np.ndarray
    _nf: int
    _fail: Callable[..., Any]  # NumericModel's methods used here
    singular_message: Callable[..., str]

    def forward_batch(
        self, Q: ArrayLike, U: ArrayLike, t: Any = 0.0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """u' and lambda at N states in one call, checked as NumericModel.forward.

        Parameters
        ----------
        Q : array_like
            The coordinates, N x nq.
        U : array_like
            The speeds, N x n.
        t : float or array_like, optional
            One time for every state, or one per state; default 0.

        Returns
        -------
        tuple of numpy.ndarray
            UD (N x n), LAM (N x m) and the pivot ratios (N).

        Raises
        ------
        ModelInputError
            Arrays of the wrong shape, or NaN or infinity in any state.
        SingularSystemError
            The KKT matrix is singular at some states (the message counts them and names the
            first), or the expressions are not defined at one.
        """
        Q = np.asarray(Q, dtype=float)
        U = np.asarray(U, dtype=float)
        if Q.ndim != 2 or Q.shape[1] != self.nq or U.shape != (Q.shape[0], self.n):
            raise ModelInputError(
                f"{self.model.name}: batched states must be (N, {self.nq}) and (N, {self.n}), "
                f"got {Q.shape} and {U.shape}"
            )
        N = Q.shape[0]
        Q, U = np.ascontiguousarray(Q), np.ascontiguousarray(U)
        T = np.ascontiguousarray(np.atleast_1d(np.asarray(t, float)))
        out = np.empty((N, self._nf))
        st = np.empty(N, np.int64)
        if self._numeric:  # one rank-revealing numeric solve per state
            self._forward_each(Q, U, T, out, st)
        else:
            k = self._k
            k.set_threads(select.threads())
            k.batch("forward")(Q, U, T, self._batch_parameters(N), self._db0[None], out, st)
        bad = (st != OK) & (st != SINGULAR)
        if bad.any():
            if (st == NOT_FINITE).any() or not np.isfinite(T).all():
                raise ModelInputError(f"{self.model.name}: batched states contain NaN or infinity")
            i = int(np.argmax(bad))
            self._fail(int(st[i]), Q[i], U[i])
        n, nl = self.n, self.n + self.m
        UD, LAM, piv = out[:, :n], out[:, n:nl], out[:, nl]
        singular = ~(piv > PIVOT_RATIO_MIN)
        if singular.any():
            i = int(np.argmax(singular))
            raise SingularSystemError(
                f"{singular.sum()} of {N} states are singular; first: index {i}. "
                + self.singular_message(Q[i], float(piv[i]))
            )
        return UD, LAM, piv

    def _batch_parameters(self, N: int) -> np.ndarray:
        """The kernels' P: this model's `pa` as one row, or one row per state where the
        parameters or Schur references are arrays of N (crosscheck.sweep.worker's
        reference_batch gives each sample its own)."""
        cols = list(self.p) + list(self.sref)
        if not any(np.ndim(c) for c in cols):
            return self._pa[None]
        P = np.empty((N, len(cols)))
        for j, c in enumerate(cols):
            P[:, j] = c
        return P

    def _forward_each(
        self, Q: np.ndarray, U: np.ndarray, T: np.ndarray, out: np.ndarray, st: np.ndarray
    ) -> None:
        """The forward kernel state by state (the numeric solve), statuses as a batch's."""
        P = self._batch_parameters(len(Q))
        for i in range(len(Q)):
            st[i] = self._kf(
                Q[i],
                U[i],
                float(T[i if len(T) > 1 else 0]),
                P[i if len(P) > 1 else 0],
                self._db0,
                out[i],
            )
