"""Pinocchio engine (registered as ``pinocchio`` in pyproject.toml's ``crosscheck.engines``)."""

from crosscheck.engines.pinocchio.adapter import PinocchioAdapter

__all__ = ["PinocchioAdapter"]
