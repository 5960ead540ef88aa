"""Pinocchio engine (registered as ``pinocchio`` in pyproject.toml's ``crosscheck.engines``)."""

from .adapter import PinocchioAdapter

__all__ = ["PinocchioAdapter"]
