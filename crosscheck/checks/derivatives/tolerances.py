"""What limits each derivative comparison, and the tolerance derived from it.

Every derivatives record is judged at each state against a tolerance computed there from what
limits the comparison; the record keeps the state where error / tolerance is largest, with
that state's error, tolerance and the figures the tolerance came from (docs/tolerances.md,
"Derivative tolerances").

- The reference's exact derivatives solve the KKT matrix K = [[M, -A^T], [A, 0]] once more
  with R's partial derivatives as right sides: their own error is round-off amplified by
  cond(K), far below every bound here.
- An engine's analytical derivatives (Pinocchio) solve the same K with their own right sides:
  the operands carry the error an exact engine answer is allowed (the suite's exact bound,
  ANALYTIC_OPERANDS = 1e-11 relative), and the solve amplifies it by cond(K), measured at the
  state; the maps' differencing adds its estimate (10x, `EngineDerivatives.map_error`). The
  tolerance is capped at ANALYTIC_BAR (1e-8): an analytical derivative less accurate than
  that is not what the routine claims.
- Central differences (every other engine, and Pinocchio's models without a derivative
  routine) err by the stencil's truncation and by the engine's own error magnified by the
  step: (8 (g1 - g-1) - (g2 - g-2)) / 12h turns an error of at most delta in each value into at
  most 1.5 delta / h. delta is the engine's exact tolerance (what its forward answer is held
  to, times the answer's scale); the truncation is measured on the same stencil points with the
  reference's own forward answer, whose derivative is known exactly (the same function on the
  manifold, so the same truncation up to the engine's error, which the round-off term bounds):
  tolerance = DIFFERENCE_SLACK x truncation + 1.5 delta / h, over the derivative's scale.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from crosscheck.checks.tolerances import SOFT_PREDICTION, SOFT_PREDICTION_FLOOR, Tolerance

ANALYTIC_OPERANDS = 1e-11
ANALYTIC_BAR = 1e-8
MAP_SLACK = 10.0
DIFFERENCE_SLACK = 2.0
# the step of the engines' central differences: h = delta^(1/5) balances the fourth-order
# stencil's truncation (~h^4) against the engine's error magnified by 1.5 / h (delta = 1e-11:
# h = 6.3e-3; delta = 1e-9: h = 1.6e-2), within these bounds
STEP_RANGE = (1e-3, 3e-2)
# where a stencil at that step would reach what an MJCF file's monitor watches (a limit, a
# contact), the step is halved until it clears, down to the step at which the round-off bound
# 1.5 delta / h reaches STEP_ROUND_OFF_BAR of the answer's scale: the largest differenced
# tolerance the built-in models get at the balanced step (1.3e-5, docs/tolerances.md) rounded
# down, so a shrunk step judges no looser than those records already do
STEP_ROUND_OFF_BAR = 1e-5
STENCIL = ((1, 8.0), (-1, -8.0), (2, -1.0), (-2, 1.0))  # offsets in h and weights / 12h
ROUND_OFF_GAIN = 1.5  # sum of |weights| / 12
# where MuJoCo's soft solve stops: its raw answer misses the predicted one by <= 8.6e-10 of the
# answer's scale (docs/engines/mujoco.md, benchmarks/mujoco_soft.py predict 200), rounded up
SOFT_SOLVE_MISS = 1e-9


@dataclass(frozen=True)
class Judged:
    """One comparison at one state: error and tolerance (both scaled), the figures behind the
    tolerance, and the reason."""

    error: float
    tolerance: float
    reason: str
    figures: dict

    @property
    def ratio(self) -> float:
        return self.error / self.tolerance if self.tolerance > 0 else float("inf")

    def named(self) -> Tolerance:
        return Tolerance(self.tolerance, self.reason)


def scale(x: np.ndarray) -> float:
    """max(max |x|, 1): the scaled_error metric's denominator."""
    return max(float(np.max(np.abs(x))), 1.0) if np.size(x) else 1.0


def step(delta: float) -> float:
    """The engines' difference step for an answer accurate to delta (relative)."""
    return float(np.clip(delta**0.2, *STEP_RANGE))


def step_floor(delta: float) -> float:
    """The smallest step a stencil is shrunk to (STEP_ROUND_OFF_BAR), at most the balanced one."""
    return min(ROUND_OFF_GAIN * delta / STEP_ROUND_OFF_BAR, step(delta))


def condition(M: np.ndarray, A: np.ndarray) -> float:
    """cond(K) of the KKT matrix [[M, -A_r^T], [A_r, 0]] (2-norm) on A's independent rows
    (A_r = U_r^T A, the rank at reference.numeric.redundant.RANK_RTOL: the matrix the solve
    factors where rows are dependent)."""
    from reference.numeric.redundant import RANK_RTOL

    if A.shape[0]:
        U, s, _vt = np.linalg.svd(A)
        r = int((s > RANK_RTOL * s[0]).sum()) if s[0] > 0 else 0
        A = U[:, :r].T @ A
    m = A.shape[0]
    K = np.block([[M, -A.T], [A, np.zeros((m, m))]])
    return float(np.linalg.cond(K))


def analytic(
    error: float, kappa: float, map_error: float, method: str, engine_kappa: float | None = None
) -> Judged:
    """The tolerance of an engine's analytical derivative at one state (`engine_kappa`: the
    condition number of the engine's own regularized solve, where worse than K's)."""
    worst = max(kappa, engine_kappa or 0.0, 1.0)
    tol = min(ANALYTIC_OPERANDS * worst + MAP_SLACK * map_error, ANALYTIC_BAR)
    which = (
        f"cond(K) = {kappa:.2g} of the KKT matrix"
        if worst == max(kappa, 1.0)
        else f"the condition number {worst:.2g} of the engine's regularized solve "
        f"(||J M^-1 J^T|| / mu on its dependent rows; cond(K) = {kappa:.2g})"
    )
    reason = (
        f"analytical derivatives ({method}) against the reference's exact ones: the "
        f"operands' error ({ANALYTIC_OPERANDS:.0e}, the suite's exact bound) amplified by "
        f"{which}, plus {MAP_SLACK:g}x the maps' differencing estimate {map_error:.1e}; "
        f"capped at the {ANALYTIC_BAR:.0e} bar"
    )
    figures = {"condition_number": worst, "map_error": map_error, "method": method}
    return Judged(error, tol, reason, figures)


def differenced(
    error: float,
    truncation: float,
    delta: float,
    h: float,
    value_scale: float,
    dscale: float,
    shrunk: str = "",
) -> Judged:
    """The tolerance of an engine's central differences at one state: the measured
    truncation (absolute), the round-off bound 1.5 delta value_scale / h, over the
    derivative's scale dscale (`shrunk`: why h is below the balanced step, said)."""
    round_off = ROUND_OFF_GAIN * delta * value_scale / h
    tol = (DIFFERENCE_SLACK * truncation + round_off) / dscale
    reason = (
        f"central differences (fourth order, step {h:.1e}{shrunk}) of the engine's answer along "
        f"consistent directions against the reference's exact derivatives: "
        f"{DIFFERENCE_SLACK:g}x the stencil's truncation measured with the reference's answer "
        f"on the same states ({truncation / dscale:.1e}) plus the engine's error bound "
        f"{delta:.0e} magnified by 1.5/h ({round_off / dscale:.1e})"
    )
    figures = {
        "step": h,
        "truncation_estimate": truncation / dscale,
        "round_off_estimate": round_off / dscale,
    }
    return Judged(error, tol, reason, figures)


def soft(
    miss: float, h: float, value_scale: float, dscale: float, predicted: float, shrunk: str = ""
) -> Judged:
    """The tolerance of a soft engine's raw derivatives against the predicted ones (metric
    relative_miss): SOFT_PREDICTION, as for the answer itself, plus the soft solve's own miss
    (SOFT_SOLVE_MISS of the answer's scale) magnified by the stencil's 1.5/h, in the same
    units (over the derivative's scale and the predicted effect, at least its floor)."""
    noise = ROUND_OFF_GAIN * SOFT_SOLVE_MISS * value_scale / h / dscale
    noise /= max(predicted, SOFT_PREDICTION_FLOOR)
    tol = SOFT_PREDICTION.value + noise
    reason = (
        f"the derivative of the engine's raw soft answer (central differences, step {h:.1e}"
        f"{shrunk}) "
        f"against the derivative of the raw answer its documented impedance predicts from "
        f"the reference's: {SOFT_PREDICTION.value:.0e} of the predicted soft effect, as for the "
        f"answer itself, plus the soft solve's own miss ({SOFT_SOLVE_MISS:.0e} of the answer) "
        f"magnified by 1.5/h ({noise:.1e})"
    )
    return Judged(miss, tol, reason, {"step": h, "round_off_estimate": noise})
