"""Generalized inertia and active forces projected on partial velocities (Eqs. 7 and 9).

sum_i [ m_i a_Gi . dv_Gi/ds_k + (I_Gi alpha_i + omega_i x H_Gi) . domega_i/ds_k ] = F_k
where s are the coordinate rates (d'Alembert, Eq. 7) or the speeds (Kane, Eq. 9). The two
principles differ only in which rates the partial velocities are taken with respect to.

The per-body pieces (a_G from the rate of v_G's components, gravity in those components, the
inertia torque, the loads' points) are also what the summed form of the same equations
projects (reference.formulations.kane_sums).
"""

from __future__ import annotations

import sympy as sp

from reference.system import Body, Force, Model


def inertial_acceleration(b: Body, v_rate: sp.Matrix) -> sp.Matrix:
    """a_G from the time derivative of v_G's components: plus omega x v_G where they are
    body components (the derivative of a body-fixed frame's components is not the inertial
    one)."""
    if b.v_frame == "body":
        return v_rate + b.omega.cross(b.v_G)
    return v_rate


def body_gravity(model: Model, b: Body) -> sp.Matrix:
    """Gravity in the components of the body's v_G (rotated into the body frame where v_G is
    in body components)."""
    if b.v_frame == "body":
        return b.R.T * model.gravity if b.R is not None else sp.zeros(3, 1)
    return model.gravity


def inertia_torque(b: Body, alpha: sp.Matrix) -> sp.Matrix:
    """Euler's I_G alpha + omega x I_G omega (body components)."""
    return b.inertia * alpha + b.omega.cross(b.inertia * b.omega)


def load_points(model: Model) -> list[tuple[sp.Matrix, sp.Matrix]]:
    """(velocity, force) of every applied force and (angular velocity, torque) of every
    applied torque."""
    return [
        (ld.velocity, ld.force) if isinstance(ld, Force) else (ld.omega, ld.torque)
        for ld in model.loads
    ]


def generalized_inertia_minus_active(model: Model, ud) -> sp.Matrix:
    """E_k = (generalized inertia force)_k - F_k, with u' as the symbols `ud`."""
    u = model.speeds
    E = sp.zeros(len(u), 1)
    for b in model.bodies:
        a_G = inertial_acceleration(b, model.time_derivative(b.v_G, ud))
        g = body_gravity(model, b)
        alpha = model.time_derivative(b.omega, ud)  # body-fixed components: alpha = d(omega)/dt
        T_star = inertia_torque(b, alpha)
        weight = b.mass * g
        for k, s in enumerate(u):
            dv = b.v_G.diff(s)
            dw = b.omega.diff(s)
            E[k] += b.mass * (a_G.T * dv)[0] + (T_star.T * dw)[0] - (weight.T * dv)[0]
    for vel, load in load_points(model):
        for k, s in enumerate(u):
            E[k] -= (load.T * vel.diff(s))[0]
    if model.potential != 0:  # springs: F_k = -sum_j dV/dq_j dq'_j/ds_k
        for k, s in enumerate(u):
            for q, qdot in zip(model.coordinates, model.kinematics, strict=True):
                E[k] += sp.diff(model.potential, q) * sp.diff(qdot, s)
    return E
