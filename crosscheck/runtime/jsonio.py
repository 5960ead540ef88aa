"""The JSON encoding of every file the suite writes (results.json, sweep.json, bench.json, the
baseline): numpy arrays and scalars become lists and numbers; NaN and infinities are kept
(as JavaScript's NaN/Infinity, which Python's json reads back) unless ``allow_nan`` is False."""

from __future__ import annotations

import json
from typing import Any


def default(x: Any) -> Any:
    """json.dumps' ``default``: numpy values to plain Python, anything else refused."""
    try:
        import numpy as np

        if isinstance(x, np.ndarray):
            return x.tolist()
        if isinstance(x, np.generic):
            return x.item()
    except ImportError:  # pragma: no cover
        pass
    raise TypeError(f"not JSON serializable: {type(x)}")


def dumps(obj: Any, *, allow_nan: bool = True, indent: int = 2) -> str:
    """The suite's JSON text of obj."""
    return json.dumps(obj, indent=indent, default=default, allow_nan=allow_nan)
