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
    "frame_bar": "frame_bar:model",
    "double_pendulum_3d": "double_pendulum:model",
    "top_euler": "top:euler_model",
    "top_cartesian": "top:cartesian_model",
    "exercise_6_1": "exercise_6_1:model",
    "exercise_6_2": "exercise_6_2:model",
    "exercise_6_4": "exercise_6_4:model",
    "knife_edge": "knife_edge:model",
    "pendulum_moving_support": "moving_support:model",
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
