"""d'Alembert's principle with multipliers, Eq. 7 of the unit.

sum_i [ m_i a_Gi . dv_Gi/dq'_k + (I_Gi alpha_i + omega_i x H_Gi) . domega_i/dq'_k ]
    = F_qk + sum_j lambda_j a_jk
Gravity enters as the weight force at each mass center (not through a potential), which makes
the agreement with Lagrange's equations a real check of both.
"""

from __future__ import annotations

from reference.constraints import constraint_set
from reference.eom import EquationsOfMotion, acceleration_symbols, multiplier_symbols, split_linear
from reference.formulations.projection import generalized_inertia_minus_active
from reference.system import Model


def dalembert(model: Model) -> EquationsOfMotion:
    # The speeds are the coordinate rates here (Model.validate), so d/ds_k is d/dq'_k.
    ud = acceleration_symbols(model)
    M, f = split_linear(generalized_inertia_minus_active(model, ud), ud)
    return EquationsOfMotion(
        model, "dalembert", M, f, constraint_set(model), ud, multiplier_symbols(model)
    )
