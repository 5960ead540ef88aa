"""Registry of the unit's systems: name -> factory. Drives the CLI and test parametrization."""

from __future__ import annotations

from functools import cache
from importlib import import_module

from reference.errors import ModelInputError

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


# models added at run time (users' files, entry points: crosscheck.user_models), name ->
# (Model, origin, source); `get` finds them beside the built-in ones
_USER: dict = {}


def names() -> list[str]:
    return list(_FACTORIES)


def register(model, origin: str, source=None) -> None:
    """Make a user's Model available to `get` under its name (a built-in name is refused).
    `source`: what the engines may need beside the Model (an MJCF import: the compiled MuJoCo
    model and the state maps, reference.mjcf.loader.MjcfImport)."""
    if model.name in _FACTORIES:
        raise ModelInputError(
            f"model name {model.name!r} ({origin}) is a built-in model's name; rename it"
        )
    model.validate()
    _USER[model.name] = (model, origin, source)


def user_names() -> list[str]:
    return list(_USER)


def origin(name: str) -> str:
    """Where a model comes from: 'built-in' or the user's file / entry point."""
    return _USER[name][1] if name in _USER else "built-in"


def user_source(name: str):
    """The registered source object of a user model (None for built-in models)."""
    return _USER[name][2] if name in _USER else None


def get(name: str):
    """The Model called `name` (validated), or an error listing the valid names."""
    if name in _USER:
        return _USER[name][0]
    return _builtin(name)


@cache
def _builtin(name: str):
    if name not in _FACTORIES:
        valid = list(_FACTORIES) + list(_USER)
        raise ModelInputError(f"unknown model {name!r}; valid: {', '.join(valid)}")
    module, factory = _FACTORIES[name].split(":")
    model = getattr(import_module(f"{__name__}.{module}"), factory)()
    model.validate()
    return model
