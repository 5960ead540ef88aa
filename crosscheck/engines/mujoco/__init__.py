"""MuJoCo engine (registered as ``mujoco`` in pyproject.toml's ``crosscheck.engines``)."""

from crosscheck.engines.mujoco.adapter import MujocoAdapter

__all__ = ["MujocoAdapter"]
