"""Exudyn engine (registered as ``exudyn`` in pyproject.toml's ``crosscheck.engines``)."""

from crosscheck.engines.exudyn.adapter import ExudynAdapter

__all__ = ["ExudynAdapter"]
