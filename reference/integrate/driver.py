"""Time integration of a NumericModel with constraint stabilization.

`simulate(nm, q0, u0, t_end, method, rtol, atol, integrator="DOP853")` integrates the
acceleration-level ("index-1") equations u' = KKT(q, u, t) of reference.numeric.model with one of
four treatments of the constraints (METHODS). Every method runs scipy's OdeSolver step by step (the
`integrator` class, DOP853 by default) in the same loop, so they differ only in what they do to
the right-hand side or to the accepted step:

``index1``
    No stabilization: y = (q, u), y' = (N(q, u, t), u'). The constraints are only weak
    invariants: f(q, t) and A u + a0 drift at the integrator's error level (Hairer-Wanner II
    Sec. VII.2). Guarantee: none beyond the integrator's tolerance.

``baumgarte``
    The constraint rows A u' = b are replaced by A u' = b - 2 alpha (A u + a0) - beta^2 f(q, t)
    (position rows) and A u' = b - 2 alpha (A u + a0) (motion rows), i.e. the Drake convention
    g'' + 2 alpha g' + beta^2 g = 0: a damped oscillator with omega0 = beta, zeta = alpha / beta.
    Default gains BAUMGARTE_ALPHA = BAUMGARTE_BETA = 10 1/s (critical damping, omega0 = 10 1/s:
    MapleSim's documented range is 1-10; larger omega0 makes an explicit integrator
    step-limited, eigenvalues ~ -omega0). Guarantee: the residual stays bounded at a
    tolerance-dependent level (measured: tests/test_integrate.py); energy is not conserved.
    The stabilizing terms are passed to the compiled forward as an offset of b, so one RHS call
    costs a residuals call more than index1.

``projection``
    Coordinate projection after every accepted step (Hairer-Wanner II Sec. VII.2; Eich 1993
    shows the base method's order is kept): positions by Gauss-Newton on f(q, t) = 0 with
    minimum-norm steps dq = -J^T (J J^T)^-1 f (plain least squares in q: the metric of
    NumericModel.project, well defined where M is singular, as with Euler parameters), then
    velocities by the minimum-norm correction u <- u - A^T (A A^T)^-1 (A u + a0), exact
    because the velocity constraint is linear in u. Guarantee: |f| <= PROJECTION_TOL-level
    (~1e-15 relative) and |A u + a0| at round-off after every step. After projecting,
    the solver's cached derivative (DOP853/RK45/RK23 are FSAL: solver.f is reused as the first
    stage of the next step) is refreshed, solver.f = fun(t, y_projected): one extra RHS call per
    step (measured: +6 % RHS calls, same error as reusing the unprojected derivative, see
    bench.json "skips"), step size and error history untouched (no restart). The dense output of
    a step is taken before projecting (t_eval points are then projected too). Multistep codes
    (BDF, LSODA) keep a history that projecting y alone would corrupt: refused for this method.

``nullspace``
    Coordinate partitioning (Wehage & Haug 1982): QR with column pivoting of the constraint
    Jacobian picks m dependent coordinates/speeds whose block is best conditioned; the ODE is
    integrated in the independent coordinates and speeds only; every RHS call recovers the
    dependent coordinates by Newton on f(q, t) = 0 (warm-started) and the dependent speeds from
    A u + a0 = 0, then takes the independent components of u'. Chosen over an orthonormal
    null-space basis N(q) because the independent speeds are a true local ODE state (a
    QR/SVD basis of null(A) does not vary smoothly with q, so v = N^T u is not one) and because
    f(q, t) = 0 then holds to Newton tolerance at every evaluation. When the dependent block
    degrades (its smallest singular value falls below REPARTITION_RATIO x that of the full
    Jacobian) the integration stops at the accepted step and restarts with a new partition.
    A trial stage whose dependent coordinates do not exist (independent Euler parameters whose
    squares exceed 1) returns NaN, which scipy's RK error test treats as a rejected step.
    Guarantee: constraints at Newton tolerance / round-off at every output. For models whose
    speeds are not coordinate rates only speeds are partitioned (such models here have motion
    constraints only).

Initial state: projected onto the manifold first (NumericModel.project) and checked; a state
that cannot be made consistent raises OffManifoldError with the residual left. The KKT pivot
ratio is checked in every RHS call (index1, projection, nullspace: the compiled forward returns
it) or at every accepted step (baumgarte), and a collapse raises SingularSystemError with t.
Bounded time: `max_wall_s` and `max_steps` raise IntegrationTimeout (never a hang).

Energy: `energy="auto"` adds the accumulated work W of the applied loads and of rheonomic
constraints as an extra ODE state where the model does not declare `energy_conserved` (so
E(t) - E(0) - W(t) is the work-energy balance), and nothing where it does (E(t) - E(0) is
computed after the run from the stored states); `energy="none"` skips the bookkeeping,
`energy="work"` forces it. W is excluded from the error test (atol 1e300) and the other
components' tolerances are scaled by sqrt(N / (N + 1)), so the RMS error norm and hence every
step are those of the run without W: bookkeeping never changes the trajectory.

Stepping: on the C backend the whole DOP853 run of index1, projection and baumgarte runs in
the model's C module (integrate_compiled: within the tolerance of the Python loop, with the
same errors); the Python loop below runs everything else, and any run the C loop declines.
`stepper` chooses.

Layout: integrate_common (settings, errors, Trajectory, the Problem base), one module per
method family (integrate_index1: index1 and baumgarte; integrate_projection;
integrate_nullspace); this module is the driver (simulate) and re-exports the public names.
"""

from __future__ import annotations

import math
import time

import numpy as np

from reference.errors import ModelInputError
from reference.integrate import compiled as stepping
from reference.integrate.common import (  # noqa: F401 - re-exported
    BAUMGARTE_ALPHA,
    BAUMGARTE_BETA,
    INTEGRATORS,
    METHODS,
    NEWTON_MAX_ITER,
    NEWTON_TOL,
    PIVOT_WARN,
    PROJECTABLE,
    PROJECTION_FAIL,
    PROJECTION_MAX_ITER,
    PROJECTION_TOL,
    RANK_TOL,
    REPARTITION_RATIO,
    IntegrationError,
    IntegrationTimeout,
    Trajectory,
    consistent_initial_state,
    direction_reversed,
)
from reference.integrate.index1 import Baumgarte, Index1
from reference.integrate.nullspace import Nullspace
from reference.integrate.projection import Projection
from reference.numeric.model import NumericModel

_PROBLEMS = {
    "index1": Index1,
    "baumgarte": Baumgarte,
    "projection": Projection,
    "nullspace": Nullspace,
}


# ---- the driver -------------------------------------------------------------------------
def _tolerances_with_work(size: int, rtol, atol):
    """Tolerances for y = (..., W): W excluded (its atol 1e300 makes its scale 1e300 whatever
    rtol is), the rest scaled to keep the RMS norm. rtol stays a scalar: Radau takes no vector
    rtol (scipy compares it with numbers), and the error norm is the same either way."""
    c = math.sqrt((size - 1) / size)
    av = np.empty(size)
    av[:-1] = np.asarray(atol, float) * c
    av[-1] = 1e300
    return float(np.max(rtol)) * c, av


def simulate(
    nm: NumericModel,
    q0,
    u0,
    t_end: float,
    method: str = "projection",
    rtol: float = 1e-8,
    atol: float = 1e-10,
    integrator: str = "DOP853",
    t_eval=None,
    *,
    t0: float = 0.0,
    energy: str = "auto",
    alpha: float = BAUMGARTE_ALPHA,
    beta: float = BAUMGARTE_BETA,
    refresh: bool = True,
    max_wall_s: float | None = None,
    max_steps: int | None = None,
    max_correction: float = math.inf,
    first_step: float | None = None,
    max_step: float = math.inf,
    stepper: str | None = None,
) -> Trajectory:
    """Integrate from (q0, u0) at t0 to t_end with one of METHODS (see the module docstring).

    The initial state is projected onto the manifold first (OffManifoldError where that is
    impossible or moves it by more than `max_correction`). `energy`: "auto" | "work" | "none".
    `alpha`, `beta`: Baumgarte gains [1/s]. `refresh`: projection recomputes solver.f after
    projecting (False reuses the unprojected derivative: one RHS call less per step, measured
    in the benchmark). `stepper`: "auto" (the C stepper where the run qualifies,
    integrate_compiled), "c" (an error where it does not) or "python"; default
    CROSSCHECK_STEPPER, else "auto". Raises SingularSystemError (KKT pivots collapse),
    IntegrationError (step-size underflow, projection/Newton failure), IntegrationTimeout
    (bounds exceeded).
    """
    _check_arguments(method, integrator, energy, t0, t_end)
    stepper = stepping.setting(stepper)
    bookkeeping = energy == "work" or (energy == "auto" and not nm.model.energy_conserved)
    t_start = time.perf_counter()
    q, u, corr = consistent_initial_state(nm, q0, u0, t0, max_correction)
    prob = _PROBLEMS[method].build(
        nm, bookkeeping, {"alpha": alpha, "beta": beta, "refresh": refresh}
    )
    prob.stats["ic_correction"] = corr
    opts = {"rtol": rtol, "atol": atol, "max_step": max_step}
    if first_step is not None:
        opts["first_step"] = first_step
    te = None if t_eval is None else np.asarray(t_eval, float)
    if te is not None and (np.any(np.diff(te) < 0) or te[0] < t0 or te[-1] > t_end):
        raise ModelInputError("t_eval must be sorted and inside [t0, t_end]")
    run = _Run(
        nm,
        prob,
        INTEGRATORS[integrator],
        opts,
        (rtol, atol),
        bookkeeping,
        te,
        (max_steps, max_wall_s, t_start),
        (integrator, method),
    )
    run.stepper = stepper
    if te is None:
        run.record(t0, list(q), list(u), 0.0 if bookkeeping else None)
    run.integrate(prob.initial(q, u, t0), t0, t_end)
    settings = {
        "rtol": rtol,
        "atol": atol,
        "integrator": integrator,
        "energy": energy,
        "bookkeeping": bookkeeping,
        "t0": t0,
        "t_end": t_end,
        **prob.settings(),
    }
    return run.trajectory(method, settings, time.perf_counter() - t_start)


def _check_arguments(method, integrator, energy, t0, t_end):
    if method not in _PROBLEMS:
        raise ModelInputError(f"unknown method {method!r}; valid: {', '.join(METHODS)}")
    if integrator not in INTEGRATORS:
        raise ModelInputError(f"unknown integrator {integrator!r}; valid: {', '.join(INTEGRATORS)}")
    _PROBLEMS[method].check_integrator(integrator)
    if energy not in ("auto", "work", "none"):
        raise ModelInputError(f"energy must be 'auto', 'work' or 'none', got {energy!r}")
    if not (t_end > t0):
        raise ModelInputError(f"t_end = {t_end} must be greater than t0 = {t0}")


class _Run:
    """One integration: the solver loop over partitions (one segment except for nullspace),
    the recorded outputs, the bounds."""

    def __init__(self, nm, prob, cls, opts, tols, bookkeeping, te, bounds, what):
        self.nm, self.prob, self.cls, self.opts, self.tols = nm, prob, cls, opts, tols
        self.bookkeeping, self.te, self.k_eval = bookkeeping, te, 0
        self.max_steps, self.max_wall_s, self.t_start = bounds
        self.integrator, self.method = what
        self.T, self.Q, self.U, self.W = [], [], [], []
        self.nfev = self.nsteps = 0
        self.A_last, self.rank_crossings = None, []  # the rank-loss monitor (_orientation)
        self.rows = None  # the independent rows it watches, where rows may be dependent
        self.stepper = "python"  # or "auto" / "c": the compiled stepper (integrate_compiled)

    def record(self, t, qq, uu, W):
        self.T.append(t)
        self.Q.append(qq)
        self.U.append(uu)
        self.W.append(W)

    def _tolerances(self, size):
        if self.bookkeeping:
            # W is carried but not error-controlled (atol 1e300), and the other components'
            # tolerances are scaled by sqrt(N/(N+1)) so the RMS error norm, hence every step
            # size, is the same as without bookkeeping: the work never changes the trajectory.
            self.opts["rtol"], self.opts["atol"] = _tolerances_with_work(size, *self.tols)

    def integrate(self, y, t, t_end):
        prob = self.prob
        if self.A_last is None:
            self._orientation(t, y)
        prob.stats.setdefault("stepper", "python")
        if self.stepper != "python" and stepping.run_compiled(self, y, t, t_end, self.stepper):
            return
        while True:  # one solver per partition
            self._tolerances(len(y))
            solver = self.cls(prob.fun, t, y, t_end, **self.opts)
            restart = False
            while solver.status == "running":
                restart = self._step(solver, t_end)
                if restart and solver.status == "running":
                    break
            self.nfev += solver.nfev
            if not restart or solver.status != "running":
                return
            t = solver.t
            qq, uu, W = prob.full(t, solver.y)
            y = prob.y0(qq, uu, t, W if W is not None else 0.0)

    def _step(self, solver, t_end) -> bool:
        """One accepted step, its outputs and the bounds; True when a restart is due."""
        prob, te = self.prob, self.te
        msg = solver.step()
        if solver.status == "failed":
            self.nfev += solver.nfev
            raise self.failed(solver.t, msg)
        self.nsteps += 1
        if te is not None and self.k_eval < len(te) and te[self.k_eval] <= solver.t:
            dense = solver.dense_output()
            while self.k_eval < len(te) and te[self.k_eval] <= solver.t:
                tk = te[self.k_eval]
                self.record(float(tk), *prob.full(tk, prob.dense_state(tk, dense(tk))))
                self.k_eval += 1
        restart = prob.after_step(solver)
        self._orientation(solver.t, solver.y)
        if te is None:
            self.record(float(solver.t), *prob.full(solver.t, solver.y))
        running = solver.status == "running"
        if self.max_steps is not None and self.nsteps >= self.max_steps and running:
            raise self.out_of_steps(solver.t, t_end)
        if (
            self.max_wall_s is not None
            and running
            and time.perf_counter() - self.t_start > self.max_wall_s
        ):
            raise self.out_of_time(solver.t, t_end)
        return restart

    # the errors of a run that stops early, worded once for both steppers
    def failed(self, t, msg) -> IntegrationError:
        return IntegrationError(
            f"{self.nm.model.name}: {self.integrator} failed at t = {t:.6g} "
            f"with method {self.method}: {msg}"
        )

    def out_of_steps(self, t, t_end) -> IntegrationTimeout:
        return IntegrationTimeout(
            f"{self.nm.model.name}: {self.method} reached max_steps = {self.max_steps} at t = "
            f"{t:.6g} of {t_end}"
        )

    def out_of_time(self, t, t_end) -> IntegrationTimeout:
        return IntegrationTimeout(
            f"{self.nm.model.name}: {self.method} exceeded max_wall_s = {self.max_wall_s} s at "
            f"t = {t:.6g} of {t_end} after {self.nsteps} steps"
        )

    def _orientation(self, t, y):
        """Rank-loss monitor: an eigenvalue of A_k A_{k-1}^T with a negative real part between
        two accepted steps means a singular value of the configuration Jacobian A passed through
        zero (a row direction reversed; common.direction_reversed, which also counts two at
        once): the step crossed a pose where A loses rank, whatever the KKT pivots sampled on
        the way. One Jacobian evaluation per accepted step (the RHS costs several per step)."""
        prob = self.prob
        if not prob.mc:
            return
        A = prob.constraint_jacobian(t, y)
        if self.nm.redundant:  # dependent rows: det(A A^T) is 0 with a round-off sign
            A = self._independent_rows(A)
        last = self.A_last
        if last is not None:
            if len(A) == prob.nq:  # one row: C is the dot product
                crossed = float(np.dot(A, last)) < 0.0
            else:
                Ak = np.asarray(A, float).reshape(-1, prob.nq)
                C = Ak @ np.asarray(last, float).reshape(-1, prob.nq).T
                try:
                    crossed = bool(direction_reversed(C))
                except np.linalg.LinAlgError:  # a non-finite A: no verdict, as a NaN dot
                    crossed = False
            if crossed:
                self.rank_crossings.append(float(t))
        self.A_last = A

    def _independent_rows(self, A):
        """The rows of A that are independent at the run's start (pivoted QR of A^T, at
        reference.numeric.redundant's rank tolerance), kept for the whole run: the monitor then
        watches their span, which loses rank exactly where the mechanism does. Without this
        a model with dependent rows (a planar loop closed by a 3-D connect, tilted) reported
        a "crossing" at about half of its steps (49 in 2 s of tests/data/fourbar_tilted.xml)."""
        prob = self.prob
        Am = np.asarray(A, float).reshape(prob.mc, prob.nq)
        if self.rows is None:
            import scipy.linalg

            from reference.numeric.redundant import RANK_RTOL

            _, R, piv = scipy.linalg.qr(Am.T, mode="economic", pivoting=True)
            d = np.abs(np.diag(R))
            rank = int(np.sum(d > RANK_RTOL * max(float(d[0]) if d.size else 0.0, 1.0)))
            self.rows = np.sort(piv[:rank])
        return Am[self.rows].ravel().tolist()

    def trajectory(self, method, settings, wall) -> Trajectory:
        prob, nm, T = self.prob, self.nm, self.T
        stats = dict(prob.stats)
        stats["min_pivot_ratio"] = min(stats["min_pivot_ratio"], prob.pmin[0])
        if stats["min_pivot_ratio"] == math.inf:
            stats.pop("min_pivot_ratio")
        warnings = []
        if stats.get("min_pivot_ratio", math.inf) < PIVOT_WARN:
            warnings.append(
                f"the KKT pivot ratio fell to {stats['min_pivot_ratio']:.1e} (< {PIVOT_WARN:g}): "
                f"the run passed close to a singular pose (a kinematic singularity or dependent "
                f"rows), where the motion may not be unique and digits are lost"
            )
        if self.rank_crossings:
            stats["rank_crossings_t"] = list(self.rank_crossings)
            warnings.append(
                f"the constraint Jacobian lost rank between accepted steps at t = "
                f"{', '.join(f'{t:.6g}' for t in self.rank_crossings)} (an eigenvalue of "
                f"A_k A_k-1^T with a negative real part: a row direction reversed): the run "
                f"crossed a singular pose, where the continuation is not unique"
            )
        return Trajectory(
            t=np.array(T),
            q=np.array(self.Q, float).reshape(len(T), nm.nq),
            u=np.array(self.U, float).reshape(len(T), nm.n),
            nfev=self.nfev,
            nsteps=self.nsteps,
            wall_s=wall,
            method=method,
            settings=settings,
            work=np.array(self.W, float) if self.bookkeeping else None,
            stats=stats,
            nm=nm,
            warnings=warnings,
        )
