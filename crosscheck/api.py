"""A Python API for users' own test suites.

    import crosscheck
    records = crosscheck.check("my_mechanism.xml")              # or a .py file, a name, a Model
    crosscheck.assert_passes("my_mechanism.xml", engines=["mujoco"])   # in a pytest test

The records are the same dicts `crosscheck run` writes to results.json (crosscheck.checks.tolerances
.record): model, engine, check, quantity, error, tolerance, passed (None: reported or skipped,
with the reason).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

API_ORIGIN = "Python API (crosscheck.check)"


def _names(model) -> list[str]:
    """The registered model names `model` stands for (files and Model objects registered)."""
    from crosscheck.user_models import load_model_file, register_all
    from reference import models
    from reference.system import Model

    if isinstance(model, Model):
        models.register(model, API_ORIGIN, None)
        return [model.name]
    if isinstance(model, (str, os.PathLike)):
        text = os.fspath(model)
        if Path(text).suffix.lower() in (".xml", ".mjcf", ".py") or Path(text).is_file():
            return register_all(load_model_file(text))
        models.get(text)  # an unknown name: the registry's error lists the valid ones
        return [text]
    raise TypeError(
        f"check() takes a model name, a file path or a reference Model, not {type(model).__name__}"
    )


def check(
    model: str | os.PathLike | object,
    engines: Iterable[str] | None = None,
    *,
    states: int = 6,
    trajectories: bool = False,
    t_end: float = 5.0,
) -> list[dict]:
    """Cross-check a model (a built-in or registered name, an MJCF/Python file, or a Model)
    against the engines (default: every registered engine that imports here) at `states`
    consistent states, and, with trajectories=True, over t_end seconds; returns the records."""
    from crosscheck.commands.arguments import resolve_engines
    from crosscheck.run.checks import run

    names = _names(model)
    # as the CLI: every registered engine that imports here unless some are named
    engine_names = resolve_engines(list(engines) if engines is not None else None)
    records, _series = run(names, engine_names, states, trajectories=trajectories, t_end=t_end)
    return records


def failures(records: list[dict]) -> list[dict]:
    """The failed records, worst first (error over tolerance)."""
    failed = [r for r in records if r["passed"] is False]
    return sorted(
        failed,
        key=lambda r: (
            -(
                r["error"] / r["tolerance"]
                if r["error"] is not None and r["tolerance"]
                else float("inf")
            )
        ),
    )


def message(r: dict) -> str:
    """One record as a line: what failed, by how much, against which bound and why."""
    err = "non-finite" if r["error"] is None else f"{r['error']:.3e}"
    return (
        f"{r['model']} {r['engine']} {r['check']} {r['quantity']}: error {err} > "
        f"{r['tolerance']:.1e} ({r['reason']})"
    )


def assert_passes(model, engines: Iterable[str] | None = None, **kw) -> list[dict]:
    """check(), then raise AssertionError with the worst failed record's message (and the
    count of the others); returns the records when nothing failed."""
    records = check(model, engines, **kw)
    failed = failures(records)
    if failed:
        more = f" (and {len(failed) - 1} more failed records)" if len(failed) > 1 else ""
        raise AssertionError(message(failed[0]) + more)
    return records
