"""Planted errors in one block of an engine's derivatives: what the derivatives records must
catch (tests/test_derivatives_engines.py) and what `crosscheck sensitivity --derivatives`
sizes.

An engine with derivatives of its own (Pinocchio) gets the error in its own Jacobian, before
the maps (EngineJacobians: the block of da/dq, da/dv or da/dtau, or of its constraint forces'):
a sign flipped on one column (a wrong sign in one joint's term), one column dropped (a missing
term), or every entry scaled by (1 + size) (a relative error of that size). An engine that is
differenced gets the same kinds of error in its differenced block, in the reference's terms.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

FAULT_KINDS = ("sign", "drop", "scale")
# the engine's Jacobian blocks and the reference's direction blocks they feed
ENGINE_BLOCKS = {"q": "dq", "v": "du", "tau": "dtau"}


@dataclass(frozen=True)
class Fault:
    """One planted error.

    Parameters
    ----------
    block : {'q', 'v', 'tau'}
        The Jacobian block: with respect to the coordinates, the speeds, the forces.
    target : {'accelerations', 'forces'}
        The derivative of the accelerations or of the constraint forces (multipliers).
    kind : {'sign', 'drop', 'scale'}
        A column's sign flipped, a column zeroed, or every entry times (1 + size).
    size : float
        The relative error of 'scale'.
    column : int
        The column of 'sign' and 'drop'.
    """

    block: str
    target: str = "accelerations"
    kind: str = "scale"
    size: float = 0.0
    column: int = 0

    def __post_init__(self) -> None:
        if self.block not in ENGINE_BLOCKS or self.kind not in FAULT_KINDS:
            raise ValueError(f"fault {self}: block one of q, v, tau; kind one of {FAULT_KINDS}")
        if self.target not in ("accelerations", "forces"):
            raise ValueError(f"fault {self}: target 'accelerations' or 'forces'")

    def hits(self, second: bool, block: str) -> bool:
        """Whether it lies in the derivative of the first (u') or `second` answer (lambda, or
        A^T lambda) along the reference's direction block ('dq', 'du', 'dtau')."""
        return ENGINE_BLOCKS[self.block] == block and second == (self.target == "forces")

    def quantity(self, compared: tuple[str, str]) -> str:
        """The record that must catch it (and only it), the model's answers being
        `compared` (crosscheck.checks.derivatives.engine.compared)."""
        of = compared[1] if self.target == "forces" else compared[0]
        return f"d{of}_{ENGINE_BLOCKS[self.block]}"

    def planted(self, J: np.ndarray) -> np.ndarray:
        """J with the error in it (a copy)."""
        J = np.array(J, float, copy=True)
        if J.size == 0:
            return J
        if self.kind == "scale":
            return J * (1.0 + self.size)
        c = self.column % J.shape[1]
        J[:, c] = -J[:, c] if self.kind == "sign" else 0.0
        return J

    def in_jacobians(self, jac):
        """An EngineJacobians with the error planted in its block."""
        key = "da" if self.target == "accelerations" else "dforces"
        blocks = dict(getattr(jac, key))
        if self.block in blocks:
            blocks[self.block] = self.planted(blocks[self.block])
        return dataclasses.replace(jac, **{key: blocks})
