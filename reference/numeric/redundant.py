"""KKT solve with dependent constraint rows: unique u' and A^T lambda, minimum-norm lambda.

Real model files close loops with more rows than the loop needs: a planar four-bar closed by a
3-D `connect` has three rows of which two are independent (the out-of-plane row is zero or a
combination of the others). The unit's rule rank(A) = m (Eq. 4 discussion) then fails, but the
motion is still unique: with the SVD A = U S V^T of rank r, the rows A_r = S_r V_r^T and the
right side b_r = U_r^T b carry the same constraint, and

    [ M    -A_r^T ] [u' ]   [f  ]
    [ A_r   0     ] [mu ] = [b_r]

has a unique solution when M is definite on null(A). Then A^T lambda = A_r^T mu for every
lambda with U_r^T lambda = mu, and the one of minimum norm is lambda = U_r mu (it lies in the
range of A, orthogonal to the dependent directions). A right side b with a component outside
the range of A (U_perp^T b != 0 beyond round-off) means the rows contradict each other: no
acceleration satisfies them all, and that is an error, not a least-squares answer.

The rank is the numerical rank at the model's initial state; a state where it drops lower is a
kinematic singularity and is refused as before (SingularSystemError).
"""

from __future__ import annotations

import numpy as np

from reference.errors import InconsistentConstraintError, SingularSystemError

# A singular value of A below RANK_RTOL times the largest counts as zero. Structurally dependent
# rows give exactly 0 (tests/data/fourbar_connect.xml: a zero row) or round-off, 7e-18 relative
# (tests/data/fourbar_tilted.xml, the same loop in a tilted frame; measured with
# `nm.matrices` and np.linalg.svd at the initial state); the codegen path refuses a Schur pivot
# ratio (a squared singular value ratio) under 1e-12, so sqrt(1e-12) = 1e-6 puts the two
# paths' singular poses at the same distance.
RANK_RTOL = 1e-6

# Dependent rows must be consistent: |U_perp^T b| over (|b| + |A| |u'|) above this is a
# contradiction. Round-off of b and of the SVD leaves ~1e-15 (the four-bar: 3e-16; the
# scale is in solve); 1e-8 is
# far above that and far below any real inconsistency of O(1).
CONSISTENCY_RTOL = 1e-8


def numerical_rank(A: np.ndarray) -> tuple[int, np.ndarray]:
    """Rank of A at RANK_RTOL and its singular values."""
    if A.shape[0] == 0:
        return 0, np.zeros(0)
    s = np.linalg.svd(A, compute_uv=False)
    return int((s > RANK_RTOL * s[0]).sum()) if s.size and s[0] > 0 else 0, s


def _cholesky_with_ratio(K: np.ndarray) -> tuple[np.ndarray, float]:
    """Cholesky factor and the smallest pivot over its diagonal entry (codegen's measure)."""
    try:
        L = np.linalg.cholesky(K)
    except np.linalg.LinAlgError:
        return np.zeros_like(K), -1.0
    d = np.diag(K)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.min(np.diag(L) ** 2 / np.where(d > 0, d, np.inf)) if d.size else 1.0
    return L, float(ratio)


def solve(M, f, A, b, *, rank_expected: int, augment: bool, where: str = ""):
    """u', minimum-norm lambda, pivot ratio and rank for M u' - f = A^T lambda, A u' = b.

    `augment`: M alone is singular (Euler parameters), so M + rho A_r^T A_r is factored, which
    leaves the solution unchanged because A_r u' = b_r (as in reference.backends.codegen).
    """
    M, f, A, b = (np.asarray(x, float) for x in (M, f, A, b))
    n, m = M.shape[0], A.shape[0]
    if m == 0:
        _L, piv = _cholesky_with_ratio(M)
        ud = np.linalg.solve(M, f) if piv > 0 else np.full(n, np.nan)
        return ud, np.zeros(0), piv, 0
    U, s, Vt = np.linalg.svd(A)
    r = int((s > RANK_RTOL * s[0]).sum()) if s[0] > 0 else 0
    if r < rank_expected:
        raise SingularSystemError(
            f"{where}: the constraint rows lose rank here (rank {r} < {rank_expected} at the "
            f"initial state; singular values {np.array2string(s, precision=2)}): a kinematic "
            f"singularity. Move the state away from this pose."
        )
    Ur = U[:, :r]
    Ar = s[:r, None] * Vt[:r]
    br = Ur.T @ b
    if augment:
        rho = (np.trace(M) / n) / max((Ar * Ar).sum() / max(r, 1), 1e-300)
        K, fa = M + rho * Ar.T @ Ar, f + rho * Ar.T @ br
    else:
        K, fa = M, f
    _L, piv_M = _cholesky_with_ratio(K)
    if not piv_M > 0:
        return np.full(n, np.nan), np.full(m, np.nan), piv_M, r
    Y = np.linalg.solve(K, Ar.T)
    y = np.linalg.solve(K, fa)
    S = Ar @ Y
    _Ls, piv_S = _cholesky_with_ratio(S)
    if not piv_S > 0:
        return np.full(n, np.nan), np.full(m, np.nan), piv_S, r
    mu = np.linalg.solve(S, br - Ar @ y)
    ud = y + Y @ mu
    lam = Ur @ mu
    off = float(np.linalg.norm(A @ ud - b))
    # the scale includes the unconstrained acceleration y = K^-1 f: at a state where u' and b
    # vanish (the N-four-bar released upright: measured |u'| ~ 1e-16) round-off alone would
    # otherwise look like a contradiction
    scale = float(np.linalg.norm(b) + s[0] * max(np.linalg.norm(ud), np.linalg.norm(y))) or 1.0
    if off > CONSISTENCY_RTOL * scale:
        raise InconsistentConstraintError(
            f"{where}: the constraint rows are dependent (rank {r} < {m}) and contradict each "
            f"other: |A u' - b| = {off:.2e} (relative {off / scale:.1e} > "
            f"{CONSISTENCY_RTOL:.0e}). Remove the contradicting constraints or fix their anchors."
        )
    return ud, lam, min(piv_M, piv_S), r
