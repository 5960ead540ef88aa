"""The one contract every formulation returns: M x'' - f = A^T lambda, A x'' = b.

x is the model's speed vector (q' for Lagrange's and d'Alembert's models, the dependent speeds
u for Kane's). `crosscheck` and the tests talk only to this contract.

It comes in two forms. `EquationsOfMotion` holds M and f as expressions (the textbook's
models). `SummedEquations` holds them as sums over the bodies, M = sum P^T W P and
f = g + sum Q^T w, each term's partial velocities P, Q and weights W, w as expressions and the
sums left to the evaluation (reference.backends.body_sums): a robot's M written out as
expressions is too large to derive (docs/architecture.md, "Two derivation paths"). Both give
A, b, M, f and the residuals alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from reference.constraints import ConstraintSet
from reference.system import Model


class _Rows:
    """What both forms share: the constraint rows and the residual equations."""

    M: sp.Matrix
    f: sp.Matrix
    constraints: ConstraintSet
    accelerations: tuple[sp.Symbol, ...]
    multipliers: tuple[sp.Symbol, ...]

    @property
    def A(self) -> sp.Matrix:
        return self.constraints.A

    @property
    def b(self) -> sp.Matrix:
        return self.constraints.b

    def residual_equations(self) -> sp.Matrix:
        """The dynamic equations as printed in the unit: M u' - f - A^T lambda (= 0)."""
        lam = sp.Matrix(self.multipliers) if self.multipliers else sp.zeros(0, 1)
        ud = sp.Matrix(self.accelerations)
        return self.M * ud - self.f - (self.A.T * lam if lam.shape[0] else sp.zeros(*self.f.shape))

    def constraint_equations(self) -> sp.Matrix:
        """The twice-differentiated (or once, for motion constraints) rows: A u' - b (= 0)."""
        return self.A * sp.Matrix(self.accelerations) - self.b


@dataclass(frozen=True)
class EquationsOfMotion(_Rows):
    model: Model
    formulation: str
    M: sp.Matrix  # n x n generalized mass matrix
    f: sp.Matrix  # n forcing: applied generalized forces minus velocity-product terms
    constraints: ConstraintSet
    accelerations: tuple[sp.Symbol, ...]  # symbols for u'
    multipliers: tuple[sp.Symbol, ...]  # symbols for lambda


@dataclass(frozen=True)
class BodySums:
    """M = sum_i P_i^T W_i P_i and f = direct + sum_j Q_j^T w_j.

    Parameters
    ----------
    inertia : tuple of (P, W)
        P a 3 x n matrix (a body's partial velocities or partial angular velocities, one
        column per speed), W its 3 x 3 weight (m times the identity, or the central inertia).
    forces : tuple of (Q, w)
        Q a 3 x n matrix of partial velocities, w the 3 x 1 force or torque it projects.
    direct : sympy Matrix
        n x 1: generalized forces given as such (the springs' -dV/dq).
    """

    inertia: tuple[tuple[sp.Matrix, sp.Matrix], ...]
    forces: tuple[tuple[sp.Matrix, sp.Matrix], ...]
    direct: sp.Matrix


@dataclass(frozen=True)
class SummedEquations(_Rows):
    """M x'' - f = A^T lambda, A x'' = b with M and f as `sums` over the bodies."""

    model: Model
    formulation: str
    sums: BodySums
    constraints: ConstraintSet
    accelerations: tuple[sp.Symbol, ...]
    multipliers: tuple[sp.Symbol, ...]

    @property
    def M(self) -> sp.Matrix:  # type: ignore[override]
        """The sum written out (for small models: the tests compare it with the other form)."""
        n = len(self.model.speeds)
        return sum((P.T * W * P for P, W in self.sums.inertia), sp.zeros(n, n))

    @property
    def f(self) -> sp.Matrix:  # type: ignore[override]
        """The sum written out, as M."""
        return sum((Q.T * w for Q, w in self.sums.forces), self.sums.direct)


def acceleration_symbols(model: Model) -> tuple[sp.Symbol, ...]:
    return tuple(sp.Symbol(f"{u.name}_dot", real=True) for u in model.speeds)


def multiplier_symbols(model: Model) -> tuple[sp.Symbol, ...]:
    return tuple(sp.Symbol(f"lambda{j + 1}", real=True) for j in range(model.n_constraints))


def split_linear(E: sp.Matrix, ud) -> tuple[sp.Matrix, sp.Matrix]:
    """E = M u' - f is linear in u': M = dE/du', f = -E(u' = 0)."""
    M = E.jacobian(list(ud))
    f = -E.subs({a: 0 for a in ud})
    return M, f
