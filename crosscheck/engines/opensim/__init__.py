"""OpenSim engine (registered as ``opensim`` in pyproject.toml's ``crosscheck.engines``)."""

from crosscheck.engines.opensim.adapter import OpenSimAdapter

__all__ = ["OpenSimAdapter"]
