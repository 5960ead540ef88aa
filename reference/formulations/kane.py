"""Kane's equations with dependent generalized speeds, Eqs. 8-9 of the unit.

sum_i [ m_i a_Gi . dv_Gi/du_k + (I_Gi alpha_i + omega_i x H_Gi) . domega_i/du_k ]
    = F_uk + sum_j lambda_j a_jk,   with sum_k a_jk u_k + a_j0 = 0 (Eq. 8)
and the kinematic differential equations q' = N(q, u, t) closing the system.
"""

from __future__ import annotations

from reference.constraints import constraint_set
from reference.eom import EquationsOfMotion, acceleration_symbols, multiplier_symbols, split_linear
from reference.formulations.projection import generalized_inertia_minus_active
from reference.system import Model


def kane(model: Model) -> EquationsOfMotion:
    ud = acceleration_symbols(model)
    M, f = split_linear(generalized_inertia_minus_active(model, ud), ud)
    return EquationsOfMotion(
        model, "kane", M, f, constraint_set(model), ud, multiplier_symbols(model)
    )
