"""OpenSim engine (registered as ``opensim`` in pyproject.toml's ``crosscheck.engines``)."""

from .adapter import OpenSimAdapter

__all__ = ["OpenSimAdapter"]
