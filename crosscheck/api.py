"""A Python API for users' own test suites.

    import crosscheck
    records = crosscheck.check("my_mechanism.xml")              # or a .py file, a name, a Model
    crosscheck.assert_passes("my_mechanism.xml", engines=["mujoco"])   # in a pytest test

The records are the same dicts `crosscheck run` writes to results.json (docs/results.md):
model, engine, check, quantity, error, tolerance, passed (None: reported or skipped, with the
reason).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

# the largest `states` the API takes: the CLI's --states bound
from crosscheck.commands.arguments import MAX_STATES

API_ORIGIN = "Python API (crosscheck.check)"


def _names(model: object) -> list[str]:
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
    engines: Iterable[str] | str | None = None,
    *,
    states: int = 6,
    trajectories: bool = False,
    t_end: float = 5.0,
) -> list[dict]:
    """Cross-check a model against the engines, as `crosscheck run` does.

    Parameters
    ----------
    model : str, path-like or reference.system.Model
        A built-in or registered model name, an MJCF (.xml) or Python (.py) model file, or a
        Model object.
    engines : iterable of str, or str, optional
        Engine names (a string is read as comma-separated names, as on the command line).
        Default: every registered engine that imports here.
    states : int, default 6
        Consistent states per model for the instantaneous checks (1 to MAX_STATES).
    trajectories : bool, default False
        Also compare trajectories over `t_end` seconds.
    t_end : float, default 5.0
        Trajectory horizon in seconds: finite, > 0 and at most the CLI's --t-end bound.

    Returns
    -------
    list of dict
        The records, as in results.json (docs/results.md).

    Raises
    ------
    reference.errors.ModelInputError
        Every bad argument at once (an unknown model or engine, a count or horizon out of
        range), before any work.
    TypeError
        `model` is none of the accepted kinds.
    """
    from crosscheck.commands.arguments import resolve_engines
    from crosscheck.run.checks import run

    engine_list = _engine_names(engines)
    _check_numbers(states, t_end)
    names = _names(model)
    # as the CLI: every registered engine that imports here unless some are named
    engine_names = resolve_engines(engine_list)
    records, _series = run(names, engine_names, states, trajectories=trajectories, t_end=t_end)
    return records


def _engine_names(engines: Iterable[str] | str | None) -> list[str] | None:
    """Engine names from an iterable, or a string read as comma-separated names."""
    if engines is None:
        return None
    names = (
        [n.strip() for n in engines.split(",")]
        if isinstance(engines, str)
        else [str(e).strip() for e in engines]
    )
    if not names or "" in names:
        from reference.errors import ModelInputError

        raise ModelInputError(
            f"check(): engines={engines!r} names no engine or an empty one; give engine "
            f"names (a list, or one comma-separated string), or None for every engine"
        )
    return names


def _check_numbers(states: object, t_end: Any) -> None:
    """Every problem with the counts and the horizon, raised once."""
    import math

    from crosscheck.commands.arguments import MAX_T_END
    from reference.errors import ModelInputError

    problems = []
    if isinstance(states, bool) or not isinstance(states, int) or not 1 <= states <= MAX_STATES:
        problems.append(f"states={states!r}: give a whole number from 1 to {MAX_STATES}")
    try:
        t = float(t_end)
    except (TypeError, ValueError):
        t = math.nan
    if not (math.isfinite(t) and 0 < t <= MAX_T_END):
        problems.append(
            f"t_end={t_end!r}: give a finite horizon in seconds, > 0 and <= {MAX_T_END:g}"
        )
    if problems:
        raise ModelInputError("check(): " + "; ".join(problems))


def failures(records: list[dict]) -> list[dict]:
    """The failed records, worst first.

    Parameters
    ----------
    records : list of dict
        Records as `check` returns them.

    Returns
    -------
    list of dict
        The records with ``passed`` False, by error over tolerance, largest first (a
        non-finite error first of all).
    """
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
    """One failed record as a line: what failed, by how much, against which bound and why.

    Parameters
    ----------
    r : dict
        A record with a tolerance (not a skip).

    Returns
    -------
    str
    """
    err = "non-finite" if r["error"] is None else f"{r['error']:.3e}"
    return (
        f"{r['model']} {r['engine']} {r['check']} {r['quantity']}: error {err} > "
        f"{r['tolerance']:.1e} ({r['reason']})"
    )


def assert_passes(
    model: str | os.PathLike | object, engines: Iterable[str] | str | None = None, **kw: Any
) -> list[dict]:
    """`check`, for a test: fail with the worst failed record's message.

    Parameters
    ----------
    model, engines, **kw
        As for `check`.

    Returns
    -------
    list of dict
        The records, when none failed.

    Raises
    ------
    AssertionError
        Some record failed: the message is the worst one's, with the count of the others.
    reference.errors.ModelInputError
        As for `check`.
    """
    records = check(model, engines, **kw)
    failed = failures(records)
    if failed:
        more = f" (and {len(failed) - 1} more failed records)" if len(failed) > 1 else ""
        raise AssertionError(message(failed[0]) + more)
    return records
