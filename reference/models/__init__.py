"""Registry of the unit's systems: name -> factory. Drives the CLI and test parametrization."""
from __future__ import annotations

from functools import lru_cache
from importlib import import_module

from ..errors import ModelInputError

# name -> "module:factory"; modules are imported on first use (sympy construction costs time)
_FACTORIES = {
    "pendulum_angle": "pendulum:angle_model",
    "pendulum_xy": "pendulum:xy_model",
    "slider_crank_free": "slider_crank:free_model",
    "slider_crank": "slider_crank:model",
    "slider_crank_split": "slider_crank:split_model",
}


def names() -> list[str]:
    return list(_FACTORIES)


@lru_cache(maxsize=None)
def get(name: str):
    """The Model called `name` (validated), or an error listing the valid names."""
    if name not in _FACTORIES:
        raise ModelInputError(f"unknown model {name!r}; valid: {', '.join(_FACTORIES)}")
    module, factory = _FACTORIES[name].split(":")
    model = getattr(import_module(f"{__name__}.{module}"), factory)()
    model.validate()
    return model
