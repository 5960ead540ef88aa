"""Constraint equations, Eqs. 1-4 and 8 of the unit.

Configuration constraints f_j(q, t) = 0 (Eq. 1) give, by differentiation, the velocity form
sum_k a_jk q'_k + a_j0 = 0 (Eqs. 2-3) with a_jk = df_j/dq_k and a_j0 = df_j/dt (Eq. 4). Motion
constraints are given directly in that form in the speeds (Eq. 8). Both are mapped to the model's
speeds through q' = N(q, u, t), so every formulation sees A u + a0 = 0 and its derivative
A u' = b with b = -(d/dt)(A u + a0) at u' = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from reference.dag import Calculus
from reference.errors import RedundantConstraintError
from reference.system import Model


@dataclass(frozen=True)
class ConstraintSet:
    """A (m x n_u), a0 (m), b (m): A u + a0 = 0 and A u' = b; f: the position-level rows."""

    A: sp.Matrix
    a0: sp.Matrix
    b: sp.Matrix
    f: sp.Matrix  # configuration constraints f(q, t) (position residuals); motion rows have none
    A_q: sp.Matrix  # Eq. 4 coefficients in the coordinate rates, configuration constraints only
    a0_q: sp.Matrix
    names: tuple[str, ...]

    @property
    def m(self) -> int:
        return self.A.shape[0]


def configuration_coefficients(
    f: sp.Matrix, q, t, calculus: Calculus | None = None
) -> tuple[sp.Matrix, sp.Matrix]:
    """Eq. 4: a_jk = df_j/dq_k, a_j0 = df_j/dt (with `calculus`: on the expressions' graph)."""
    if f.shape[0] == 0:
        return sp.zeros(0, len(q)), sp.zeros(0, 1)
    if calculus is not None:
        return calculus.jacobian(f, q), calculus.diff(f, t)
    return f.jacobian(list(q)), f.diff(t)


def motion_coefficients(
    g: sp.Matrix, u, calculus: Calculus | None = None
) -> tuple[sp.Matrix, sp.Matrix]:
    """Eq. 8: rows linear in the speeds, split into A (coefficients) and a0 (the rest)."""
    if g.shape[0] == 0:
        return sp.zeros(0, len(u)), sp.zeros(0, 1)
    if calculus is not None:
        return calculus.jacobian(g, u), calculus.replace(g, {s: 0 for s in u})
    A = g.jacobian(list(u))
    a0 = g.subs({s: 0 for s in u})
    return A, a0


def constraint_set(model: Model, calculus: Calculus | None = None) -> ConstraintSet:
    """All constraints of a model in its speeds, with the acceleration-level right side b.

    `calculus` (reference.dag.Calculus) takes the derivatives on the expressions' graph, for a
    model too large for sympy's tree walks; None takes sympy's own (the textbook's models)."""
    q, u, t = model.coordinates, model.speeds, model.t
    f = (
        sp.Matrix(model.configuration_constraints)
        if model.configuration_constraints
        else sp.zeros(0, 1)
    )
    A_q, a0_q = configuration_coefficients(f, q, t, calculus)
    # q' = N u + n0 (the kinematics are affine in u in every model of the unit)
    qdot = sp.Matrix(model.kinematics)
    N, n0 = motion_coefficients(qdot, u, calculus)
    rows_A = [A_q * N] if f.shape[0] else []
    rows_a0 = [a0_q + A_q * n0] if f.shape[0] else []
    if model.motion_constraints:
        A_m, a0_m = motion_coefficients(sp.Matrix(model.motion_constraints), u, calculus)
        rows_A.append(A_m)
        rows_a0.append(a0_m)
    if rows_A:
        A = sp.Matrix.vstack(*rows_A)
        a0 = sp.Matrix.vstack(*rows_a0)
    else:
        A, a0 = sp.zeros(0, len(u)), sp.zeros(0, 1)
    velocity_rows = A * sp.Matrix(u) + a0
    if calculus is not None:
        b = -calculus.rate(velocity_rows)
    else:
        b = -model.time_derivative(velocity_rows, accelerations=None)
    names = model.constraint_names or tuple(f"c{j + 1}" for j in range(A.shape[0]))
    return ConstraintSet(A=A, a0=a0, b=b, f=f, A_q=A_q, a0_q=a0_q, names=names)


def is_rheonomic(model: Model) -> bool:
    """Rheonomic: some constraint depends explicitly on time (a0 != 0 from df/dt, Eq. 4)."""
    exprs = list(model.configuration_constraints) + list(model.motion_constraints)
    return any(sp.diff(e, model.t) != 0 for e in exprs)


def integrability(A_row, a0, q, t) -> str:
    """The exactness test that follows Eq. 4 for one motion constraint in the coordinate rates.

    da_jk/dq_l = da_jl/dq_k for all k, l and da_jk/dt = da_j0/dq_k. Passing means holonomic;
    failing does not prove nonholonomic (an integrating factor may exist), so the answer is
    "not exact as written".
    """
    n = len(q)
    for k in range(n):
        if sp.simplify(sp.diff(A_row[k], t) - sp.diff(a0, q[k])) != 0:
            return "not exact as written"
        for l in range(k + 1, n):
            if sp.simplify(sp.diff(A_row[k], q[l]) - sp.diff(A_row[l], q[k])) != 0:
                return "not exact as written"
    return "holonomic"


def classify(model: Model) -> list[dict]:
    """Kind of every constraint row: configuration (holonomic) or motion (tested with Eq. 4's
    rule)."""
    out = []
    names = model.constraint_names or tuple(f"c{j + 1}" for j in range(model.n_constraints))
    rheo = lambda e: "rheonomic" if sp.diff(e, model.t) != 0 else "scleronomic"
    n_config = len(model.configuration_constraints)
    for name, f in zip(names[:n_config], model.configuration_constraints, strict=True):
        out.append(
            {
                "name": name,
                "kind": "configuration",
                "holonomic": "holonomic",
                "time": rheo(f),
                "expression": str(f),
            }
        )
    names_m = names[n_config:]
    for name, g in zip(names_m, model.motion_constraints, strict=True):
        if model.speeds_are_coordinate_rates:
            A, a0 = motion_coefficients(sp.Matrix([g]), model.speeds)
            kind = integrability(list(A), a0[0], model.coordinates, model.t)
        else:
            kind = "not tested: the speeds are not coordinate rates"
        out.append(
            {
                "name": name,
                "kind": "motion",
                "holonomic": kind,
                "time": rheo(g),
                "expression": str(g),
            }
        )
    return out


def check_independent(A_numeric: np.ndarray, names, *, where: str) -> None:
    """Eq. 4 discussion: rank(A) must equal m. Name the dependent rows and the way out."""
    m = A_numeric.shape[0]
    if m == 0:
        return
    s = np.linalg.svd(A_numeric, compute_uv=False)
    # Rank tolerance: round-off of an SVD of an m x n matrix of entries of size max|A|.
    tol = max(A_numeric.shape) * np.finfo(float).eps * (s[0] if s.size else 0.0) * 10
    rank = int((s > tol).sum())
    if rank == m:
        return
    dependent, rank_before = [], 0
    for j in range(m):  # a row that does not raise the rank of the rows before it
        r = int(np.linalg.matrix_rank(A_numeric[: j + 1], tol))
        if r == rank_before:
            dependent.append(names[j])
        rank_before = r
    raise RedundantConstraintError(
        f"constraint rows are dependent at {where}: rank(A) = {rank} < m = {m}; rows "
        f"{dependent} repeat earlier rows. Remove the redundant constraints (Eq. 4: only "
        f"independent constraint equations may be used)"
    )
