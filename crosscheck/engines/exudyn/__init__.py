"""Exudyn engine (registered as ``exudyn`` in pyproject.toml's ``crosscheck.engines``)."""

from .adapter import ExudynAdapter

__all__ = ["ExudynAdapter"]
