"""Pinocchio's analytical derivatives on a user's MJCF file.

Pinocchio answers a user's file with pin.forwardDynamics on the file's rows written from its
frame Jacobians (crosscheck/engines/pinocchio/user_file.py). Its derivative routine needs the
rows as its own constraint models, so the same equalities are given to it that way: a
`connect` as a CONTACT_3D between the two anchor frames (LOCAL_WORLD_ALIGNED: the rows
p1 - p2, the file's own), a `weld` as a CONTACT_6D (LOCAL: the relative placement, position and
orientation, the constraint the file's weld rows describe on the manifold; a weld with
torquescale 0 has no rotation rows, so it is a CONTACT_3D). Rows may be dependent (a planar
loop closed by a connect, a weld on a one-degree-of-freedom chain), so the solve is proximal
(PROX); constraintDynamics must give the accelerations
pin.forwardDynamics gives (the answer the instantaneous records judge), else no derivatives are
claimed. A `joint` equality has no constraint model: such a file is differenced.

computeConstraintDynamicsDerivatives then gives ddq_dq, ddq_dv, ddq_dtau and the derivatives of
the stacked contact forces lambda_e. Their generalized force J_c^T lambda_e (J_c the constraint
models' Jacobian, Pinocchio's convention M a + nle = tau + J_c^T lambda_e) is the constraint
force the reference writes A^T lambda, in Pinocchio's speeds; G^T J_c^T lambda_e in the
reference's (v = G u, the velocity map at q, power kept). Only u' and that force are unique
where rows are dependent, so those are compared (the multipliers' convention differs: a weld's
six contact forces are not the file's rows).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from crosscheck.engines.base import EngineUnsupported
from crosscheck.engines.linearization import EngineJacobians, EngineMaps
from crosscheck.engines.mujoco.user_file import rate_derivatives
from crosscheck.engines.pinocchio.derivatives import proximal_conditioning

# mu: where rows are dependent, the derivatives are computed on Pinocchio's mu-regularized
# factorization, whose round-off grows as 1/mu (weld_sites.xml: 3.1e-6 at mu 1e-8, 4.2e-8 at
# 1e-6, 1.4e-9 at 1e-4, du'/dtau); the proximal iterations remove mu's bias from the answer,
# which must still equal forwardDynamics' (SAME_ANSWER)
PROX = (1e-12, 1e-4, 1000)
# constraintDynamics against forwardDynamics on the independent rows: two exact solves of the
# same rows, round-off apart (~1e-14); above this they are not the same problem
SAME_ANSWER = 1e-9
LWA, LOCAL = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED, pin.ReferenceFrame.LOCAL
SIX = pin.ContactType.CONTACT_6D


def constraint_models(em):
    """(models, datas) of the file's equalities as Pinocchio constraint models."""
    cms, cds = pin.StdVec_RigidConstraintModel(), pin.StdVec_RigidConstraintData()
    for kind, objs, extra in em._eq:
        if kind == "joint":
            raise EngineUnsupported(
                "a joint equality has no Pinocchio constraint model, so no derivative routine: "
                "differenced like the other engines"
            )
        f1, f2 = (em.model.frames[f] for f in objs)
        six = kind == "weld" and extra != 0.0
        cm = pin.RigidConstraintModel(
            SIX if six else pin.ContactType.CONTACT_3D,
            em.model,
            f1.parentJoint,
            f1.placement,
            f2.parentJoint,
            f2.placement,
            LOCAL if six else LWA,
        )
        cms.append(cm)
        cds.append(cm.createData())
    return cms, cds


class UserFileDerivatives:
    """The derivative model beside a UserFilePinModel (module docstring)."""

    def __init__(self, em):
        self.em = em
        self.data = em.model.createData()
        self.cms, self.cds = constraint_models(em)
        pin.initConstraintDynamics(em.model, self.data, self.cms, self.cds)
        self.prox = pin.ProximalSettings(*PROX)

    def jacobians(self, qe: np.ndarray, ve: np.ndarray) -> EngineJacobians:
        em, m, d = self.em, self.em.model, self.data
        tau = em._tau(qe, ve)
        a = pin.constraintDynamics(m, d, qe, ve, tau, self.cms, self.cds, self.prox).copy()
        plain = np.asarray(em._solve(qe, ve)[0], float)
        if np.max(np.abs(a - plain)) > SAME_ANSWER * max(float(np.max(np.abs(plain))), 1.0):
            raise EngineUnsupported(
                "constraintDynamics does not give forwardDynamics' accelerations on this file "
                f"(they differ by {np.max(np.abs(a - plain)):.1e}): no derivatives claimed"
            )
        # a file without equalities has no constraint models: constraintDynamics is then ABA
        forces = np.concatenate(
            [np.zeros(0)]
            + [
                cd.contact_force.vector if cm.type == SIX else cd.contact_force.linear
                for cm, cd in zip(self.cms, self.cds, strict=True)
            ]
        )
        out = pin.computeConstraintDynamicsDerivatives(m, d, self.cms, self.cds, self.prox)
        # one degree of freedom: Pinocchio hands an n x 1 matrix over as a vector
        aq, av, at, lq, lv, lt = (np.array(x, float).reshape(-1, m.nv) for x in out)
        J = self.constraint_jacobian(qe)
        return EngineJacobians(
            a,
            forces,
            {"q": aq, "v": av, "tau": at},
            {"q": lq, "v": lv, "tau": lt},
            "computeConstraintDynamicsDerivatives (the file's rows as constraint models)",
            proximal_conditioning(m, m.createData(), qe, J, PROX[1]),
        )

    def constraint_jacobian(self, qe: np.ndarray) -> np.ndarray:
        """J_c of the constraint models at qe, rows as lambda_e is stacked."""
        m, d = self.em.model, self.data
        pin.computeJointJacobians(m, d, qe)
        pin.framesForwardKinematics(m, d, qe)
        for cm, cd in zip(self.cms, self.cds, strict=True):
            cm.calc(m, d, cd)  # the contact frames' placements at qe (the Jacobian's frames)
        J = np.array(pin.getConstraintsJacobian(m, d, self.cms, self.cds), float)
        return J.reshape(-1, m.nv)  # no rows on one degree of freedom: (0,), not (0, 1)

    def back(self, qe, ve, ae, fe):
        """(u', the generalized constraint force in the reference's speeds)."""
        em = self.em
        qpos, qvel = em._mj_state(qe, ve)
        acc = rate_derivatives(em.imp.joints, qpos, qvel, em._qacc(qe, ve, ae))
        q = em.from_engine_state(qe, ve)[0]
        # v = G u at q: the velocity map is linear in u, so its columns are its unit images
        G = np.column_stack([em.to_engine_state(q, e)[1] for e in np.eye(len(acc))])
        return acc, G.T @ (self.constraint_jacobian(qe).T @ np.asarray(fe, float))

    def maps(self) -> EngineMaps:
        em = self.em
        return EngineMaps(
            to_engine=lambda q, u: em.to_engine_state(q, u),
            tangent=lambda q0, q1: pin.difference(em.model, q0, q1),
            back=self.back,
            applied=lambda qe, ve: np.asarray(em._tau(qe, ve), float),
            jacobians=self.jacobians,
            fault=getattr(em, "planted_fault", None),
        )
