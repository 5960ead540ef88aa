"""What the summed forms of Eqs. 5-9 share (reference.eom.SummedEquations): each body's
partial velocities and its inertia terms, the loads' and the springs' generalized forces, the
equations put together, every derivative taken on the expressions' graph (reference.dag).

A body with mass-center velocity v_G = V u + v_t and angular velocity omega = Omega u +
omega_t (V = dv_G/du, Omega = domega/du: 3 x n, one column per speed) contributes
m V^T V + Omega^T I_G Omega to M whatever the formulation (Eq. 9's inertia forces and the
second derivative of Eq. 5's kinetic energy are the same quadratic form); the formulations
differ in the forces they project (reference.formulations.kane_sums, lagrange_sums).
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from reference.constraints import constraint_set
from reference.dag import Calculus
from reference.eom import BodySums, SummedEquations, acceleration_symbols, multiplier_symbols
from reference.formulations.projection import load_points
from reference.system import Model

Term = tuple[sp.Matrix, sp.Matrix]


def calculus(model: Model) -> Calculus:
    """One derivation's derivatives (remembered across the bodies, which share their
    parents' kinematics)."""
    return Calculus(model.coordinates, model.kinematics, model.t)


def partials(calc: Calculus, vector: sp.Matrix, speeds: Sequence[sp.Symbol]) -> sp.Matrix:
    """d vector / d u_k, one column per speed: a point's partial velocities or a body's
    partial angular velocities (vector linear in the speeds)."""
    return calc.jacobian(vector, speeds)


def inertia_terms(model: Model, calc: Calculus) -> list[Term]:
    """(V, m 1) and (Omega, I_G) of every body: M = sum m V^T V + Omega^T I_G Omega."""
    out = []
    for b in model.bodies:
        out.append((partials(calc, b.v_G, model.speeds), b.mass * sp.eye(3)))
        out.append((partials(calc, b.omega, model.speeds), b.inertia))
    return out


def load_terms(model: Model, calc: Calculus) -> list[Term]:
    """(partial velocities of its point, force) of every applied force and (partial angular
    velocities, torque) of every applied torque: F_k = sum load . d(velocity)/du_k."""
    return [(partials(calc, vel, model.speeds), load) for vel, load in load_points(model)]


def spring_forces(model: Model, calc: Calculus) -> sp.Matrix:
    """-sum_j dV/dq_j dq'_j/du_k of the model's springs' potential V (gravity is not in it)."""
    n = len(model.speeds)
    if model.potential == 0:
        return sp.zeros(n, 1)
    grad = [calc.diff(model.potential, q) for q in model.coordinates]
    return sp.Matrix(
        [
            -sp.Add(*[g * calc.diff(qd, s) for g, qd in zip(grad, model.kinematics, strict=True)])
            for s in model.speeds
        ]
    )


def _nonzero(term: Term) -> bool:
    P, W = term
    return any(x != 0 for x in P) and any(x != 0 for x in W)


def summed_equations(
    model: Model, formulation: str, calc: Calculus, forces: list[Term]
) -> SummedEquations:
    """The equations of `model` with the bodies' inertia terms, these force terms, the springs
    and the loads (terms that are zero left out), and the constraint rows of Eqs. 1-4 and 8."""
    sums = BodySums(
        inertia=tuple(t for t in inertia_terms(model, calc) if _nonzero(t)),
        forces=tuple(t for t in forces + load_terms(model, calc) if _nonzero(t)),
        direct=spring_forces(model, calc),
    )
    return SummedEquations(
        model,
        formulation,
        sums,
        constraint_set(model, calc),
        acceleration_symbols(model),
        multiplier_symbols(model),
    )
