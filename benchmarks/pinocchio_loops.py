"""Pinocchio's own closed-loop solver, constraintDynamics, on the model the suite's Pinocchio
adapter builds from an MJCF file (crosscheck.engines.pinocchio.user_file): one 3-D point
constraint (RigidConstraintModel CONTACT_3D, world-aligned rows, as MuJoCo's connect rows)
per `connect`, the adapter's damping and spring torques, and Pinocchio's proximal settings for
loops with dependent rows (a planar loop closed in 3-D: the Delassus matrix is singular, so
the exact solve is the limit of the proximal iterations; PROX as
benchmarks/pinocchio_loop_derivatives.py).

The adapter itself solves with forwardDynamics on an independent subset of the rows; this is
the cost of Pinocchio's solver for closed chains, for benchmarks/derivation_paths.py.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
PROX = (1e-12, 1e-8, 50)  # accuracy, proximal weight, iterations


class PinLoops:
    """constraintDynamics on a UserFilePinModel's model (connect equalities only)."""

    def __init__(self, adapter):
        if any(kind != "connect" for kind, _frames, _extra in adapter._eq):
            raise ValueError("only connect equalities are written as Pinocchio constraints")
        self.adapter = adapter
        model = self.model = adapter.model
        self.data = model.createData()
        self.cms = pin.StdVec_RigidConstraintModel()
        self.cds = pin.StdVec_RigidConstraintData()
        for _kind, (f1, f2), _extra in adapter._eq:
            a, b = model.frames[f1], model.frames[f2]
            cm = pin.RigidConstraintModel(
                pin.ContactType.CONTACT_3D,
                model,
                a.parentJoint,
                a.placement,
                b.parentJoint,
                b.placement,
                LWA,
            )
            self.cms.append(cm)
            self.cds.append(cm.createData())
        pin.initConstraintDynamics(model, self.data, self.cms, self.cds)
        self.prox = pin.ProximalSettings(*PROX)

    def _inputs(self, q, u):
        qe, ve = self.adapter.to_engine_state(q, u)
        return qe, ve, self.adapter._tau(qe, ve)

    def accelerations(self, q, u) -> np.ndarray:
        """Pinocchio's a (its own speeds) at the reference's state (q, u)."""
        qe, ve, tau = self._inputs(q, u)
        args = (self.model, self.data, qe, ve, tau, self.cms, self.cds, self.prox)
        return np.array(pin.constraintDynamics(*args), float)

    def error(self, q, u, engine_accelerations) -> float:
        """The largest difference from the adapter's accelerations (Pinocchio's speeds)."""
        return float(np.max(np.abs(self.accelerations(q, u) - engine_accelerations)))

    def timed(self, q, u):
        """The bare constraintDynamics call at (q, u), its inputs mapped beforehand."""
        qe, ve, tau = self._inputs(q, u)
        args = (self.model, self.data, qe, ve, tau, self.cms, self.cds, self.prox)
        return lambda: pin.constraintDynamics(*args)
