"""R's partial derivatives for a model on the sums path, by complex steps of its own generated
module (reference.backends.summed_source) instead of differentiating M and f written out.

The module's `matrices` is straight-line arithmetic, sin and cos on the graph's subexpressions
and the bodies' sums in numpy (reference.backends.body_sums), so it runs unchanged on complex
numbers, and for a real-analytic F

    F(x + i h e_k) = F(x) + i h dF/dx_k - h^2/2 d2F/dx_k2 - ...,   dF/dx_k = Im F(x + i h e_k) / h

to round-off: no difference is taken, so nothing cancels, and the error is O(h^2) relative.
All nq + n steps (each coordinate, then each speed) run as one batched call, one complex column
each, giving M_x, f_x, A_x, b_x; then P_x = M_x u' - f_x, L_x = A_x^T lambda and
C_x = A_x u' - b_x, the 'residual' kind's partial derivatives (reference.derivatives.codegen),
which reference.derivatives.exact solves as it solves the generated ones. The velocity rows'
d(A u + a0)/dq comes from the module's `residuals` the same way.

The derivative costs what the sums path's forward costs, times a batched call's width: no
derivation, no cache entry of its own (Cassie: docs/checks.md, benchmarks/derivatives.md).
"""

from __future__ import annotations

import re

import numpy as np

from reference.errors import SingularSystemError

# The step: its O(h^2) truncation is 1e-60 relative, far below round-off, and h times the
# entries' derivatives stays far above the smallest normal number (1e-308).
STEP = 1e-30

# The functions a complex step differentiates exactly (analytic, and numpy's complex versions
# are the analytic continuation); abs, atan2 or a comparison would not be (abs of a complex
# is its modulus: the derivative would be silently lost).
ANALYTIC = frozenset({"sin", "cos", "tan", "sqrt", "exp", "log"})
_CALL = re.compile(r"\b([A-Za-z_][A-Za-z_0-9]*)\(")


def unsupported(source: str) -> set[str]:
    """The functions a summed module calls that a complex step cannot differentiate (its own
    functions and the sums aside): empty where complex steps apply."""
    own = {"_sums", "_sum_tables", "matrices", "kinematics", "residuals", "position_jacobian"}
    return set(_CALL.findall(source)) - ANALYTIC - own - {"energy"}


class ComplexStep:
    """R's partial derivatives of one NumericModel on the sums path by complex steps.

    Parameters
    ----------
    nm : NumericModel
        A model whose module is summed (nm.kernels of the Python backend, or nm's own Python
        kernels behind the C ones: the sums path runs on Python).
    """

    def __init__(self, nm):
        self.nm = nm
        self._matrices = nm._py.generated("matrices")
        self._residuals = nm._py.generated("residuals")

    def _stepped(self, fn, q: np.ndarray, u: np.ndarray, t: float, speeds: bool) -> list:
        """fn's groups at every complex step (one column each: the coordinates, then the
        speeds where `speeds`), as complex arrays (entries x steps)."""
        nq, n = q.size, u.size
        k = nq + n if speeds else nq
        Q = np.repeat(q.astype(complex)[:, None], k, axis=1)
        U = np.repeat(u.astype(complex)[:, None], k, axis=1)
        Q[np.arange(nq), np.arange(nq)] += 1j * STEP
        if speeds:
            U[np.arange(n), nq + np.arange(n)] += 1j * STEP
        with np.errstate(all="ignore"):  # a state where they are not defined: checked below
            groups = fn(Q, U, t, self.nm.p)
        out = [np.array([np.broadcast_to(e, (k,)) for e in g], complex) for g in groups]
        out = [g.reshape(-1, k) for g in out]
        if not all(np.isfinite(g).all() for g in out):
            self.nm.forward(q, u, t)  # raises the forward's own error where it has one
            raise SingularSystemError(self.nm.singular_message(q, float("nan")))
        return out

    def residual_jacobians(
        self, q: np.ndarray, u: np.ndarray, t: float, ud: np.ndarray, lam: np.ndarray
    ) -> dict[str, np.ndarray]:
        """P_x, L_x, C_x for x = q and u at (u', lambda), as the generated 'residual' module
        gives them (reference.derivatives.exact.DerivativeModel.residual_jacobians)."""
        n, nq, m = self.nm.n, self.nm.nq, self.nm.m
        M, f, A, b = (g.imag / STEP for g in self._stepped(self._matrices, q, u, t, True))
        k = nq + n
        M, A = M.reshape(n, n, k), A.reshape(m, n, k)
        P = np.einsum("ijk,j->ik", M, ud) - f
        L = np.einsum("jik,j->ik", A, lam) if m else np.zeros_like(P)
        C = np.einsum("jik,i->jk", A, ud) - b
        return {
            "P_q": P[:, :nq],
            "L_q": L[:, :nq],
            "C_q": C[:, :nq],
            "P_u": P[:, nq:],
            "L_u": L[:, nq:],
            "C_u": C[:, nq:],
        }

    def velocity_jacobian(self, q: np.ndarray, u: np.ndarray, t: float) -> np.ndarray:
        """d(A u + a0)/dq (m x nq)."""
        _position, velocity = self._stepped(self._residuals, q, u, t, False)
        return velocity.imag / STEP  # type: ignore[no-any-return]
