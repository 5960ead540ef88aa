"""scipy's DOP853 (Dormand-Prince 8(5,3), Hairer-Norsett-Wanner I Sec. II.10) with a leaner step.

`LeanDOP853` keeps scipy's tableau, its error estimate (the 5th- and 3rd-order estimators
combined as in Hairer's code), its step-size control (SAFETY 0.9, factors 0.2..10, no growth
after a rejection), its initial step and its dense output, so a run takes the same steps as
scipy's DOP853 up to the round-off of the stage sums. What it drops is the Python around them:
scipy's rk_step calls the right side through two wrappers (nfev counting, np.asarray) and forms
each stage as np.dot(K[:s].T, a[:s]) * h (slice, transpose, slice, product, scaling); here each
stage is one row-vector product (h a_s) . K[:s] on views made once, and the right side is
called directly. Measured (benchmarks/reference_speed.md, "The compiled stepper"): scipy's
stepping cost ~10 us per right-side call on the slider-crank, as much as the right side itself.
"""

from __future__ import annotations

import numpy as np
import scipy.integrate as si

# scipy's own step-size control (scipy.integrate._ivp.rk): kept, so the steps are scipy's
SAFETY, MIN_FACTOR, MAX_FACTOR = 0.9, 0.2, 10.0


class LeanDOP853(si.DOP853):
    """scipy.integrate.DOP853 with the stage loop written out (see the module docstring)."""

    def __init__(self, fun, t0, y0, t_bound, **options):
        super().__init__(fun, t0, y0, t_bound, **options)
        self._rhs = fun  # the caller's right side: float64 vectors of len(y) out
        ns = self.n_stages
        # per stage: its c, its row of h A (a view into _hA, which each step fills with h times
        # the tableau in one product) and the view K[:s] it combines: ndarray.dot on ready
        # views, no slicing and no scaling per stage (numpy's per-call cost dominates here)
        K = self.K
        self._A = np.ascontiguousarray(self.A[1:ns, : ns - 1])
        self._hA = np.empty_like(self._A)
        self._stages = [(float(self.C[s]), self._hA[s - 1, :s], K[:s], K[s]) for s in range(1, ns)]
        # a right side with `into(t, y, out)` fills each stage's row of K itself (no fresh
        # vector and no copy per stage); any other is called and its result copied in
        self._into = getattr(fun, "into", None)
        self._b, self._Kb = np.ascontiguousarray(self.B), K[:-1]
        self._e53 = np.vstack([self.E5, self.E3])  # both error estimators in one product

    def _stage_sweep(self, t, y, h):
        """The 12 stages and the new state: (y_new, f_new), K filled as scipy's rk_step."""
        K, rhs = self.K, self._rhs
        K[0] = self.f
        np.multiply(self._A, h, out=self._hA)
        into = self._into
        if into is not None:
            for c, ha, Ks, Kr in self._stages:
                into(t + c * h, y + ha.dot(Ks), Kr)
        else:
            for c, ha, Ks, Kr in self._stages:
                Kr[:] = rhs(t + c * h, y + ha.dot(Ks))
        y_new = y + h * self._b.dot(self._Kb)
        f_new = np.asarray(rhs(t + h, y_new), dtype=float)
        K[-1] = f_new
        self.nfev += self.n_stages
        return y_new, f_new

    def _error_norm(self, h, y, y_new) -> float:
        """scipy's DOP853 error norm (_estimate_error_norm), same formula."""
        scale = self.atol + np.maximum(np.abs(y), np.abs(y_new)) * self.rtol
        r = self._e53.dot(self.K) / scale
        e5, e3 = (r * r).sum(axis=1).tolist()
        if e5 == 0.0 and e3 == 0.0:
            return 0.0
        return abs(h) * e5 / ((e5 + 0.01 * e3) * self.n) ** 0.5

    def _step_impl(self):
        t, y = self.t, self.y
        min_step = 10 * abs(float(np.nextafter(t, self.direction * np.inf)) - t)
        h_abs = min(max(self.h_abs, min_step), self.max_step)
        rejected = False
        while True:
            if h_abs < min_step:
                return False, self.TOO_SMALL_STEP
            h = h_abs * self.direction
            t_new = t + h
            if self.direction * (t_new - self.t_bound) > 0:
                t_new = self.t_bound
            h = t_new - t
            h_abs = abs(h)
            y_new, f_new = self._stage_sweep(t, y, h)
            err = self._error_norm(h, y, y_new)
            if err < 1.0:
                factor = (
                    MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * err**self.error_exponent)
                )
                h_abs *= min(1.0, factor) if rejected else factor
                break
            h_abs *= max(MIN_FACTOR, SAFETY * err**self.error_exponent)
            rejected = True
        self.h_previous, self.y_old = h, y
        self.t, self.y, self.h_abs, self.f = t_new, y_new, h_abs, f_new
        return True, None
