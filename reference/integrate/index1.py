"""The index-1 family: the acceleration-level equations as they are (index1), and with
Baumgarte's stabilizing terms (baumgarte)."""

from __future__ import annotations

import numpy as np

from reference.errors import ModelInputError
from reference.integrate.common import BAUMGARTE_ALPHA, BAUMGARTE_BETA, Problem, as_floats
from reference.numeric.model import PIVOT_RATIO_MIN


class Index1(Problem):
    """y' = (N(q, u, t), u') from the compiled KKT solve; `offset(q, u, t)`, when given, shifts
    the constraint rows' right side: A u' = b + offset (Baumgarte)."""

    def __init__(self, nm, energy, offset=None):
        super().__init__(nm, energy)
        nq, n, fr = self.nq, self.n, self.fr
        rates, work, singular, arrays = self.rates, self.work, self.singular, self.arrays
        PMIN = PIVOT_RATIO_MIN
        pmin = self.pmin
        size = nq + n + (1 if work else 0)
        nl = n + self.m
        # u' | lambda | ratio written into one buffer the RHS reuses (forward_fast's `out`):
        # no fresh vectors per call; fun's own result stays fresh (the solver keeps it), and
        # fun.into(t, y, out) writes y' into a row the caller owns
        buf = np.empty(nl + 1)
        ud, lam = buf[:n], buf[n:nl]

        def fun_into(t, y, out):
            if arrays:  # views of y straight into the compiled kernel
                q, u = y[:nq], y[nq : nq + n]
            else:  # the Python path is fastest on lists of floats
                yl = y.tolist()
                q, u = yl[:nq], yl[nq : nq + n]
            try:
                fr(q, u, t, offset(q, u, t) if offset else None, buf)
            except (ZeroDivisionError, ValueError) as exc:
                self.forward_failed(t, q, exc)
            piv = buf.item(nl)
            if not piv > PMIN:
                singular(t, q, piv)
            if piv < pmin[0]:
                pmin[0] = piv
            out[:nq] = u if rates else self.qdot(q, u, t)
            out[nq : nq + n] = ud
            if work:
                out[nq + n] = self.power(q, u, t, lam)
            return out

        def fun(t, y):
            return fun_into(t, y, np.empty(size))

        # the stepper's stages write straight into its stage array (integrate_rk)
        fun.into = fun_into
        self.fun = fun


class Baumgarte(Index1):
    def __init__(self, nm, energy, alpha=BAUMGARTE_ALPHA, beta=BAUMGARTE_BETA):
        if alpha < 0 or beta < 0:
            raise ModelInputError(f"Baumgarte gains must be >= 0, got alpha={alpha}, beta={beta}")
        self.alpha, self.beta = float(alpha), float(beta)
        two_a, b2 = 2.0 * self.alpha, self.beta**2

        def offset(q, u, t):
            # A u' = b - 2 alpha (A u + a0) - beta^2 f(q, t), the last on position rows only
            pos, vel = self.res(q, u, t)
            pos, vel, mc = as_floats(pos), as_floats(vel), self.mc
            return [-two_a * v - (b2 * pos[j] if j < mc else 0.0) for j, v in enumerate(vel)]

        super().__init__(nm, energy, offset)

    @classmethod
    def build(cls, nm, energy, opts):
        return cls(nm, energy, opts["alpha"], opts["beta"])

    def settings(self):
        return {"alpha": self.alpha, "beta": self.beta}
