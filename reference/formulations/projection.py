"""Generalized inertia and active forces projected on partial velocities (Eqs. 7 and 9).

sum_i [ m_i a_Gi . dv_Gi/ds_k + (I_Gi alpha_i + omega_i x H_Gi) . domega_i/ds_k ] = F_k
where s are the coordinate rates (d'Alembert, Eq. 7) or the speeds (Kane, Eq. 9). The two
principles differ only in which rates the partial velocities are taken with respect to.
"""

from __future__ import annotations

import sympy as sp

from reference.system import Force, Model


def generalized_inertia_minus_active(model: Model, ud) -> sp.Matrix:
    """E_k = (generalized inertia force)_k - F_k, with u' as the symbols `ud`."""
    u = model.speeds
    E = sp.zeros(len(u), 1)
    g_inertial = model.gravity
    for b in model.bodies:
        a_G = model.time_derivative(b.v_G, ud)
        if b.v_frame == "body":  # inertial derivative of body-frame components
            a_G += b.omega.cross(b.v_G)
            g = b.R.T * g_inertial if b.R is not None else sp.zeros(3, 1)
        else:
            g = g_inertial
        alpha = model.time_derivative(b.omega, ud)  # body-fixed components: alpha = d(omega)/dt
        H = b.inertia * b.omega
        T_star = b.inertia * alpha + b.omega.cross(H)
        weight = b.mass * g
        for k, s in enumerate(u):
            dv = b.v_G.diff(s)
            dw = b.omega.diff(s)
            E[k] += b.mass * (a_G.T * dv)[0] + (T_star.T * dw)[0] - (weight.T * dv)[0]
    for ld in model.loads:
        vel, load = (ld.velocity, ld.force) if isinstance(ld, Force) else (ld.omega, ld.torque)
        for k, s in enumerate(u):
            E[k] -= (load.T * vel.diff(s))[0]
    if model.potential != 0:  # springs: F_k = -sum_j dV/dq_j dq'_j/ds_k
        for k, s in enumerate(u):
            for q, qdot in zip(model.coordinates, model.kinematics, strict=True):
                E[k] += sp.diff(model.potential, q) * sp.diff(qdot, s)
    return E
