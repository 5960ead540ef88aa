"""What a built engine model answers, in the reference's coordinates: its answer at one state
(EngineForward, from EngineModel.forward) and a trajectory (EngineTrajectory, from
EngineModel.simulate). Part of the engine contract (crosscheck.engines.base re-exports both).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["EngineForward", "EngineTrajectory"]


@dataclass
class EngineForward:
    """An engine's answer at one state, in the reference's coordinates.

    Parameters
    ----------
    accelerations : ndarray
        u' in the reference model's speed order.
    multipliers : ndarray or None
        lambda in the reference model's constraint order (sign and scale of the textbook's
        rows), or None when the engine model has no constraint forces that map to them.
    raw : dict
        Engine-native quantities worth reporting (residuals, impedance...), floats or arrays.
    multipliers_note : str, optional
        Why ``multipliers`` is None.
    rigid_accelerations, rigid_multipliers : ndarray, optional
        Soft engines only (Capabilities.rigid_recovery): the rigid answer recovered from the
        engine's own soft output.
    iterations : int, optional
        Solver iterations (0: no solve, 1: a direct solve); None if not reported.
    predicted_acceleration_error, predicted_multiplier_error : ndarray, optional
        Soft engines, at a state where the answer is regularized: raw - rigid as the
        regularization predicts it; None where the model has no soft rows (then exact).
    multiplier_rows : tuple of int, optional
        The reference's rows ``multipliers`` answers (None: all); ``multipliers_note`` says why
        the others (a quaternion's unit-norm row) are left out.
    constraint_forces, rigid_constraint_forces, speed_map : ndarray, optional
        J^T lambda of those rows in the engine's speeds v (``rigid_``: from a soft engine's
        recovery) and H with u = H v, to compare with the reference's H^T A^T lambda.
    """

    accelerations: np.ndarray
    multipliers: np.ndarray | None
    raw: dict = field(default_factory=dict)
    multipliers_note: str | None = None
    rigid_accelerations: np.ndarray | None = None
    rigid_multipliers: np.ndarray | None = None
    iterations: int | None = None
    predicted_acceleration_error: np.ndarray | None = None
    predicted_multiplier_error: np.ndarray | None = None
    multiplier_rows: tuple[int, ...] | None = None
    constraint_forces: np.ndarray | None = None
    rigid_constraint_forces: np.ndarray | None = None
    speed_map: np.ndarray | None = None

    @property
    def soft(self) -> bool:
        """Whether the answer is regularized here (compare its rigid recovery, predict the raw
        one)."""
        return (
            self.rigid_accelerations is not None and self.predicted_acceleration_error is not None
        )


@dataclass
class EngineTrajectory:
    """A trajectory computed by the engine, mapped to the reference's (q, u) at the requested
    times.

    Parameters
    ----------
    t : ndarray
        Output times.
    q, u : ndarray
        The reference's coordinates and speeds, one row per output time.
    violation, velocity_violation : ndarray
        The engine-side constraint residuals per output time (zeros without constraints).
    energy : ndarray
        The engine's K + V per output time.
    integrator : str
        The engine integrator used.
    setting : dict
        Its setting (rtol or timestep...).
    wall_s : float, optional
        Time in the engine's stepping (mapping excluded where the engine allows).
    steps : int, optional
        Engine steps or right-hand-side evaluations.
    raw : dict
        Engine-native figures worth reporting.
    failure : str, optional
        None when the integration reached the last time, else why it stopped.
    warnings : dict
        Engine warnings that fired (name -> count): a run with any is not a trajectory of the
        model.
    """

    t: np.ndarray
    q: np.ndarray
    u: np.ndarray
    violation: np.ndarray
    velocity_violation: np.ndarray
    energy: np.ndarray
    integrator: str
    setting: dict = field(default_factory=dict)
    wall_s: float | None = None
    steps: int | None = None
    raw: dict = field(default_factory=dict)
    failure: str | None = None
    warnings: dict = field(default_factory=dict)
