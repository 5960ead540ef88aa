"""Kane's equations (Eq. 9) and d'Alembert's principle (Eq. 7) as sums over the bodies.

With each body's partial velocities V = dv_G/du and partial angular velocities
Omega = domega/du (reference.formulations.body_terms), its accelerations are
a_G = V u' + a_0 and alpha = Omega u' + alpha_0, where a_0 and alpha_0 are the velocity
products (the time derivatives at u' = 0, plus omega x v_G where v_G has body components).
Eq. 9,

    sum_i [ m_i a_Gi . V_i,k + (I_i alpha_i + omega_i x I_i omega_i) . Omega_i,k ]
        = F_k + sum_j lambda_j a_jk,

is then M u' - f = A^T lambda with

    M = sum_i m_i V_i^T V_i + Omega_i^T I_i Omega_i,
    f = F + sum_i V_i^T m_i (g_i - a_0i) - Omega_i^T (I_i alpha_0i + omega_i x I_i omega_i),

F the loads' sum of (partial velocity)^T load and the springs' -sum_j dV/dq_j dq'_j/du_k.
d'Alembert's principle (Eq. 7) is the same sum with the coordinate rates as the speeds.
"""

from __future__ import annotations

from reference.eom import SummedEquations
from reference.formulations.body_terms import calculus, partials, summed_equations
from reference.formulations.projection import body_gravity, inertia_torque, inertial_acceleration
from reference.system import Model


def kane_sums(model: Model, formulation: str = "kane") -> SummedEquations:
    """Eq. 9 as sums over the bodies (Eq. 7 with `formulation` 'dalembert')."""
    calc = calculus(model)
    forces = []
    for b in model.bodies:
        a_0 = inertial_acceleration(b, calc.rate(b.v_G))
        alpha_0 = calc.rate(b.omega)
        V, Omega = partials(calc, b.v_G, model.speeds), partials(calc, b.omega, model.speeds)
        forces.append((V, b.mass * (body_gravity(model, b) - a_0)))
        forces.append((Omega, -inertia_torque(b, alpha_0)))
    return summed_equations(model, formulation, calc, forces)


def dalembert_sums(model: Model) -> SummedEquations:
    """Eq. 7 as sums over the bodies: Eq. 9's with the coordinate rates as the speeds (which
    Model.validate requires of a d'Alembert model)."""
    return kane_sums(model, "dalembert")
