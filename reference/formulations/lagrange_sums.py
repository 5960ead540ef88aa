"""Lagrange's equations (Eqs. 5-6) as sums over the bodies.

K = sum_i 1/2 m_i v_Gi . v_Gi + 1/2 omega_i . I_i omega_i, with V = dv_G/dq' and
Omega = domega/dq' each body's partial velocities (reference.formulations.body_terms; the
speeds are the coordinate rates here), dK/dq'_k = sum_i m_i v_Gi . V_i,k + I_i omega_i .
Omega_i,k and, I_i being constant in body components,

    d/dt(dK/dq'_k) - dK/dq_k
        = sum_i m_i (v_Gi' . V_i,k + v_Gi . (V_i,k' - dv_Gi/dq_k))
                + I_i omega_i' . Omega_i,k + I_i omega_i . (Omega_i,k' - domega_i/dq_k)

where ' is the time derivative of the components. With v_G' = V q'' + v_0' and omega' =
Omega q'' + omega_0' (the velocity products at q'' = 0), Eqs. 5-6 are M q'' - f = A^T lambda
with Kane's M (reference.formulations.kane_sums) and

    f = F_nc - dV/dq + sum_i [ -V_i^T m_i v_0i' - (V_i' - dv_Gi/dq)^T m_i v_Gi
                               - Omega_i^T I_i omega_0i' - (Omega_i' - domega_i/dq)^T I_i omega_i
                               + (dr_Gi/dq)^T m_i g ],

the last term being the gravity potential's -dV/dq, the springs' in -dV/dq, and F_nc the
loads' (partial velocity)^T load. Every factor is taken from the scalar K as Lagrange does,
not from Newton-Euler, so it checks Kane's sums as the symbolic Lagrange checks Kane.
"""

from __future__ import annotations

import sympy as sp

from reference.eom import SummedEquations
from reference.errors import ModelDefinitionError
from reference.formulations.body_terms import calculus, partials, summed_equations
from reference.system import Model


def lagrange_sums(model: Model) -> SummedEquations:
    """Eqs. 5-6 as sums over the bodies (the speeds are the coordinate rates: Model.validate)."""
    calc = calculus(model)
    q, rates = model.coordinates, model.speeds
    moving = set(q) | set(rates) | {model.t}
    gravity = any(g != 0 for g in model.gravity)
    forces = []
    for b in model.bodies:
        if moving & set().union(*(calc.free(sp.sympify(x)) for x in b.inertia)):
            raise ModelDefinitionError(model.name, [f"body {b.name}: I_G must be constant"])
        V, Omega = partials(calc, b.v_G, rates), partials(calc, b.omega, rates)
        I_omega = b.inertia * b.omega
        forces += [
            (V, -b.mass * calc.rate(b.v_G)),
            (calc.rate(V) - calc.jacobian(b.v_G, q), -b.mass * b.v_G),
            (Omega, -b.inertia * calc.rate(b.omega)),
            (calc.rate(Omega) - calc.jacobian(b.omega, q), -I_omega),
        ]
        if gravity:
            if b.r_G is None:
                raise ValueError(f"{model.name}: body {b.name} needs r_G for the gravity potential")
            forces.append((calc.jacobian(b.r_G, q), b.mass * model.gravity))
    return summed_equations(model, "lagrange", calc, forces)
