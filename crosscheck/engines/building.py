"""Building engine models, what every adapter would otherwise write again: TableAdapter
(models, variants and build from a table of engine models, through lookup_builder and
resolve_params) and check_state (a reference state's sizes and finiteness, as the reference
checks them)."""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from crosscheck.engines.base import EngineAdapter, EngineModel, EngineUnsupported

__all__ = [
    "ModelTable",
    "TableAdapter",
    "check_state",
    "is_user_model",
    "lookup_builder",
    "resolve_params",
    "single_variant",
    "table_variants",
]

# An adapter's models: reference model -> the engine model's builder, or {variant: builder}
# for several engine models of one reference model (the first variant is build's default).
ModelTable = dict[str, Any]


def resolve_params(model_name: str, params: dict | None) -> dict[str, float]:
    """The reference model's parameter values (defaults filled in, names and signs checked)."""
    from reference.models import get
    from reference.numeric.model import resolve_parameters

    return resolve_parameters(get(model_name), params)


def is_user_model(table: ModelTable, model_name: str) -> bool:
    """A model loaded from a user's file (reference.models.user_names), not in the table."""
    from reference.models import user_names

    return model_name not in table and model_name in user_names()


def table_variants(table: ModelTable, model_name: str) -> tuple[str | None, ...]:
    """The variants of a model in an adapter's table; (None,) for a single engine model."""
    entry = table.get(model_name)
    return tuple(entry) if isinstance(entry, dict) else (None,)


def single_variant(engine: str, model_name: str, variant: str | None, what: str = "") -> None:
    """Refuse a variant for a model with one engine model (``what`` names it, e.g. a user's
    file; default the engine)."""
    if variant is not None:
        raise EngineUnsupported(f"{model_name}: {what or engine} has a single variant here")


def lookup_builder(
    engine: str,
    table: ModelTable,
    model_name: str,
    variant: str | None,
    unsupported: dict[str, str] | None = None,
) -> Any:
    """The builder of one variant of a model in an adapter's table (the default variant when
    ``variant`` is None); EngineUnsupported with the reason, or with the valid names."""
    if unsupported and model_name in unsupported:
        raise EngineUnsupported(unsupported[model_name])
    if model_name not in table:
        raise EngineUnsupported(
            f"{engine} adapter has no model {model_name!r} (mapped: {', '.join(table)})"
        )
    entry = table[model_name]
    if not isinstance(entry, dict):
        single_variant(engine, model_name, variant)
        return entry
    key = variant or next(iter(entry))
    if key not in entry:
        raise EngineUnsupported(
            f"{model_name}: unknown {engine} variant {key!r}; valid: {', '.join(entry)}"
        )
    return entry[key]


def check_state(
    where: str, nq: int, n: int, q: Any, u: Any = None, t: float = 0.0
) -> tuple[np.ndarray, np.ndarray | None]:
    """A reference state's sizes and finiteness, checked as the reference checks them;
    ``where`` names the model and engine in the error. Returns (q, u) as flat float arrays."""
    from reference.errors import ModelInputError

    q = np.asarray(q, dtype=float).reshape(-1)
    if q.size != nq:
        raise ModelInputError(f"{where}: expected {nq} coordinates, got {q.size}")
    if u is not None:
        u = np.asarray(u, dtype=float).reshape(-1)
        if u.size != n:
            raise ModelInputError(f"{where}: expected {n} speeds, got {u.size}")
    if not (np.all(np.isfinite(q)) and (u is None or np.all(np.isfinite(u))) and math.isfinite(t)):
        raise ModelInputError(f"{where}: state contains NaN or infinite values")
    return q, u


class TableAdapter(EngineAdapter):
    """An adapter whose engine models are one ModelTable: ``model_table`` (reference model ->
    builder(model_name, params), or {variant: builder}), ``refused`` (reference model -> why
    the engine cannot express it) and ``user_files`` (it also builds the models loaded from
    users' files; its build() then handles them before the table)."""

    model_table: ClassVar[ModelTable] = {}
    refused: ClassVar[dict[str, str]] = {}
    user_files: ClassVar[bool] = False

    def models(self) -> tuple[str, ...]:
        from reference.models import user_names

        return (*self.model_table, *(user_names() if self.user_files else ()))

    def unsupported(self) -> dict[str, str]:
        return dict(self.refused)

    def variants(self, model_name: str) -> tuple[str | None, ...]:
        return table_variants(self.model_table, model_name)

    def build(
        self, model_name: str, params: dict[str, float] | None = None, variant: str | None = None
    ) -> EngineModel:
        builder = lookup_builder(self.name, self.model_table, model_name, variant, self.refused)
        model: EngineModel = builder(model_name, resolve_params(model_name, params))
        return model
