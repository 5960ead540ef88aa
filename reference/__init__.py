"""Engine-free reference implementation of the unit's multiplier formulations (Kamman, Unit 6)."""

from .errors import ModelInputError  # noqa: F401
from .numeric import NumericModel  # noqa: F401
