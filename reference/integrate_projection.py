"""Coordinate projection after every accepted step (Hairer-Wanner II Sec. VII.2)."""

from __future__ import annotations

import numpy as np

from .errors import ModelInputError, SingularSystemError
from .integrate_common import (
    PROJECTABLE,
    PROJECTION_FAIL,
    PROJECTION_MAX_ITER,
    PROJECTION_TOL,
    IntegrationError,
    _min_norm_correction,
)
from .integrate_index1 import _Index1


class _Projection(_Index1):
    """index1's RHS; after each accepted step y is projected and solver.f refreshed."""

    def __init__(self, nm, energy, refresh=True):
        super().__init__(nm, energy)
        self.refresh = refresh
        if not self.rates and self.mc:
            raise ModelInputError(
                f"{nm.model.name}: position projection needs speeds equal to the coordinate "
                f"rates (this model maps q' = N(q, u))"
            )

    @classmethod
    def build(cls, nm, energy, opts):
        return cls(nm, energy, opts["refresh"])

    @staticmethod
    def check_integrator(integrator):
        if integrator not in PROJECTABLE:
            raise ModelInputError(
                f"projection needs a one-step integrator whose state is (t, y, f): "
                f"{', '.join(PROJECTABLE)}; {integrator} keeps a multistep history that "
                f"projecting y would corrupt"
            )

    def dense_state(self, t, y):
        return self.project(t, y)

    def settings(self):
        return {"metric": "euclidean", "refresh": self.refresh}

    def project_q(self, q, t):
        """Gauss-Newton with minimum-norm steps on f(q, t) = 0 (in place on the list q)."""
        mc, nq, p, res, pjac = self.mc, self.nq, self.p, self.res, self.pjac
        if not mc:
            return q, None
        zu = self.zeros_u
        tol = PROJECTION_TOL * (1.0 + max(abs(v) for v in q))
        J = None
        for it in range(PROJECTION_MAX_ITER + 1):
            pos = res(q, zu, t, p)[0]
            err = max(abs(v) for v in pos)
            if err <= tol:
                break
            if it == PROJECTION_MAX_ITER:
                break
            J = pjac(q, zu, t, p)[0]
            try:
                dq = _min_norm_correction(J, mc, nq, pos, self.nm.redundant)
            except np.linalg.LinAlgError:
                raise SingularSystemError(
                    f"{self.nm.model.name}: projection at t = {t:.6g}: the constraint "
                    f"Jacobian is rank deficient at q = {np.round(q, 6).tolist()}"
                ) from None
            q = [a + b for a, b in zip(q, dq, strict=False)]
            self.stats["projection_iterations"] += 1
        if err > PROJECTION_FAIL:
            raise IntegrationError(
                f"{self.nm.model.name}: position projection did not converge at t = {t:.6g} "
                f"(|f| = {err:.2e} after {PROJECTION_MAX_ITER} Gauss-Newton steps): the step "
                f"left the manifold too far; tighten rtol/atol"
            )
        return q, J

    def project_u(self, q, u, t):
        if not self.m:
            return u
        vel = self.res(q, u, t, self.p)[1]
        if self.mc == self.m and self.rates:
            A = self.pjac(q, self.zeros_u, t, self.p)[0]  # A = df/dq when u = q'
        else:
            A = self.mat(q, u, t, self.p)[2]
        du = _min_norm_correction(A, self.m, self.n, vel, self.nm.redundant)
        return [a + b for a, b in zip(u, du, strict=False)]

    def project(self, t, y):
        q, u, W = self.full(t, y)
        q, _ = self.project_q(q, t)
        u = self.project_u(q, u, t)
        return np.array(q + u + ([W] if self.work else []), float)

    def after_step(self, solver):
        solver.y = self.project(solver.t, solver.y)
        self.stats["projections"] += 1
        if self.refresh:
            solver.f = solver.fun(solver.t, solver.y)
        return False
