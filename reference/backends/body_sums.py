"""The sums over the bodies of a summed module's M and f, formed numerically at evaluation.

A module generated from reference.eom.SummedEquations (reference.backends.summed_source)
computes the entries of every term's partial velocities and weights at a state, straight-line,
and hands them here:

    M = sum_i P_i^T W_i P_i,        f = direct + sum_j Q_j^T w_j,

with P_i, Q_j the 3 x n partial velocities (only their nonzero columns travel: a body moves
with its ancestors' speeds only) and W_i, w_j the 3 x 3 weights and the 3 x 1 forces. The
sums are two matrix products over the stacked terms, in numpy; the module's functions run
them through `namespace(batched)`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class SumTables:
    """Where each value of a summed module's lists goes.

    The inertia values are, term after term, the 3 rows of P's nonzero columns (`cols`, row
    by row) and then W's 9 entries; the force values the same with Q and w's 3 entries.
    `take` picks a group out of the values, `put` places P's (or Q's) entries in the stacked
    (terms x 3 x n) array."""

    n: int
    n_inertia: int
    n_forces: int
    p_take: np.ndarray
    p_put: np.ndarray
    w_take: np.ndarray
    q_take: np.ndarray
    q_put: np.ndarray
    f_take: np.ndarray


def _layout(n: int, columns: Sequence[Sequence[int]], weight: int):
    """(take, put) of the partial velocities' entries and `take` of the weights' for terms
    with these nonzero columns."""
    take, put, wtake = [], [], []
    pos = 0
    for t, cols in enumerate(columns):
        for row in range(3):
            for c in cols:
                take.append(pos)
                put.append((3 * t + row) * n + c)
                pos += 1
        wtake.extend(range(pos, pos + weight))
        pos += weight
    return np.array(take, int), np.array(put, int), np.array(wtake, int)


def sum_tables(
    n: int, inertia_columns: Sequence[Sequence[int]], force_columns: Sequence[Sequence[int]]
) -> SumTables:
    """The tables of a module with n speeds and these terms' nonzero columns."""
    p_take, p_put, w_take = _layout(n, inertia_columns, 9)
    q_take, q_put, f_take = _layout(n, force_columns, 3)
    return SumTables(
        n, len(inertia_columns), len(force_columns), p_take, p_put, w_take, q_take, q_put, f_take
    )


def _stacked(values: np.ndarray, take: np.ndarray, put: np.ndarray, terms: int, n: int):
    """The terms' partial velocities as one (3 terms) x n array (trailing axes: a batch), of the
    values' dtype (complex for the complex-step derivatives: a float array would drop their
    imaginary parts)."""
    out = np.zeros((terms * 3 * n, *values.shape[1:]), values.dtype)
    out[put] = values[take]
    return out.reshape(terms * 3, n, *values.shape[1:])


def sums(
    S: SumTables, inertia: Sequence[float], forces: Sequence[float], direct: Sequence[float]
) -> tuple[list[float], list[float]]:
    """M (n x n, row by row) and f at one state, as lists of floats."""
    n, T = S.n, S.n_inertia
    iv, fv = np.array(inertia, float), np.array(forces, float)
    P = _stacked(iv, S.p_take, S.p_put, T, n)
    W = iv[S.w_take].reshape(T, 3, 3)
    WP = np.matmul(W, P.reshape(T, 3, n)).reshape(3 * T, n)
    M = P.T @ WP
    Q = _stacked(fv, S.q_take, S.q_put, S.n_forces, n)
    f = np.array(direct, float) + Q.T @ fv[S.f_take]
    return M.ravel().tolist(), f.tolist()  # type: ignore[no-any-return]


def _column(values: Sequence[Any]) -> np.ndarray:
    """Values of a batch (arrays of the states, or numbers shared by all) as one array, one row
    per value: float, or complex where a value is (reference.derivatives.complex_step)."""
    arrays = [i for i, v in enumerate(values) if type(v) is np.ndarray and v.ndim]
    numbers = [i for i, v in enumerate(values) if not (type(v) is np.ndarray and v.ndim)]
    rows = [values[i] for i in arrays]
    if len({r.shape for r in rows}) > 1:  # numbers of some states only: broadcast
        rows = np.broadcast_arrays(*rows)
    size = rows[0].size if rows else 1
    stacked = np.array(rows).reshape(len(arrays), size)
    shared = np.array([values[i] for i in numbers]).reshape(len(numbers), 1)
    complex_ = stacked.dtype.kind == "c" or shared.dtype.kind == "c"
    out = np.empty((len(values), size), complex if complex_ else float)
    out[arrays] = stacked
    out[numbers] = shared
    return out


def sums_batched(
    S: SumTables, inertia: Sequence[Any], forces: Sequence[Any], direct: Sequence[Any]
) -> tuple[np.ndarray, np.ndarray]:
    """M's entries (n^2 x N) and f (n x N) at N states."""
    n, T = S.n, S.n_inertia
    iv, fv, dv = _column(inertia), _column(forces), _column(direct)
    N = max(iv.shape[1], fv.shape[1], dv.shape[1])
    iv, fv, dv = (np.broadcast_to(x, (x.shape[0], N)) for x in (iv, fv, dv))
    P = _stacked(iv, S.p_take, S.p_put, T, n).reshape(T, 3, n, N)
    W = iv[S.w_take].reshape(T, 3, 3, N)
    M = np.einsum("taiz,tabz,tbjz->ijz", P, W, P, optimize=True)
    Q = _stacked(fv, S.q_take, S.q_put, S.n_forces, n)
    f = dv + np.einsum("kiz,kz->iz", Q, fv[S.f_take])
    return M.reshape(n * n, N), f


def namespace(batched: bool) -> dict[str, Any]:
    """What a summed module's source calls: `_sum_tables` once when it is loaded, `_sums` in
    its matrices function."""
    return {"_sum_tables": sum_tables, "_sums": sums_batched if batched else sums}
