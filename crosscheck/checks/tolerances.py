"""The named tolerances and error metrics the records are judged by.

Each tolerance is named where its comparison is made, with the reason it has that size; the
records themselves (one per model x formulation x engine x check x quantity, the results.json
contract) are made by crosscheck.checks.records.record.

Error metric: max |engine - reference| over the compared entries and states, divided by
max(max |reference|, 1 SI unit). The floor keeps quantities that are legitimately near zero
(a multiplier of 0 in Exercise 6.6, a state at rest) from turning round-off into huge relative
errors; it makes the figure an absolute error for quantities below 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# ---- named tolerances, each with its reason ------------------------------------------------


@dataclass(frozen=True)
class Tolerance:
    value: float
    reason: str


EXACT_KKT = Tolerance(
    1e-11,
    "an exact answer in the engine (a tree or an unconstrained model, Pinocchio's KKT "
    "solve, or its proximal iterations converged to 1e-12) against the reference's: both "
    "round-off limited (~1e-14 of the largest term); 1e-11 is the suite's bound and "
    "leaves room for the ~1e-12 amplification by small axial inertias (Example 4) and "
    "MuJoCo's 1e-12 light bodies",
)
STATE_MAP = Tolerance(
    1e-12,
    "reference -> engine -> reference state map: trigonometric and quaternion round "
    "trips lose a few ulps",
)
MASS_MATRIX = Tolerance(
    1e-11,
    "M assembled by the engine's CRBA against the reference's symbolic M at the same "
    "coordinates: round-off only",
)
ENERGY = Tolerance(
    1e-11,
    "kinetic plus potential energy from the engine's own routines against the "
    "reference's, same datum: round-off only",
)
FORMULATIONS = Tolerance(
    1e-11,
    "two derivations of the same equations evaluated in different arithmetic order: round-off only",
)


def formulations_tolerance(kappa: float) -> Tolerance:
    """The bar between two formulations' exact KKT solves where cond(K) = `kappa`: each solve
    is backward stable, so each answer may err by ~eps x kappa relative; FORMULATIONS where
    that bound is below it (every textbook model)."""
    bound = float(np.finfo(float).eps) * kappa
    if bound <= FORMULATIONS.value:
        return FORMULATIONS
    return Tolerance(
        bound,
        f"two derivations of the same equations, each solved exactly: a backward-stable "
        f"solve errs by up to eps x cond(K) relative, {bound:.1e} here (cond(K) = "
        f"{kappa:.2g} of the KKT matrix, the largest at the compared states), above the "
        f"round-off bar {FORMULATIONS.value:.0e}",
    )


SOFT_PREDICTION = Tolerance(
    1e-4,
    "MuJoCo's raw (soft) answer against the one predicted from the reference's "
    "accelerations and the documented solref/solimp impedance, never from MuJoCo's "
    "constraint solution (crosscheck/engines/mujoco/soft_prediction.py): they differ by "
    "where MuJoCo's soft solve stops (<= 8.6e-10 scaled), so the judged ratio was <= "
    "8.6e-6 over 200 states of every MuJoCo model with soft rows (PYTHONPATH=$PWD python "
    "benchmarks/mujoco_soft.py predict 200, docs/engines/mujoco.md); 1e-4 "
    "leaves 11x, and a 0.1 % mass error (a miss ~1e-4 of the answer) fails",
)
# Below this predicted (scaled) soft error the solver floor (<= 8.6e-10 measured) is not small
# against the prediction, so the miss is measured against the floor instead: a state where the
# constraint forces are small compared with the force scale predicts a tiny soft error, and
# the ratio would otherwise measure MuJoCo's solver tolerance (seen in a sweep: 6e-5 at a
# predicted error of ~1e-6 on the slider-crank).
SOFT_PREDICTION_FLOOR = 1e-5


def soft_prediction(raw_value, reference, predicted_error) -> tuple[float, float, float]:
    """MuJoCo's raw soft answer against the reference and the error its impedance predicts.

    Returns (miss, raw error, predicted error): the raw error is max |raw - reference| and the
    predicted one max |predicted|, both over max(max |reference|, 1); the miss is
    max |(raw - reference) - predicted| over the same scale, divided by
    max(predicted error, SOFT_PREDICTION_FLOOR)."""
    reference = np.asarray(reference, float)
    predicted_error = np.asarray(predicted_error, float)
    if reference.size == 0:
        return 0.0, 0.0, 0.0
    scale = max(float(np.max(np.abs(reference))), 1.0)
    actual = np.asarray(raw_value, float) - reference
    pred = float(np.max(np.abs(predicted_error))) / scale
    miss = float(np.max(np.abs(actual - predicted_error))) / scale
    return miss / max(pred, SOFT_PREDICTION_FLOOR), float(np.max(np.abs(actual))) / scale, pred


RIGID_RECOVERY = Tolerance(
    1e-9,
    "rigid answer recovered from MuJoCo's own output (f + A^-1 R f): exact up to the "
    "conditioning of A = J M^-1 J^T (the suite's bound for recovered answers)",
)


def scaled_error(value, reference) -> float:
    """max |value - reference| / max(max |reference|, 1)."""
    value = np.asarray(value, float)
    reference = np.asarray(reference, float)
    if value.shape != reference.shape:
        raise ValueError(f"shape mismatch {value.shape} vs {reference.shape}")
    if reference.size == 0:
        return 0.0
    return float(np.max(np.abs(value - reference)) / max(float(np.max(np.abs(reference))), 1.0))


METRICS = {
    "scaled_error": "max |value - reference| / max(max |reference|, 1)",
    "relative_energy_error": "|(K + V)_engine - (K + V)_reference| / max(|K| + |V|, 1)",
    "relative_miss": "max |(raw - reference) - predicted| / max(max |predicted|, 1e-5), "
    "both scaled as scaled_error",
}


class WorstCase:
    """Tracks the largest error of one quantity over several states."""

    def __init__(self):
        self.error = 0.0
        self.state = None
        self.finite = True

    def add(self, err: float, state_index: int):
        if not np.isfinite(err):
            self.finite = False
            self.error, self.state = float("inf"), state_index
        elif self.finite and err >= self.error:
            self.error, self.state = err, state_index
