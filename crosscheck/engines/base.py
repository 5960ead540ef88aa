"""The one small interface every engine adapter implements.

An adapter builds the engine's model of a reference model, maps a consistent reference state to
the engine's state, and returns the engine's answers mapped back to the reference's speeds and
multipliers (same order, same sign and scale as the textbook rows).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Protocol

import numpy as np


class EngineUnsupported(Exception):
    """The engine cannot represent this model; the message is the reason shown in results."""


@dataclass
class EngineForward:
    """Engine answer at one state, in reference coordinates.

    accelerations: u' in the reference model's speed order.
    multipliers: lambda in the reference model's constraint order, or None when the engine
        model has no constraint rows that map to them (a minimal-coordinate tree).
    raw: engine-native quantities worth reporting (iterations, soft-constraint impedance, the
        de-regularized answer, ...), all floats or arrays.
    """

    accelerations: np.ndarray
    multipliers: Optional[np.ndarray]
    raw: dict = field(default_factory=dict)


class EngineModel(Protocol):
    """An engine's model of one reference model with one parameter set."""

    engine: str
    model_name: str

    def to_engine_state(self, q: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Reference (q, u) -> engine (qpos/q, qvel/v)."""

    def from_engine_state(self, qe: np.ndarray, ve: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Engine state -> reference (q, u) (the inverse map, tested both ways)."""

    def forward(self, q: np.ndarray, u: np.ndarray, t: float = 0.0) -> EngineForward:
        """Accelerations and constraint forces at a consistent reference state."""

    def energy(self, q: np.ndarray, u: np.ndarray) -> tuple[float, float]:
        """(kinetic, potential) in the engine, same datum as the reference."""


class EngineAdapter(Protocol):
    name: str

    def build(self, model_name: str, params: dict[str, float]) -> EngineModel:
        """Engine model for a reference model; raises EngineUnsupported with the reason."""
