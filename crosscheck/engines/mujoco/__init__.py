"""MuJoCo engine (registered as ``mujoco`` in pyproject.toml's ``crosscheck.engines``)."""

from .adapter import MujocoAdapter

__all__ = ["MujocoAdapter"]
