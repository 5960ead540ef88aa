"""Pinocchio's analytical derivatives of its answer, in the reference's terms.

- Point constraints (``solver = "constraint"``): constraintDynamics, then
  computeConstraintDynamicsDerivatives with the same constraint models and proximal settings:
  ddq_dq, ddq_dv, ddq_dtau and dlambda_dq, dlambda_dv, dlambda_dtau of the stacked
  contact_force (q in the tangent space: Pinocchio differentiates along integrate(q, dq)).
- Trees and unconstrained models (``solver = "aba"``): computeABADerivatives: ddq_dq, ddq_dv
  and Minv = ddq_dtau; the multipliers (joint reactions) follow from the accelerations through
  the adapter's maps.
- Textbook rows given as J and gamma (``solver = "kkt"``): Pinocchio has no derivative routine
  for a user's J; those models are differenced like the other engines (the check says so).

The maps' Jacobians are crosscheck.engines.linearization's; the configuration tangent is
pin.difference. A model's `planted_fault` (crosscheck.checks.derivatives.faults.Fault.in_jacobians,
set by the tests and `crosscheck sensitivity` only) plants an error in one of Pinocchio's blocks.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from crosscheck.engines.base import EngineUnsupported
from crosscheck.engines.linearization import EngineJacobians, EngineMaps

KKT_ROWS = (
    "its textbook rows are handed to forwardDynamics as J and gamma, which Pinocchio has no "
    "derivative routine for: differenced like the other engines"
)


def proximal_conditioning(model, data, qe, J: np.ndarray, mu: float) -> float | None:
    """||J M^-1 J^T|| / mu where the constraint rows that are not identically zero are
    dependent (the Delassus matrix's smallest singular value below mu): the condition number
    of the mu-regularized solve the derivatives use, whose round-off grows as 1/mu (a weld on a
    one-degree-of-freedom chain: 3.1e-6 at mu 1e-8, 1.4e-9 at mu 1e-4). None otherwise: full
    rank, or only exactly zero rows (a planar loop's out-of-plane row), which couple nothing."""
    if mu <= 0 or J.size == 0:
        return None
    rows = np.max(np.abs(J), axis=1) > 0.0
    if not rows.any():
        return None
    M = np.array(pin.crba(model, data, qe), float)
    M = np.triu(M) + np.triu(M, 1).T
    Dl = J[rows] @ np.linalg.solve(M, J[rows].T)
    s = np.linalg.svd(Dl, compute_uv=False)
    return float(s[0] / mu) if s[-1] < mu else None


def jacobians(em, qe: np.ndarray, ve: np.ndarray, t: float) -> EngineJacobians:
    """Pinocchio's answer at (qe, ve) and its analytical derivatives (module docstring)."""
    m, d = em.model, em.data
    tau = np.asarray(em._applied(qe, ve, t), float)
    if em.solver == "aba":
        a = pin.aba(m, d, qe, ve, tau).copy()
        dq, dv, minv = (np.array(x, float) for x in pin.computeABADerivatives(m, d, qe, ve, tau))
        return EngineJacobians(
            a, np.zeros(0), {"q": dq, "v": dv, "tau": minv}, {}, "computeABADerivatives"
        )
    if em.solver != "constraint":
        raise EngineUnsupported(KKT_ROWS)
    a = pin.constraintDynamics(m, d, qe, ve, tau, em.cms, em.cds, em.prox).copy()
    forces = np.concatenate([cd.contact_force.linear for cd in em.cds])
    out = pin.computeConstraintDynamicsDerivatives(m, d, em.cms, em.cds, em.prox)
    # one degree of freedom: Pinocchio hands an n x 1 matrix over as a vector
    aq, av, at, lq, lv, lt = (np.array(x, float).reshape(-1, m.nv) for x in out)
    J = np.array(pin.getConstraintsJacobian(m, d, em.cms, em.cds), float)
    return EngineJacobians(
        a,
        forces,
        {"q": aq, "v": av, "tau": at},
        {"q": lq, "v": lv, "tau": lt},
        "computeConstraintDynamicsDerivatives",
        proximal_conditioning(m, m.createData(), qe, J, float(em.prox_settings[1])),
    )


def maps(em, t: float) -> EngineMaps:
    """The engine model's maps as the linearization reads them."""
    m = em.model

    def back(qe, ve, ae, fe):
        return em._acc_to_reference(qe, ve, ae), em._multipliers(qe, ve, ae, fe)

    return EngineMaps(
        to_engine=lambda q, u: em.to_engine_state(q, u),
        tangent=lambda q0, q1: pin.difference(m, q0, q1),
        back=back,
        applied=lambda qe, ve: np.asarray(em._applied(qe, ve, t), float),
        jacobians=lambda qe, ve: jacobians(em, qe, ve, t),
        fault=getattr(em, "planted_fault", None),
    )
