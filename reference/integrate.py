"""Time integration of a NumericModel with constraint stabilization.

`simulate(nm, q0, u0, t_end, method, rtol, atol, integrator="DOP853")` integrates the
acceleration-level ("index-1") equations u' = KKT(q, u, t) of reference.numeric with one of four
treatments of the constraints (METHODS). Every method runs scipy's OdeSolver step by step (the
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
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Optional

import numpy as np
import scipy.integrate as si
import scipy.linalg as sla

from .errors import ModelInputError, OffManifoldError, SingularSystemError
from .numeric import MANIFOLD_TOL, PIVOT_RATIO_MIN, NumericModel

METHODS = ("index1", "baumgarte", "projection", "nullspace")
INTEGRATORS = {"DOP853": si.DOP853, "RK45": si.RK45, "RK23": si.RK23, "Radau": si.Radau,
               "BDF": si.BDF, "LSODA": si.LSODA}
# integrators whose whole internal state is (t, y, f, step size): projection may reset y and f
PROJECTABLE = ("DOP853", "RK45", "RK23", "Radau")

# Baumgarte gains in the Drake convention g'' + 2 alpha g' + beta^2 g = 0 [1/s]: critical
# damping (zeta = alpha / beta = 1) at omega0 = beta = 10 1/s. The constraint error then decays
# like exp(-10 t): fast against the models' motions (periods 0.5-2 s) and slow enough to keep
# the stabilized system non-stiff for DOP853 (eigenvalues ~ -10 next to step sizes of ~1e-2).
BAUMGARTE_ALPHA = 10.0
BAUMGARTE_BETA = 10.0

# Gauss-Newton on f(q, t) = 0 stops at |f| <= PROJECTION_TOL * (1 + |q|_inf): a few ulps of
# entries of size ~1 (the residual of the evaluated expression cannot get below round-off).
PROJECTION_TOL = 4e-15
PROJECTION_MAX_ITER = 8
# A projection that leaves more than this after PROJECTION_MAX_ITER iterations means the step
# left the neighbourhood where Gauss-Newton converges: an error, not a silent inaccuracy.
PROJECTION_FAIL = 1e-9

# coordinate partitioning: Newton tolerance for the dependent coordinates, and the condition
# that triggers a new partition: sigma_min(A_dependent) < REPARTITION_RATIO * sigma_min(A).
# A column-pivoted QR choice keeps sigma_min(A_d) within a small factor of sigma_min(A) (the
# strong rank-revealing bound is 1 / sqrt(1 + m (n - m)): 0.28 for the largest model here), so
# 0.1 re-partitions only after the block has clearly degraded, well before digits are lost.
# A run whose smallest KKT pivot ratio fell below this passed close to a singular pose (a
# kinematic singularity, redundant rows): Trajectory.warnings says so. It is a partial guard
# only: an integrator can step across a pose where A loses rank without sampling it closely.
PIVOT_WARN = 1e-8

NEWTON_TOL = 4e-15
NEWTON_MAX_ITER = 10
REPARTITION_RATIO = 0.1
# pivoted QR of a constraint Jacobian: |R_mm| <= RANK_TOL |R_11| means rank(A) < m (the
# PIVOT_RATIO_MIN of the KKT solve, on the Jacobian's scale)
RANK_TOL = 1e-12


class IntegrationError(ModelInputError):
    """The integrator failed (step size underflow, a projection that does not converge)."""


class IntegrationTimeout(IntegrationError):
    """The run hit its wall-time or step bound before t_end (the stress scenes' guard)."""


# ---- trajectory --------------------------------------------------------------------------
@dataclass
class Trajectory:
    """Result of `simulate`: output times and states (the model's coordinates and speeds).

    Outputs are every accepted step (t_eval None) or the requested times. `work` is the
    accumulated work of loads and rheonomic constraints (None without bookkeeping); `stats`
    counts steps, projections, Newton iterations, partitions and the initial correction.
    """

    t: np.ndarray
    q: np.ndarray
    u: np.ndarray
    nfev: int
    nsteps: int
    wall_s: float
    method: str
    settings: dict
    work: Optional[np.ndarray] = None
    stats: dict = field(default_factory=dict)
    nm: Optional[NumericModel] = field(default=None, repr=False)
    warnings: list = field(default_factory=list)

    @property
    def final_state(self) -> np.ndarray:
        return np.concatenate([self.q[-1], self.u[-1]])

    def residuals(self) -> tuple[np.ndarray, np.ndarray]:
        """Position residuals f(q, t) (N x m_c) and velocity residuals A u + a0 (N x m)."""
        res, p = self.nm._scalar["residuals"], self.nm.p
        P, V = [], []
        for t, q, u in zip(self.t, self.q, self.u):
            pos, vel = res(q.tolist(), u.tolist(), float(t), p)
            P.append(pos)
            V.append(vel)
        return (np.array(P, float).reshape(len(self.t), -1),
                np.array(V, float).reshape(len(self.t), -1))

    def max_residual(self) -> dict:
        """Largest |f(q, t)| and |A u + a0| over the outputs (0 where there are no rows)."""
        P, V = self.residuals()
        return {"position": float(np.max(np.abs(P))) if P.size else 0.0,
                "velocity": float(np.max(np.abs(V))) if V.size else 0.0}

    def energy(self) -> np.ndarray:
        """K + V at the outputs."""
        en, p = self.nm._scalar["energy"], self.nm.p
        return np.array([sum(en(q.tolist(), u.tolist(), float(t), p)[0][:2])
                         for t, q, u in zip(self.t, self.q, self.u)])

    def energy_drift(self) -> Optional[float]:
        """max |E(t) - E(0) - W(t)| over the outputs, relative to max(|E|, K0 + |V0|, 1e-300):
        energy conservation where the model declares it, the work-energy balance where the
        work was integrated, None where neither is available (energy="none" on a model that
        does not conserve energy)."""
        if not self.nm.model.energy_conserved and self.work is None:
            return None
        E = self.energy()
        W = self.work if self.work is not None else 0.0
        dev = np.abs(E - E[0] - W)
        K0, V0 = self.nm.energy(self.q[0], self.u[0], self.t[0])
        scale = max(float(np.max(np.abs(E))), K0 + abs(V0), 1e-300)
        return float(np.max(dev)) / scale

    def summary(self) -> dict:
        r = self.max_residual()
        return {"method": self.method, "nfev": self.nfev, "nsteps": self.nsteps,
                "wall_s": self.wall_s, "residual_position": r["position"],
                "residual_velocity": r["velocity"], "energy_drift": self.energy_drift(),
                "warnings": list(self.warnings),
                **{k: v for k, v in self.stats.items() if isinstance(v, (int, float, str))}}


# ---- small dense linear algebra ------------------------------------------------------------
def _min_norm_correction(J: list[float], rows: int, cols: int, r: list[float],
                         redundant: bool = False) -> list[float]:
    """-J^T (J J^T)^-1 r for a flat row-major J (rows x cols): the minimum-norm step. With
    `redundant` (a model that allows dependent rows) the pseudo-inverse step -J^+ r at
    reference.redundant's rank tolerance."""
    if redundant:
        from .redundant import RANK_RTOL
        Jm = np.array(J, float).reshape(rows, cols)
        return (np.linalg.lstsq(Jm, -np.asarray(r, float), rcond=RANK_RTOL)[0]).tolist()
    if rows == 1:
        jj = sum(v * v for v in J)
        if jj == 0.0:
            raise np.linalg.LinAlgError("zero constraint row")
        s = r[0] / jj
        return [-s * v for v in J]
    Jm = np.array(J, float).reshape(rows, cols)
    y = np.linalg.solve(Jm @ Jm.T, np.asarray(r, float))
    return (-(Jm.T @ y)).tolist()


# ---- per-model facts, computed once ----------------------------------------------------
_FACTS: dict[int, tuple] = {}  # id(model) -> (model, facts): sympy checks run once per model


def _facts(nm: NumericModel) -> dict:
    model = nm.model
    hit = _FACTS.get(id(model))
    if hit is None or hit[0] is not model:
        from .constraints import is_rheonomic
        facts = {"rates": model.speeds_are_coordinate_rates, "rheonomic": is_rheonomic(model),
                 "mc": len(model.configuration_constraints)}
        hit = _FACTS[id(model)] = (model, facts)
    return hit[1]


def consistent_initial_state(nm: NumericModel, q0, u0, t0: float = 0.0,
                             max_correction: float = math.inf):
    """(q, u) on the constraint manifold closest to (q0, u0) (minimum-norm corrections).

    Raises OffManifoldError where no consistent state can be reached from (q0, u0) (Gauss-Newton
    does not converge, or the result still violates the constraints), and where the correction
    exceeds `max_correction` (a start that far off is probably a wrong input, not round-off)."""
    q0 = np.asarray(q0, float)
    u0 = np.asarray(u0, float)
    q, u = nm.project(q0, u0, t0)
    nm.check_consistent(q, u, t0, tol=MANIFOLD_TOL)
    dq = float(np.max(np.abs(q - q0))) if q.size else 0.0
    du = float(np.max(np.abs(u - u0))) if u.size else 0.0
    if max(dq, du) > max_correction:
        raise OffManifoldError(
            f"{nm.model.name}: the initial state is far off the constraint manifold: the "
            f"projection moved q by {dq:.3e} and u by {du:.3e} (allowed {max_correction:.1e}). "
            f"Give a consistent initial state.")
    return q, u, max(dq, du)


# ---- the right-hand sides ---------------------------------------------------------------
class _Problem:
    """What one method integrates: y0, fun(t, y), the full state of y, what follows a step."""

    def __init__(self, nm: NumericModel, energy: bool):
        self.nm = nm
        self.p = nm.p
        self.nq, self.n, self.m = nm.nq, nm.n, nm.m
        f = _facts(nm)
        self.rates = f["rates"]
        self.rheonomic = f["rheonomic"]
        self.mc = f["mc"]
        self.work = energy
        self.fr = nm.forward_raw
        # compiled kernels on the numba backend (arrays in and out), the generated Python on
        # the fallback (lists): every call below works with either
        self.arrays = nm.backend == "numba"
        self.kin = nm.raw_function("kinematics")
        self.res = nm.raw_function("residuals")
        self.pjac = nm.raw_function("position_jacobian")
        self.mat = nm.raw_function("matrices")
        self.en = nm.raw_function("energy")
        self.zeros_u = [0.0] * self.n
        self.stats = {"projections": 0, "projection_iterations": 0, "newton_iterations": 0,
                      "partitions": 0, "min_pivot_ratio": math.inf}
        # smallest KKT pivot ratio seen in any RHS call (a cell the closures update)
        self.pmin = [math.inf]

    def singular(self, t, q, piv):
        msg = self.nm._singular_message(q, piv)
        raise SingularSystemError(f"at t = {t:.6g}: {msg}")

    def qdot(self, q, u, t) -> list[float]:
        """q' = N(q, u, t); a parametrization singularity (3-1-3 angles at sin(theta2) = 0)
        is an error that says so, not a bare ZeroDivisionError."""
        try:
            return self.kin(q, u, t, self.p)[0]
        except (ZeroDivisionError, ValueError, OverflowError) as exc:
            raise SingularSystemError(
                f"{self.nm.model.name}: at t = {t:.6g} the kinematic equations q' = N(q, u) are "
                f"singular at q = {np.round(q, 6).tolist()} ({exc}): the coordinates are at a "
                f"singularity of their parametrization") from None

    def power(self, q, u, t, lam) -> float:
        """Power of the applied loads plus that of rheonomic constraints (-lambda . a0)."""
        P = self.en(q, u, t, self.p)[0][2]
        if self.rheonomic and lam:
            a0 = self.res(q, self.zeros_u, t, self.p)[1]
            P -= sum(l * a for l, a in zip(lam, a0))
        return P

    # defaults: the state is (q, u[, W])
    def y0(self, q, u):
        y = list(q) + list(u) + ([0.0] if self.work else [])
        return np.array(y, float)

    def full(self, t, y):
        yl = y.tolist()
        nq, n = self.nq, self.n
        return yl[:nq], yl[nq:nq + n], (yl[nq + n] if self.work else None)

    def after_step(self, solver) -> bool:
        """Post-process an accepted step; True when the solver must be restarted."""
        return False

    # what `simulate` asks of every method (its registry, _PROBLEMS)
    @classmethod
    def build(cls, nm, energy, opts: dict):
        """The problem for `nm` from simulate's keyword options (each method takes its own)."""
        return cls(nm, energy)

    @staticmethod
    def check_integrator(integrator: str) -> None:
        """Refuse an integrator this method cannot drive (ModelInputError)."""

    def initial(self, q, u, t0):
        return self.y0(q, u)

    def dense_state(self, t, y):
        """A state interpolated by the solver's dense output, as it is recorded."""
        return y

    def settings(self) -> dict:
        return {}


class _Index1(_Problem):
    """y' = (N(q, u, t), u') from the compiled KKT solve; `offset(q, u, t)`, when given, shifts
    the constraint rows' right side: A u' = b + offset (Baumgarte)."""

    def __init__(self, nm, energy, offset=None):
        super().__init__(nm, energy)
        nq, n, fr = self.nq, self.n, self.fr
        rates, work, singular, arrays = self.rates, self.work, self.singular, self.arrays
        PMIN = PIVOT_RATIO_MIN
        pmin = self.pmin
        size = nq + n + (1 if work else 0)

        def fun(t, y):
            if arrays:  # views of y straight into the compiled kernel
                q, u = y[:nq], y[nq:nq + n]
            else:  # the Python path is fastest on lists of floats
                yl = y.tolist()
                q, u = yl[:nq], yl[nq:nq + n]
            try:
                ud, lam, piv = fr(q, u, t, offset(q, u, t) if offset else None)
            except (ZeroDivisionError, ValueError):
                ud, lam, piv = None, None, -1.0
            if not piv > PMIN:
                singular(t, q, piv)
            if piv < pmin[0]:
                pmin[0] = piv
            out = np.empty(size)
            out[:nq] = u if rates else self.qdot(q, u, t)
            out[nq:nq + n] = ud
            if work:
                out[nq + n] = self.power(q, u, t, lam)
            return out

        self.fun = fun


class _Baumgarte(_Index1):
    def __init__(self, nm, energy, alpha=BAUMGARTE_ALPHA, beta=BAUMGARTE_BETA):
        if alpha < 0 or beta < 0:
            raise ModelInputError(f"Baumgarte gains must be >= 0, got alpha={alpha}, beta={beta}")
        self.alpha, self.beta = float(alpha), float(beta)
        two_a, b2 = 2.0 * self.alpha, self.beta ** 2

        def offset(q, u, t):
            # A u' = b - 2 alpha (A u + a0) - beta^2 f(q, t), the last on position rows only
            pos, vel = self.res(q, u, t, self.p)
            mc = self.mc
            return [-two_a * v - (b2 * pos[j] if j < mc else 0.0) for j, v in enumerate(vel)]

        super().__init__(nm, energy, offset)

    @classmethod
    def build(cls, nm, energy, opts):
        return cls(nm, energy, opts["alpha"], opts["beta"])

    def settings(self):
        return {"alpha": self.alpha, "beta": self.beta}


class _Projection(_Index1):
    """index1's RHS; after each accepted step y is projected and solver.f refreshed."""

    def __init__(self, nm, energy, refresh=True):
        super().__init__(nm, energy)
        self.refresh = refresh
        if not self.rates and self.mc:
            raise ModelInputError(
                f"{nm.model.name}: position projection needs speeds equal to the coordinate "
                f"rates (this model maps q' = N(q, u))")

    @classmethod
    def build(cls, nm, energy, opts):
        return cls(nm, energy, opts["refresh"])

    @staticmethod
    def check_integrator(integrator):
        if integrator not in PROJECTABLE:
            raise ModelInputError(
                f"projection needs a one-step integrator whose state is (t, y, f): "
                f"{', '.join(PROJECTABLE)}; {integrator} keeps a multistep history that "
                f"projecting y would corrupt")

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
                    f"Jacobian is rank deficient at q = {np.round(q, 6).tolist()}")
            q = [a + b for a, b in zip(q, dq)]
            self.stats["projection_iterations"] += 1
        if err > PROJECTION_FAIL:
            raise IntegrationError(
                f"{self.nm.model.name}: position projection did not converge at t = {t:.6g} "
                f"(|f| = {err:.2e} after {PROJECTION_MAX_ITER} Gauss-Newton steps): the step "
                f"left the manifold too far; tighten rtol/atol")
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
        return [a + b for a, b in zip(u, du)]

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


class _Nullspace(_Problem):
    """Coordinate partitioning: y = (q_independent, u_independent[, W])."""

    def __init__(self, nm, energy):
        super().__init__(nm, energy)
        if nm.redundant and nm.rank < nm.m:
            raise ModelInputError(
                f"{nm.model.name}: coordinate partitioning needs independent constraint rows "
                f"(rank {nm.rank} < {nm.m} rows here); use the projection, baumgarte or index1 "
                f"method")
        if self.mc and not self.rates:
            raise ModelInputError(
                f"{nm.model.name}: coordinate partitioning of configuration constraints needs "
                f"speeds equal to the coordinate rates")
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
            return np.array(self.pjac(q, self.zeros_u, t, self.p)[0], float).reshape(self.m, self.n)
        return np.array(self.mat(q, u, t, self.p)[2], float).reshape(self.m, self.n)

    def partition(self, q, u, t):
        q, u = list(map(float, q)), list(map(float, u))
        self.stats["partitions"] += 1
        if self.mc:
            J = np.array(self.pjac(q, self.zeros_u, t, self.p)[0], float).reshape(self.mc, self.nq)
            _, R, P = sla.qr(J, pivoting=True, mode="economic")
            d = np.abs(np.diag(R))
            if not d[-1] > RANK_TOL * d[0]:
                raise SingularSystemError(
                    f"{self.nm.model.name}: at t = {t:.6g} the configuration constraints' "
                    f"Jacobian is rank deficient (|R_mm / R_11| = {d[-1] / max(d[0], 1e-300):.1e})"
                    f": no dependent coordinates can be chosen at q = {np.round(q, 6).tolist()}")
            self.dep_q = sorted(int(i) for i in P[:self.mc])
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
                        f"deficient: no dependent speeds can be chosen")
                self.dep_u = sorted(int(i) for i in P[:self.m])
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
        mc, nq, p, zu = self.mc, self.nq, self.p, self.zeros_u
        qd = list(self.qd_cache)
        J0 = self.J_last
        if J0 is not None:  # dq_d = -J_d^-1 J_i dq_i: first-order accurate start
            dqi = [a - b for a, b in zip(qi, self.qi_last)]
            if mc == 1:
                d = J0[dep[0]]
                if d != 0.0:
                    qd[0] -= sum(J0[i] * dv for i, dv in zip(self.ind_q, dqi)) / d
            else:
                Jm = np.array(J0, float).reshape(mc, nq)
                step = np.linalg.solve(Jm[:, dep], Jm[:, self.ind_q] @ dqi)
                qd = (np.asarray(qd) - step).tolist()
        for k, i in enumerate(dep):
            q[i] = qd[k]
        tol = NEWTON_TOL * (1.0 + max(abs(v) for v in q))
        for it in range(NEWTON_MAX_ITER + 1):
            pos = self.res(q, zu, t, p)[0]
            if max(abs(v) for v in pos) <= tol:
                break
            if it == NEWTON_MAX_ITER:
                if max(abs(v) for v in pos) <= PROJECTION_FAIL:
                    break
                if not strict:
                    return None
                raise IntegrationError(
                    f"{self.nm.model.name}: dependent coordinates did not converge at t = "
                    f"{t:.6g} (|f| = {max(map(abs, pos)):.2e}); the partition degenerated")
            J = self.pjac(q, zu, t, p)[0]
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
                    f"{self.nm.model.name}: dependent-coordinate block singular at t = {t:.6g}")
            self.stats["newton_iterations"] += 1
        self.qd_cache = [q[i] for i in dep]
        self.qi_last = list(qi)
        self.J_last = self.pjac(q, zu, t, p)[0]
        return q

    def u_of(self, q, ui, t):
        u = [0.0] * self.n
        for k, i in enumerate(self.ind_u):
            u[i] = ui[k]
        if not self.m:
            return u
        r0 = self.res(q, u, t, self.p)[1]  # A_i u_i + a0 (dependent speeds still 0)
        dep = self.dep_u
        if self.mc == self.m and self.rates:
            A = self.J_last  # df/dq at this q (set by q_of)
        else:
            A = self.mat(q, u, t, self.p)[2]
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
            u = self.u_of(q, yl[nqi:nqi + nui], t)
            try:
                ud, lam, piv = fr(q, u, t)
            except (ZeroDivisionError, ValueError):
                ud, lam, piv = None, None, -1.0
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
        u = self.u_of(q, yl[nqi:nqi + nui], t)
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


_PROBLEMS = {"index1": _Index1, "baumgarte": _Baumgarte, "projection": _Projection,
             "nullspace": _Nullspace}


# ---- the driver -------------------------------------------------------------------------
def _tolerances_with_work(size: int, rtol, atol):
    """Tolerance vectors for y = (..., W): W excluded, the rest scaled to keep the RMS norm."""
    c = math.sqrt((size - 1) / size)
    rv = np.empty(size)
    av = np.empty(size)
    rv[:-1] = np.asarray(rtol, float) * c
    av[:-1] = np.asarray(atol, float) * c
    rv[-1], av[-1] = float(np.max(rtol)), 1e300
    return rv, av


def simulate(nm: NumericModel, q0, u0, t_end: float, method: str = "projection",
             rtol: float = 1e-8, atol: float = 1e-10, integrator: str = "DOP853", t_eval=None,
             *, t0: float = 0.0, energy: str = "auto", alpha: float = BAUMGARTE_ALPHA,
             beta: float = BAUMGARTE_BETA, refresh: bool = True,
             max_wall_s: Optional[float] = None, max_steps: Optional[int] = None,
             max_correction: float = math.inf, first_step: Optional[float] = None,
             max_step: float = math.inf) -> Trajectory:
    """Integrate from (q0, u0) at t0 to t_end with one of METHODS (see the module docstring).

    The initial state is projected onto the manifold first (OffManifoldError where that is
    impossible or moves it by more than `max_correction`). `energy`: "auto" | "work" | "none".
    `alpha`, `beta`: Baumgarte gains [1/s]. `refresh`: projection recomputes solver.f after
    projecting (False reuses the unprojected derivative: one RHS call less per step, measured
    in the benchmark). Raises SingularSystemError (KKT pivots collapse), IntegrationError
    (step-size underflow, projection/Newton failure), IntegrationTimeout (bounds exceeded).
    """
    _check_arguments(method, integrator, energy, t0, t_end)
    bookkeeping = energy == "work" or (energy == "auto" and not nm.model.energy_conserved)
    t_start = time.perf_counter()
    q, u, corr = consistent_initial_state(nm, q0, u0, t0, max_correction)
    prob = _PROBLEMS[method].build(nm, bookkeeping,
                                   {"alpha": alpha, "beta": beta, "refresh": refresh})
    prob.stats["ic_correction"] = corr
    opts = {"rtol": rtol, "atol": atol, "max_step": max_step}
    if first_step is not None:
        opts["first_step"] = first_step
    te = None if t_eval is None else np.asarray(t_eval, float)
    if te is not None and (np.any(np.diff(te) < 0) or te[0] < t0 or te[-1] > t_end):
        raise ModelInputError("t_eval must be sorted and inside [t0, t_end]")
    run = _Run(nm, prob, INTEGRATORS[integrator], opts, (rtol, atol), bookkeeping, te,
               (max_steps, max_wall_s, t_start), (integrator, method))
    if te is None:
        run.record(t0, list(q), list(u), 0.0 if bookkeeping else None)
    run.integrate(prob.initial(q, u, t0), t0, t_end)
    settings = {"rtol": rtol, "atol": atol, "integrator": integrator, "energy": energy,
                "bookkeeping": bookkeeping, "t0": t0, "t_end": t_end, **prob.settings()}
    return run.trajectory(method, settings, time.perf_counter() - t_start)


def _check_arguments(method, integrator, energy, t0, t_end):
    if method not in _PROBLEMS:
        raise ModelInputError(f"unknown method {method!r}; valid: {', '.join(METHODS)}")
    if integrator not in INTEGRATORS:
        raise ModelInputError(
            f"unknown integrator {integrator!r}; valid: {', '.join(INTEGRATORS)}")
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
        prob, te, name = self.prob, self.te, self.nm.model.name
        msg = solver.step()
        if solver.status == "failed":
            self.nfev += solver.nfev
            raise IntegrationError(f"{name}: {self.integrator} failed at t = {solver.t:.6g} "
                                   f"with method {self.method}: {msg}")
        self.nsteps += 1
        if te is not None and self.k_eval < len(te) and te[self.k_eval] <= solver.t:
            dense = solver.dense_output()
            while self.k_eval < len(te) and te[self.k_eval] <= solver.t:
                tk = te[self.k_eval]
                self.record(float(tk), *prob.full(tk, prob.dense_state(tk, dense(tk))))
                self.k_eval += 1
        restart = prob.after_step(solver)
        if te is None:
            self.record(float(solver.t), *prob.full(solver.t, solver.y))
        running = solver.status == "running"
        if self.max_steps is not None and self.nsteps >= self.max_steps and running:
            raise IntegrationTimeout(
                f"{name}: {self.method} reached max_steps = {self.max_steps} at t = "
                f"{solver.t:.6g} of {t_end}")
        if self.max_wall_s is not None and running \
                and time.perf_counter() - self.t_start > self.max_wall_s:
            raise IntegrationTimeout(
                f"{name}: {self.method} exceeded max_wall_s = {self.max_wall_s} s at t = "
                f"{solver.t:.6g} of {t_end} after {self.nsteps} steps")
        return restart

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
                f"rows), where the motion may not be unique and digits are lost")
        return Trajectory(
            t=np.array(T), q=np.array(self.Q, float).reshape(len(T), nm.nq),
            u=np.array(self.U, float).reshape(len(T), nm.n), nfev=self.nfev,
            nsteps=self.nsteps, wall_s=wall, method=method, settings=settings,
            work=np.array(self.W, float) if self.bookkeeping else None, stats=stats, nm=nm,
            warnings=warnings)
