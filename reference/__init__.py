"""Engine-free reference implementation of the unit's multiplier formulations (Kamman, Unit 6).

``NumericModel`` loads on first use: importing ``reference.errors`` (every command's error
type) then does not import sympy, numpy and the code generator (about 1 s), so the command
line can start its worker processes before it pays for them (crosscheck/commands/run.py).
"""

from typing import TYPE_CHECKING

from reference.errors import ModelInputError

if TYPE_CHECKING:
    from reference.numeric.model import NumericModel

__all__ = ["ModelInputError", "NumericModel"]


def __getattr__(name: str):
    if name == "NumericModel":
        from reference.numeric.model import NumericModel

        return NumericModel
    raise AttributeError(f"module 'reference' has no attribute {name!r}")
