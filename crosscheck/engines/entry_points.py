"""The engines' entry points, read from the installed packages' metadata without importing any
engine (standard library only): what the workers' server preloads is known before this
process has imported numpy (crosscheck/runtime/workers.py)."""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache
from importlib import metadata

GROUP = "crosscheck.engines"


@cache
def entry_points() -> dict[str, metadata.EntryPoint]:
    """{engine name: its entry point} of every package registering under GROUP."""
    return {ep.name: ep for ep in metadata.entry_points(group=GROUP)}


def engine_modules(names: Sequence[str] | None = None) -> tuple[str, ...]:
    """The module of every registered engine's entry point, or of the registered ones among
    `names` (what worker processes preload), in the engines' alphabetical order."""
    eps = entry_points()
    return tuple(eps[n].module for n in sorted(eps) if names is None or n in names)
