"""The one contract every formulation returns: M x'' - f = A^T lambda, A x'' = b.

x is the model's speed vector (q' for Lagrange's and d'Alembert's models, the dependent speeds
u for Kane's). `crosscheck` and the tests talk only to this contract.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from reference.constraints import ConstraintSet
from reference.system import Model


@dataclass(frozen=True)
class EquationsOfMotion:
    model: Model
    formulation: str
    M: sp.Matrix  # n x n generalized mass matrix
    f: sp.Matrix  # n forcing: applied generalized forces minus velocity-product terms
    constraints: ConstraintSet
    accelerations: tuple[sp.Symbol, ...]  # symbols for u'
    multipliers: tuple[sp.Symbol, ...]  # symbols for lambda

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


def acceleration_symbols(model: Model) -> tuple[sp.Symbol, ...]:
    return tuple(sp.Symbol(f"{u.name}_dot", real=True) for u in model.speeds)


def multiplier_symbols(model: Model) -> tuple[sp.Symbol, ...]:
    return tuple(sp.Symbol(f"lambda{j + 1}", real=True) for j in range(model.n_constraints))


def split_linear(E: sp.Matrix, ud) -> tuple[sp.Matrix, sp.Matrix]:
    """E = M u' - f is linear in u': M = dE/du', f = -E(u' = 0)."""
    M = E.jacobian(list(ud))
    f = -E.subs({a: 0 for a in ud})
    return M, f
