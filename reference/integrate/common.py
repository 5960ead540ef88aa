"""What every integration method of reference.integrate.driver shares: the named settings, the
errors, the Trajectory it returns, per-model facts, consistent initial states and the Problem base
class the method families (integrate_index1, integrate_projection, integrate_nullspace)
derive from."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NoReturn

import numpy as np
import scipy.integrate as si

from reference.errors import ModelInputError, OffManifoldError, SingularSystemError
from reference.integrate import METHODS  # noqa: F401 - re-exported
from reference.integrate.rk import LeanDOP853
from reference.numeric.model import MANIFOLD_TOL, NumericModel

INTEGRATORS = {
    # scipy's DOP853 with a leaner step (integrate_rk: same tableau, control and steps)
    "DOP853": LeanDOP853,
    "RK45": si.RK45,
    "RK23": si.RK23,
    "Radau": si.Radau,
    "BDF": si.BDF,
    "LSODA": si.LSODA,
}
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
    work: np.ndarray | None = None
    stats: dict = field(default_factory=dict)
    nm: NumericModel | None = field(default=None, repr=False)
    warnings: list = field(default_factory=list)

    @property
    def final_state(self) -> np.ndarray:
        return np.concatenate([self.q[-1], self.u[-1]])

    def residuals(self) -> tuple[np.ndarray, np.ndarray]:
        """Position residuals f(q, t) (N x m_c) and velocity residuals A u + a0 (N x m)."""
        res = self.nm.residuals
        P, V = [], []
        for t, q, u in zip(self.t, self.q, self.u, strict=True):
            pos, vel = res(q, u, float(t))
            P.append(pos)
            V.append(vel)
        return (
            np.array(P, float).reshape(len(self.t), -1),
            np.array(V, float).reshape(len(self.t), -1),
        )

    def max_residual(self) -> dict:
        """Largest |f(q, t)| and |A u + a0| over the outputs (0 where there are no rows)."""
        P, V = self.residuals()
        return {
            "position": float(np.max(np.abs(P))) if P.size else 0.0,
            "velocity": float(np.max(np.abs(V))) if V.size else 0.0,
        }

    def energy(self) -> np.ndarray:
        """K + V at the outputs."""
        en = self.nm.energy
        return np.array(
            [sum(en(q, u, float(t))) for t, q, u in zip(self.t, self.q, self.u, strict=True)]
        )

    def energy_drift(self) -> float | None:
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
        return {
            "method": self.method,
            "nfev": self.nfev,
            "nsteps": self.nsteps,
            "wall_s": self.wall_s,
            "residual_position": r["position"],
            "residual_velocity": r["velocity"],
            "energy_drift": self.energy_drift(),
            "warnings": list(self.warnings),
            **{k: v for k, v in self.stats.items() if isinstance(v, (int, float, str))},
        }


def as_floats(v):
    """A kernel output as a list of floats (it is one already on the Python backend): the
    integrators' arithmetic on a few entries is cheaper on floats than numpy's per-call cost."""
    return v.tolist() if type(v) is np.ndarray else v


# ---- small dense linear algebra ------------------------------------------------------------
def direction_reversed(C: np.ndarray) -> np.ndarray:
    """The rank monitor's test on C = A_k A_(k-1)^T (one m x m matrix or a stack): True where
    an eigenvalue of C has a negative real part, i.e. a row direction of A reversed in the step.

    Up to terms of second order in the turn of A's singular vectors over the step, the
    eigenvalues of C are the products s_i(k) s_i(k-1) of A's signed singular values, so each
    singular value that passed through zero gives one negative eigenvalue. det(C) < 0 sees
    only an odd number of them: the IFToMM A02 chain of N cells loses N ranks at once when it
    lies flat, and for even N the signs cancel. Every reversal det(C) sees, this sees (a
    negative determinant needs a negative real eigenvalue); a subspace of rows turning by more
    than 90 degrees in one step also reads as a reversal, as one row's dot product does.

    Cost: Re(lambda) |x|^2 = x^H (C + C^T) x / 2 for an eigenpair, so where C + C^T is
    positive definite (one Cholesky factorization, as cheap as the determinant) no eigenvalue
    is in the left half-plane. C + C^T = 2 A A^T - O(h^2) fails that only where a singular
    value of A is as small as its change over the step, near a singular pose: only there are
    the eigenvalues computed."""
    try:
        np.linalg.cholesky(C + np.swapaxes(C, -1, -2))
    except np.linalg.LinAlgError:
        return np.linalg.eigvals(C).real.min(axis=-1) < 0.0
    return np.zeros(C.shape[:-2], bool)


def min_norm_correction(
    J: list[float], rows: int, cols: int, r: list[float], redundant: bool = False
) -> list[float]:
    """-J^T (J J^T)^-1 r for a flat row-major J (rows x cols): the minimum-norm step. With
    `redundant` (a model that allows dependent rows) the pseudo-inverse step -J^+ r at
    reference.numeric.redundant's rank tolerance."""
    if redundant:
        from reference.numeric.redundant import RANK_RTOL

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
        from reference.constraints import is_rheonomic

        facts = {
            "rates": model.speeds_are_coordinate_rates,
            "rheonomic": is_rheonomic(model),
            "mc": len(model.configuration_constraints),
        }
        hit = _FACTS[id(model)] = (model, facts)
    return hit[1]


def consistent_initial_state(
    nm: NumericModel, q0, u0, t0: float = 0.0, max_correction: float = math.inf
):
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
            f"Give a consistent initial state."
        )
    return q, u, max(dq, du)


# ---- the right-hand sides ---------------------------------------------------------------
class Problem:
    """What one method integrates: y0, fun(t, y), the full state of y, what follows a step."""

    def __init__(self, nm: NumericModel, energy: bool):
        self.nm = nm
        self.nq, self.n, self.m = nm.nq, nm.n, nm.m
        f = _facts(nm)
        self.rates = f["rates"]
        self.rheonomic = f["rheonomic"]
        self.mc = f["mc"]
        self.work = energy
        self.fr = nm.forward_fast
        # float64 vectors into the C kernels, lists into the generated Python (its fastest
        # input); vectors out of both
        self.arrays = nm.backend != "python"
        self.kin = nm.fast_function("kinematics")
        self.res = nm.fast_function("residuals")
        self.pjac = nm.fast_function("position_jacobian")
        self.mat = nm.fast_function("matrices")
        self.en = nm.fast_function("energy")
        # u = 0 for the position-only calls (f(q, t), df/dq): in the kernels' own input type
        self.zeros_u = np.zeros(self.n) if self.arrays else [0.0] * self.n
        self.stats = {
            "projections": 0,
            "projection_iterations": 0,
            "newton_iterations": 0,
            "partitions": 0,
            "min_pivot_ratio": math.inf,
        }
        # smallest KKT pivot ratio seen in any RHS call (a cell the closures update)
        self.pmin = [math.inf]

    def singular(self, t, q, piv) -> NoReturn:
        msg = self.nm.singular_message(q, piv)
        err = SingularSystemError(f"at t = {t:.6g}: {msg}")
        err.t_singular = float(t)  # where the run stopped (crosscheck.checks.trajectory.horizon)
        raise err

    def forward_failed(self, t, q, exc: Exception) -> NoReturn:
        """A right side that raised: the model's own error keeps its words (an inconsistent
        rank drop, a coordinate singularity), a bare arithmetic error is a singular pose."""
        if isinstance(exc, ModelInputError):
            msg = f"at t = {t:.6g}: {exc}"
            try:
                again = type(exc)(msg)
            except TypeError:  # an error class whose constructor takes more than a message
                again = ModelInputError(msg)
            if isinstance(again, SingularSystemError):
                again.t_singular = float(t)
            raise again from None
        self.singular(t, q, -1.0)

    def qdot(self, q, u, t) -> list[float]:
        """q' = N(q, u, t); a parametrization singularity (3-1-3 angles at sin(theta2) = 0)
        is an error that says so, not a bare ZeroDivisionError."""
        try:
            return self.kin(q, u, t)[0]
        except (ZeroDivisionError, ValueError, OverflowError) as exc:
            raise SingularSystemError(
                f"{self.nm.model.name}: at t = {t:.6g} the kinematic equations q' = N(q, u) are "
                f"singular at q = {np.round(q, 6).tolist()} ({exc}): the coordinates are at a "
                f"singularity of their parametrization"
            ) from None

    def power(self, q, u, t, lam) -> float:
        """Power of the applied loads plus that of rheonomic constraints (-lambda . a0)."""
        P = self.en(q, u, t)[0][2]
        if self.rheonomic and len(lam):
            a0 = self.res(q, self.zeros_u, t)[1]
            P -= sum(l * a for l, a in zip(lam, a0, strict=True))
        return P

    # defaults: the state is (q, u[, W])
    def y0(self, q, u):
        y = list(q) + list(u) + ([0.0] if self.work else [])
        return np.array(y, float)

    def full(self, t, y):
        yl = y.tolist()
        nq, n = self.nq, self.n
        return yl[:nq], yl[nq : nq + n], (yl[nq + n] if self.work else None)

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

    def constraint_jacobian(self, t, y):
        """The position Jacobian df/dq at the state y (flat, row-major)."""
        q = self.full(t, y)[0]
        return self.pjac(np.array(q) if self.arrays else q, self.zeros_u, t)[0]

    def dense_state(self, t, y):
        """A state interpolated by the solver's dense output, as it is recorded."""
        return y

    def settings(self) -> dict:
        return {}
