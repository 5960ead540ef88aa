"""Lagrange's equations with multipliers, Eqs. 5-6 of the unit.

d/dt(dL/dq'_k) - dL/dq_k = (F_qk)_nc + sum_j lambda_j a_jk,  L = K - V.
K is the sum of 1/2 m v_G.v_G + 1/2 omega.I_G omega over the bodies; V is the model's spring
potential plus the gravity potential -m g.r_G of each body; (F_qk)_nc = sum F.dv/dq'_k over the
applied forces and torques.
"""

from __future__ import annotations

import sympy as sp

from reference.constraints import constraint_set
from reference.eom import EquationsOfMotion, acceleration_symbols, multiplier_symbols, split_linear
from reference.system import Force, Model


def kinetic_energy(model: Model) -> sp.Expr:
    K = sp.Integer(0)
    for b in model.bodies:
        K += sp.Rational(1, 2) * b.mass * (b.v_G.T * b.v_G)[0]
        K += sp.Rational(1, 2) * (b.omega.T * b.inertia * b.omega)[0]
    return K


def potential_energy(model: Model) -> sp.Expr:
    V = model.potential
    if any(g != 0 for g in model.gravity):
        for b in model.bodies:
            if b.r_G is None:
                raise ValueError(f"{model.name}: body {b.name} needs r_G for the gravity potential")
            V += -b.mass * (model.gravity.T * b.r_G)[0]
    return V


def nonconservative_forces(model: Model, rates) -> sp.Matrix:
    """(F_qk)_nc: each applied force dotted with the partial velocity of its point (Eq. 6)."""
    F = sp.zeros(len(rates), 1)
    for ld in model.loads:
        vel, load = (ld.velocity, ld.force) if isinstance(ld, Force) else (ld.omega, ld.torque)
        for k, r in enumerate(rates):
            F[k] += (load.T * vel.diff(r))[0]
    return F


def lagrange(model: Model) -> EquationsOfMotion:
    qd = model.speeds  # u_k = q'_k for Lagrange's models (checked by Model.validate)
    ud = acceleration_symbols(model)
    L = kinetic_energy(model) - potential_energy(model)
    Fnc = nonconservative_forces(model, qd)
    E = sp.zeros(len(qd), 1)
    for k, (q, v) in enumerate(zip(model.coordinates, qd, strict=True)):
        dL_dv = sp.diff(L, v)
        E[k] = model.time_derivative(dL_dv, ud) - sp.diff(L, q) - Fnc[k]
    M, f = split_linear(E, ud)
    return EquationsOfMotion(
        model, "lagrange", M, f, constraint_set(model), ud, multiplier_symbols(model)
    )
