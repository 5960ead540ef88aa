"""Coordinate projection after every accepted step (Hairer-Wanner II Sec. VII.2)."""

from __future__ import annotations

import numpy as np

from reference.errors import ModelInputError, SingularSystemError
from reference.integrate.common import (
    PROJECTABLE,
    PROJECTION_FAIL,
    PROJECTION_MAX_ITER,
    PROJECTION_TOL,
    IntegrationError,
    as_floats,
    min_norm_correction,
)
from reference.integrate.index1 import Index1


class Projection(Index1):
    """index1's RHS; after each accepted step y is projected and solver.f refreshed."""

    def __init__(self, nm, energy, refresh=True):
        super().__init__(nm, energy)
        self.refresh = refresh
        self.jac = (None, None)  # (the last projected state, the position Jacobian there)
        self.vec = np.array if self.arrays else list  # a kernel input from a list of floats
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

    def project_q(self, q, u, t):
        """Gauss-Newton with minimum-norm steps on f(q, t) = 0: (q, its kernel input, the
        velocity residual A u + a0 at the final q). The residuals function returns both groups,
        so the check that ends the iteration also gives project_u its residual (f does not
        depend on u). Arithmetic on lists of floats (a few entries: numpy's per-call cost is
        larger than the work), the kernels called with their own input type (`vec`)."""
        mc, nq, res, pjac, vec = self.mc, self.nq, self.res, self.pjac, self.vec
        zu, qk, uk = self.zeros_u, vec(q), vec(u)
        tol = PROJECTION_TOL * (1.0 + max(map(abs, q), default=0.0))
        for it in range(PROJECTION_MAX_ITER + 1):
            pos, vel = res(qk, uk, t)
            err = max(map(abs, as_floats(pos)), default=0.0)
            if err <= tol or it == PROJECTION_MAX_ITER:
                break
            J = as_floats(pjac(qk, zu, t)[0])
            try:
                dq = min_norm_correction(J, mc, nq, as_floats(pos), self.nm.redundant)
            except np.linalg.LinAlgError:
                raise SingularSystemError(
                    f"{self.nm.model.name}: projection at t = {t:.6g}: the constraint "
                    f"Jacobian is rank deficient at q = {np.round(q, 6).tolist()}"
                ) from None
            q = [a + b for a, b in zip(q, dq, strict=True)]
            qk = vec(q)
            self.stats["projection_iterations"] += 1
        if err > PROJECTION_FAIL:
            raise IntegrationError(
                f"{self.nm.model.name}: position projection did not converge at t = {t:.6g} "
                f"(|f| = {err:.2e} after {PROJECTION_MAX_ITER} Gauss-Newton steps): the step "
                f"left the manifold too far; tighten rtol/atol"
            )
        return q, qk, as_floats(vel)

    def project_u(self, qk, u, t, vel):
        """u - A^T (A A^T)^-1 (A u + a0), and A where it is the position Jacobian (None else)."""
        A = None
        if self.mc == self.m and self.rates:
            A = self.pjac(qk, self.zeros_u, t)[0]  # A = df/dq when u = q'
            Al = A
        else:
            Al = self.mat(qk, self.vec(u), t)[2]
        du = min_norm_correction(as_floats(Al), self.m, self.n, vel, self.nm.redundant)
        return [a + b for a, b in zip(u, du, strict=True)], A

    def project(self, t, y):
        """The projected state (a fresh vector); self.jac = (it, A at its q) where known."""
        if not self.m:  # no rows: nothing to project
            return y.copy()
        nq, n = self.nq, self.n
        yl = y.tolist()
        q, qk, vel = self.project_q(yl[:nq], yl[nq : nq + n], t)
        u, A = self.project_u(qk, yl[nq : nq + n], t, vel)
        out = np.array(q + u + yl[nq + n :], float)
        self.jac = (out, A)
        return out

    def constraint_jacobian(self, t, y):
        # project_u's A at this very state: the rank monitor need not evaluate it again
        hit, A = self.jac
        return A if hit is y and A is not None else super().constraint_jacobian(t, y)

    def after_step(self, solver):
        solver.y = self.project(solver.t, solver.y)
        self.stats["projections"] += 1
        if self.refresh:
            solver.f = solver.fun(solver.t, solver.y)
        return False
