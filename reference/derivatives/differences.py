"""The slow, obvious path beside the exact derivatives: central differences of the reference's
own forward call, one coordinate, speed or generalized force at a time.

Each derivative is the fourth-order central difference

    g'(x) ~ (8 (g(x + h) - g(x - h)) - (g(x + 2h) - g(x - 2h))) / (12 h),

whose truncation error is h^4 g^(5) / 30 and whose round-off is about 1.5 eps |g| / h; at the
default h = 1e-3 (coordinates of size 1: radians, metres) both are near 1e-12 |g|. The same
stencil at 2h gives an estimate of the truncation error, (D(2h) - D(h)) / 15, returned with
the derivatives. Applied forces enter the forward call only through f, so du'/dtau and
dlambda/dtau are differenced on a dense KKT solve of NumericModel.matrices (numpy's LU, the
most obvious solve there is) with tau added to f.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from reference.derivatives.exact import Derivatives
from reference.numeric.model import NumericModel

STEP = 1e-3
WEIGHTS = ((1, 8.0), (-1, -8.0), (2, -1.0), (-2, 1.0))  # offsets in h and their weights / 12h


def stencil(g: Callable[[float], np.ndarray], h: float) -> np.ndarray:
    """The fourth-order central difference of g at 0 with step h."""
    return np.asarray(sum(w * g(k * h) for k, w in WEIGHTS), float) / (12.0 * h)


def kkt_solve(M, f, A, b) -> tuple[np.ndarray, np.ndarray]:
    """u', lambda of M u' - f = A^T lambda, A u' = b by a dense LU (the minimum-norm lambda by
    least squares where A's rows are dependent)."""
    n, m = M.shape[0], A.shape[0]
    K = np.block([[M, -A.T], [A, np.zeros((m, m))]])
    z = np.linalg.lstsq(K, np.concatenate([f, b]), rcond=None)[0]
    return z[:n], z[n:]


def central_differences(
    nm: NumericModel,
    q: ArrayLike,
    u: ArrayLike,
    t: float = 0.0,
    h: float = STEP,
    blocks: tuple[str, ...] = ("dq", "du", "dtau"),
) -> tuple[Derivatives, Derivatives]:
    """The derivatives of nm's forward answer by central differences, and the estimate of
    their truncation error (the same fields: |D(2h) - D(h)| / 15).

    Parameters
    ----------
    nm : NumericModel
    q, u : array_like
        The state (it need not be consistent).
    t : float, optional
        Time.
    h : float, optional
        The step, default STEP.
    blocks : tuple of str, optional
        The blocks differenced ('dq', 'du', 'dtau'); the others are left NaN (a model whose
        dependent rows become independent off the manifold has no answer there: its q- and
        u-blocks are differenced along the manifold instead, crosscheck's reference records).

    Returns
    -------
    tuple of Derivatives
        The differences at h and the truncation estimate (the answer's own fields hold the
        forward answer in both).
    """
    q, u = np.asarray(q, float), np.asarray(u, float)
    n, nq = nm.n, nm.nq
    fw = nm.forward(q, u, t)

    def answer(qq, uu, tau=None):
        if tau is None:
            a = nm.forward(qq, uu, t)
            return np.concatenate([a.accelerations, a.multipliers])
        M, f, A, b = nm.matrices(qq, uu, t)
        return np.concatenate(kkt_solve(M, f + tau, A, b))

    size = n + nm.m

    def columns(step: float) -> np.ndarray:
        def each(block, eye, g):
            if block not in blocks:
                return [np.full(size, np.nan) for _ in eye]
            return [stencil(lambda s, e=e: g(s * e), step) for e in eye]

        cols = each("dq", np.eye(nq), lambda dx: answer(q + dx, u))
        cols += each("du", np.eye(n), lambda dx: answer(q, u + dx))
        cols += each("dtau", np.eye(n), lambda dx: answer(q, u, dx))
        return np.array(cols).T.reshape(size, nq + 2 * n)

    D, D2 = columns(h), columns(2 * h)
    return _as_derivatives(fw, D, n, nq), _as_derivatives(fw, np.abs(D2 - D) / 15.0, n, nq)


def _as_derivatives(fw, D: np.ndarray, n: int, nq: int) -> Derivatives:
    """Derivatives from the stacked columns (rows u' then lambda; columns q, u, tau)."""
    return Derivatives(fw.accelerations, fw.multipliers, D, nq, fw.pivot_ratio, fw.rank)
