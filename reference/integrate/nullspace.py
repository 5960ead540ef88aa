"""Coordinate partitioning: the independent coordinates integrated, the dependent ones solved
for by Newton, re-partitioned when the dependent block degrades."""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from reference.errors import ModelInputError, SingularSystemError
from reference.integrate.common import (
    NEWTON_MAX_ITER,
    NEWTON_TOL,
    PROJECTION_FAIL,
    RANK_TOL,
    REPARTITION_RATIO,
    IntegrationError,
    Problem,
)
from reference.numeric.model import PIVOT_RATIO_MIN


class Nullspace(Problem):
    """Coordinate partitioning: y = (q_independent, u_independent[, W])."""

    def __init__(self, nm, energy):
        super().__init__(nm, energy)
        if nm.redundant and nm.rank < nm.m:
            raise ModelInputError(
                f"{nm.model.name}: coordinate partitioning needs independent constraint rows "
                f"(rank {nm.rank} < {nm.m} rows here); use the projection, baumgarte or index1 "
                f"method"
            )
        if self.mc and not self.rates:
            raise ModelInputError(
                f"{nm.model.name}: coordinate partitioning of configuration constraints needs "
                f"speeds equal to the coordinate rates"
            )
        self.dep_q: list[int] = []
        self.dep_u: list[int] = []
        self.qd_cache: list[float] = []
        self.qi_last: list[float] = []
        self.J_last = None
        self.stats["rejected_stages"] = 0

    def initial(self, q, u, t0):
        return self.y0(q, u, t0)

    def settings(self):
        return {"dependent_coordinates": self.dep_q, "dependent_speeds": self.dep_u}

    # -- partition --
    def _A(self, q, u, t):
        if self.mc == self.m and self.rates:
            return np.array(self.pjac(q, self.zeros_u, t)[0], float).reshape(self.m, self.n)
        return np.array(self.mat(q, u, t)[2], float).reshape(self.m, self.n)

    def partition(self, q, u, t):
        q, u = list(map(float, q)), list(map(float, u))
        self.stats["partitions"] += 1
        if self.mc:
            J = np.array(self.pjac(q, self.zeros_u, t)[0], float).reshape(self.mc, self.nq)
            _, R, P = sla.qr(J, pivoting=True, mode="economic")
            d = np.abs(np.diag(R))
            if not d[-1] > RANK_TOL * d[0]:
                raise SingularSystemError(
                    f"{self.nm.model.name}: at t = {t:.6g} the configuration constraints' "
                    f"Jacobian is rank deficient (|R_mm / R_11| = {d[-1] / max(d[0], 1e-300):.1e})"
                    f": no dependent coordinates can be chosen at q = {np.round(q, 6).tolist()}"
                )
            self.dep_q = sorted(int(i) for i in P[: self.mc])
        else:
            self.dep_q = []
        if self.m:
            A = self._A(q, u, t)
            if self.mc == self.m and self.rates:
                self.dep_u = list(self.dep_q)
            else:
                _, R, P = sla.qr(A, pivoting=True, mode="economic")
                d = np.abs(np.diag(R))
                if not d[-1] > RANK_TOL * d[0]:
                    raise SingularSystemError(
                        f"{self.nm.model.name}: at t = {t:.6g} the constraint Jacobian A is rank "
                        f"deficient: no dependent speeds can be chosen"
                    )
                self.dep_u = sorted(int(i) for i in P[: self.m])
        else:
            self.dep_u = []
        self.ind_q = [i for i in range(self.nq) if i not in self.dep_q]
        self.ind_u = [i for i in range(self.n) if i not in self.dep_u]
        self.qd_cache = [q[i] for i in self.dep_q]
        self.qi_last = [q[i] for i in self.ind_q]
        self.J_last = None
        self._build_fun()
        y = [q[i] for i in self.ind_q] + [u[i] for i in self.ind_u]
        return y

    def y0(self, q, u, t=0.0, W=0.0):
        y = self.partition(q, u, t)
        return np.array(y + ([W] if self.work else []), float)

    # -- reconstruction --
    def q_of(self, qi, t, strict=True):
        """Full q from the independent coordinates: a tangent predictor from the last
        converged point, then Newton on f(q, t) = 0 in the dependent coordinates. Where Newton
        fails (a trial stage far from the manifold, e.g. independent Euler parameters whose
        squares exceed 1: no solution exists) it raises, or with strict=False returns None."""
        q = [0.0] * self.nq
        for k, i in enumerate(self.ind_q):
            q[i] = qi[k]
        dep = self.dep_q
        if not dep:
            return q
        mc, nq, zu = self.mc, self.nq, self.zeros_u
        qd = list(self.qd_cache)
        J0 = self.J_last
        if J0 is not None:  # dq_d = -J_d^-1 J_i dq_i: first-order accurate start
            dqi = [a - b for a, b in zip(qi, self.qi_last, strict=True)]
            if mc == 1:
                d = J0[dep[0]]
                if d != 0.0:
                    qd[0] -= sum(J0[i] * dv for i, dv in zip(self.ind_q, dqi, strict=True)) / d
            else:
                Jm = np.array(J0, float).reshape(mc, nq)
                step = np.linalg.solve(Jm[:, dep], Jm[:, self.ind_q] @ dqi)
                qd = (np.asarray(qd) - step).tolist()
        for k, i in enumerate(dep):
            q[i] = qd[k]
        tol = NEWTON_TOL * (1.0 + max(abs(v) for v in q))
        for it in range(NEWTON_MAX_ITER + 1):
            pos = self.res(q, zu, t)[0]
            if max(abs(v) for v in pos) <= tol:
                break
            if it == NEWTON_MAX_ITER:
                if max(abs(v) for v in pos) <= PROJECTION_FAIL:
                    break
                if not strict:
                    return None
                raise IntegrationError(
                    f"{self.nm.model.name}: dependent coordinates did not converge at t = "
                    f"{t:.6g} (|f| = {max(map(abs, pos)):.2e}); the partition degenerated"
                )
            J = self.pjac(q, zu, t)[0]
            try:
                if mc == 1:
                    q[dep[0]] -= float(pos[0]) / float(J[dep[0]])  # raises on 0
                else:
                    Jd = np.array(J, float).reshape(mc, nq)[:, dep]
                    dx = np.linalg.solve(Jd, np.asarray(pos, float))
                    for k, i in enumerate(dep):
                        q[i] -= float(dx[k])
            except (ZeroDivisionError, np.linalg.LinAlgError):
                if not strict:
                    return None
                raise SingularSystemError(
                    f"{self.nm.model.name}: dependent-coordinate block singular at t = {t:.6g}"
                ) from None
            self.stats["newton_iterations"] += 1
        self.qd_cache = [q[i] for i in dep]
        self.qi_last = list(qi)
        self.J_last = self.pjac(q, zu, t)[0]
        return q

    def u_of(self, q, ui, t):
        u = [0.0] * self.n
        for k, i in enumerate(self.ind_u):
            u[i] = ui[k]
        if not self.m:
            return u
        r0 = self.res(q, u, t)[1]  # A_i u_i + a0 (dependent speeds still 0)
        dep = self.dep_u
        if self.mc == self.m and self.rates:
            A = self.J_last  # df/dq at this q (set by q_of)
        else:
            A = self.mat(q, u, t)[2]
        if self.m == 1:
            u[dep[0]] = -float(r0[0]) / float(A[dep[0]])
        else:
            Ad = np.array(A, float).reshape(self.m, self.n)[:, dep]
            ud = np.linalg.solve(Ad, -np.asarray(r0, float))
            for k, i in enumerate(dep):
                u[i] = float(ud[k])
        return u

    def _build_fun(self):
        nqi, nui = len(self.ind_q), len(self.ind_u)
        ind_q, ind_u = self.ind_q, self.ind_u
        fr, rates, work = self.fr, self.rates, self.work
        PMIN = PIVOT_RATIO_MIN
        pmin = self.pmin

        size = nqi + nui + (1 if work else 0)

        def fun(t, y):
            yl = y.tolist()
            q = self.q_of(yl[:nqi], t, strict=False)
            if q is None:  # no dependent coordinates for this trial stage: NaN makes scipy's
                self.stats["rejected_stages"] += 1  # RK error test reject the step (h x 0.2)
                return np.full(size, np.nan)
            u = self.u_of(q, yl[nqi : nqi + nui], t)
            try:
                ud, lam, piv = fr(q, u, t)
            except (ZeroDivisionError, ValueError) as exc:
                self.forward_failed(t, q, exc)
            if not piv > PMIN:
                self.singular(t, q, piv)
            if piv < pmin[0]:
                pmin[0] = piv
            qd = u if rates else self.qdot(q, u, t)
            out = [qd[i] for i in ind_q] + [ud[i] for i in ind_u]
            if work:
                out.append(self.power(q, u, t, lam))
            return np.array(out)

        self.fun = fun

    def full(self, t, y):
        yl = y.tolist()
        nqi, nui = len(self.ind_q), len(self.ind_u)
        q = self.q_of(yl[:nqi], t)
        u = self.u_of(q, yl[nqi : nqi + nui], t)
        return q, u, (yl[nqi + nui] if self.work else None)

    def after_step(self, solver) -> bool:
        """True when the dependent block has degraded: restart with a new partition."""
        if not self.m:
            return False
        q, u, _ = self.full(solver.t, solver.y)
        A = self._A(q, u, solver.t)
        s_all = np.linalg.svd(A, compute_uv=False)
        s_dep = np.linalg.svd(A[:, self.dep_u], compute_uv=False)
        return bool(s_dep[-1] < REPARTITION_RATIO * s_all[-1])
