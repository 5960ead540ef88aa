"""The engine registry: every engine is one entry point in the group ``crosscheck.engines``.

The built-in engines register the same way, in pyproject.toml, so an engine's name is written
in exactly one place and a third-party package adds an engine with one line of its own::

    [project.entry-points."crosscheck.engines"]
    myengine = "my_package.crosscheck_adapter:MyAdapter"

The entry point names a class derived from ``EngineAdapter`` (constructed without arguments).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from importlib import metadata
from typing import Any

from crosscheck.engines.base import EngineAdapter
from crosscheck.engines.entry_points import GROUP
from crosscheck.engines.entry_points import entry_points as _entry_points
from reference.errors import ModelInputError


class UnknownEngineError(ModelInputError):
    """An engine name that no installed package registers."""


class EngineImportError(ModelInputError):
    """A registered engine whose package does not import here."""


def engine_names() -> tuple[str, ...]:
    """Every registered engine, in a stable (alphabetical) order."""
    names = tuple(sorted(_entry_points()))
    if not names:
        raise UnknownEngineError(
            f"no engines are registered under the entry-point group {GROUP!r}: the package "
            "metadata is missing; install the suite with `python -m pip install -e .`"
        )
    return names


@cache
def _adapter_class(name: str) -> type[EngineAdapter]:
    eps = _entry_points()
    if name not in eps:
        raise UnknownEngineError(
            f"unknown engine {name!r}; registered: {', '.join(engine_names())}"
        )
    try:
        cls = eps[name].load()
    except ImportError as exc:
        raise EngineImportError(
            f"engine {name!r} is registered but does not import here "
            f"({exc}); install its package or leave it out of --engines"
        ) from None
    if not (isinstance(cls, type) and issubclass(cls, EngineAdapter)):
        raise EngineImportError(
            f"engine {name!r}: entry point {eps[name].value!r} is not an EngineAdapter class"
        )
    return cls


def get_engine(name: str, **options: Any) -> EngineAdapter:
    """A fresh adapter of a registered engine (options go to its constructor)."""
    return _adapter_class(name)(**options)


def available_engines() -> tuple[str, ...]:
    """The registered engines that import here (the default engine set of every command), in
    the adapters' order (``EngineAdapter.rank``, then alphabetical)."""
    out = []
    for name in engine_names():
        try:
            cls = _adapter_class(name)
        except EngineImportError:
            continue
        out.append((cls.rank, name))
    return tuple(name for _rank, name in sorted(out))


def engine_label(name: str) -> str:
    """The engine's name in prose (``EngineAdapter.label``), or its registered name."""
    try:
        return _adapter_class(name).label or name
    except (UnknownEngineError, EngineImportError):
        return name


def engine_distributions() -> tuple[str, ...]:
    """The installed package of every engine that imports here (the keys results' meta
    records versions under), in the engines' order."""
    return tuple(_adapter_class(n).distribution for n in available_engines())


def engine_versions() -> dict[str, str | None]:
    """{distribution: installed version} of every engine that imports here (results' meta)."""
    return {
        _adapter_class(n).distribution: _version(_adapter_class(n).distribution)
        for n in available_engines()
    }


@dataclass(frozen=True)
class EngineStatus:
    name: str
    entry_point: str
    distribution: str | None
    version: str | None
    imports: bool
    error: str | None
    capabilities: dict | None
    models: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        return {
            "name": self.name,
            "entry_point": self.entry_point,
            "distribution": self.distribution,
            "version": self.version,
            "imports": self.imports,
            "error": self.error,
            "capabilities": self.capabilities,
            "models": list(self.models),
        }


def _version(distribution: str) -> str | None:
    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return None


def engine_status() -> list[EngineStatus]:
    """Name, package version, capabilities and import state of every registered engine."""
    out = []
    for name in engine_names():
        ep = _entry_points()[name].value
        try:
            adapter = get_engine(name)
        except EngineImportError as exc:
            out.append(EngineStatus(name, ep, None, None, False, str(exc), None))
            continue
        out.append(
            EngineStatus(
                name,
                ep,
                adapter.distribution,
                _version(adapter.distribution),
                True,
                None,
                adapter.capabilities.as_dict(),
                tuple(adapter.models()),
            )
        )
    return out
