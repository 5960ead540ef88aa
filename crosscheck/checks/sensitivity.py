"""What size of error the suite would catch: the smallest relative change of one parameter in
one engine's model that makes a check fail.

For each model, engine and parameter, the parameter of the ENGINE's model alone is multiplied by
(1 + rel) while the reference keeps its value, and the instantaneous comparison at the run's
consistent states is repeated (or, for a parameter that changes the engine's model but no
instantaneous figure, the trajectory comparison: trajectory_threshold below).
`threshold` searches the decades rel = 1e-13 ... 1e-1 for the smallest one that is caught: it
checks the largest first (a parameter not caught at 10 % is reported as such, with the reason)
and then bisects the decades, assuming that a change caught at one size is caught at every
larger size (the comparisons' errors grow with the change). The search costs at most
1 + ceil(log2(13)) = 5 comparisons per parameter.

The parameters are the model's generic set (reference.generic), not the defaults: a load that is
0 by default cannot be perturbed relatively, and equal defaults could hide one another (a
trajectory search runs at the textbook defaults, as `crosscheck run`'s trajectories do).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass

DECADES = tuple(range(-13, 0))  # rel = 10**k for k in DECADES
# "caught" means the suite's own verdict: some instantaneous record fails its tolerance
STATES = 3


@dataclass(frozen=True)
class Threshold:
    """The outcome for one model x engine x parameter.

    caught_at: smallest decade caught (a relative change), or None when nothing up to 10 % is;
    not_caught_below: the largest decade checked and not caught (None when even 1e-13 is);
    failing_check: the record that caught it at caught_at ("model/engine/check/quantity");
    reason: why nothing caught it, or why the parameter was not searched, or how it was
    searched when not by the instantaneous comparison;
    comparison: the comparison the search repeated ("instantaneous" or "trajectory").
    """

    model: str
    engine: str
    parameter: str
    caught_at: float | None
    not_caught_below: float | None
    failing_check: str = ""
    reason: str = ""
    evaluations: int = 0
    comparison: str = "instantaneous"

    def to_json(self) -> dict:
        return asdict(self)


# evaluate(rel) -> name of the first failing record ("" when every record passed)
Evaluate = Callable[[float], str]


def threshold(
    evaluate: Evaluate, decades: tuple[int, ...] = DECADES
) -> tuple[int | None, int | None, str, int]:
    """(caught decade k, largest decade not caught, failing record at k, evaluations) over
    `decades` (ascending; the largest is checked first)."""
    calls = 0

    def failing(k: int) -> str:
        nonlocal calls
        calls += 1
        return evaluate(10.0**k)

    top = failing(decades[-1])
    if not top:
        return None, decades[-1], "", calls
    lo, hi, hi_fail = -1, len(decades) - 1, top  # decades[hi] caught; decades[lo] not (or none)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        name = failing(decades[mid])
        if name:
            hi, hi_fail = mid, name
        else:
            lo = mid
    return decades[hi], (decades[lo] if lo >= 0 else None), hi_fail, calls


def search(
    model: str,
    engine: str,
    parameter: str,
    evaluate: Evaluate,
    unused_reason: str = "",
    largest: int = DECADES[-1],
    comparison: str = "instantaneous",
    how: str = "",
) -> Threshold:
    """The threshold of one parameter; `unused_reason` marks a parameter the engine's model does
    not contain (nothing is searched, the reason is reported); `largest` is the largest decade
    the engine accepts as a change (a principal inertia at the edge of the triangle
    inequality admits only small ones); `comparison` names what `evaluate` repeats, `how`
    (kept as the reason, caught or not) how it was run."""
    if unused_reason:
        return Threshold(
            model, engine, parameter, None, None, reason=unused_reason, comparison=comparison
        )
    k, below, name, calls = threshold(evaluate, tuple(d for d in DECADES if d <= largest))
    if k is None:
        why = (
            "the compared quantities do not depend on this parameter at these states"
            if comparison == "instantaneous"
            else how
        )
        return Threshold(
            model,
            engine,
            parameter,
            None,
            10.0**below,
            evaluations=calls,
            reason=f"no {comparison} check failed for a change of up to {10.0**below:.0e}: {why}",
            comparison=comparison,
        )
    return Threshold(
        model,
        engine,
        parameter,
        10.0**k,
        None if below is None else 10.0**below,
        failing_check=name,
        reason=how,
        evaluations=calls,
        comparison=comparison,
    )


def log_decade(value: float | None) -> int | None:
    return None if value is None else round(math.log10(value))


# ---- one engine's thresholds, by the comparisons of `crosscheck run` ----------------------


def _engine_figures(name, nm, states, adapter, perturb) -> tuple[str, dict[str, float]]:
    """(first failing record, every record's error) of one engine at the states."""
    from crosscheck.checks.instantaneous import (
        engine_records,  # the one comparison of `crosscheck run`
    )
    from crosscheck.checks.perturb import perturbed

    params = perturbed(name, nm.params, perturb)
    recs = [
        r
        for variant in adapter.variants(name)
        for r in engine_records(name, nm, states, adapter, params, variant)
    ]
    figures = {f"{r['check']}/{r['quantity']}": r["error"] for r in recs if r["error"] is not None}
    return _first_failing(recs, adapter.name), figures


def _first_failing(recs, engine: str) -> str:
    """ "model/engine/check/quantity" of the engine's first failing record, or ""."""
    return next(
        (
            f"{r['model']}/{r['engine']}/{r['check']}/{r['quantity']}"
            for r in recs
            if r["engine"] == engine and r["passed"] is False
        ),
        "",
    )


def engine_thresholds(name: str, engine: str, n_states: int = STATES) -> list[Threshold]:
    """One threshold per parameter of the model, for one engine."""
    from crosscheck.engines.base import EngineUnsupported
    from crosscheck.engines.registry import get_engine
    from crosscheck.run.checks import consistent_states, generic_model

    adapter = get_engine(engine)
    nm = generic_model(name)
    states = consistent_states(nm, n_states)
    params = [p.name for p in nm.model.parameters]
    try:
        failing, base = _engine_figures(name, nm, states, adapter, {})
    except EngineUnsupported as exc:
        return [
            search(name, engine, p, lambda rel: "", f"engine cannot represent the model: {exc}")
            for p in params
        ]
    if failing:
        return [
            search(
                name,
                engine,
                p,
                lambda rel: "",
                f"the unperturbed comparison already fails ({failing})",
            )
            for p in params
        ]
    out, trajectory_base = [], {}
    for p in params:
        sign, k, moved, refused = _largest_change(name, nm, states, adapter, p)
        if moved is None:
            out.append(
                search(
                    name,
                    engine,
                    p,
                    lambda rel: "",
                    f"the engine refuses every change of it: {refused}",
                )
            )
            continue

        def evaluate(rel, p=p, sign=sign):
            return _engine_figures(name, nm, states, adapter, {p: sign * rel})[0]

        if moved != base:
            out.append(search(name, engine, p, evaluate, largest=k))
        elif _changes_model(name, nm, adapter, p, sign * 10.0**k):
            out.append(_trajectory_threshold(name, adapter, p, sign, k, trajectory_base))
        else:
            out.append(search(name, engine, p, evaluate, _unused_reason(sign * 10.0**k)))
    return out


def _changes_model(name, nm, adapter, p, rel) -> bool:
    """A change `rel` of `p` alters the engine's model (its fingerprint) in some variant."""
    from crosscheck.checks.instantaneous import build
    from crosscheck.checks.perturb import perturbed

    try:
        return any(
            build(adapter, name, nm.params, v).fingerprint()
            != build(adapter, name, perturbed(name, nm.params, {p: rel}), v).fingerprint()
            for v in adapter.variants(name)
        )
    except NotImplementedError:  # no fingerprint: the figures are all there is to go by
        return False


def _unused_reason(rel: float) -> str:
    return (
        f"not used by the engine's model: a {rel:.0e} change moves no compared figure "
        "(the engine's coordinates or loads do not contain it)"
    )


def _trajectory_threshold(name, adapter, p, sign, k, base: dict) -> Threshold:
    """The threshold of a parameter in the engine's model that no instantaneous check sees
    (exudyn's and OpenSim's pendulum_xy rod length: the distance constraint's length, on which
    the acceleration-level rows at a consistent state do not depend): the decades are searched
    with the trajectory comparison `crosscheck run` makes, at the textbook defaults and over
    its T_END (a run costs ~0.4 s, so no shorter horizon is needed); "caught" means one of the
    engine's trajectory records fails. `base` caches the unperturbed run's verdict per
    model and engine (computed on first use)."""
    from crosscheck.checks.perturb import perturbed
    from crosscheck.checks.trajectory.check import T_END, trajectory_records
    from reference import NumericModel, models

    nm = NumericModel(models.get(name))  # the parameters of `crosscheck run`'s trajectories

    def evaluate(rel: float) -> str:
        params = perturbed(name, nm.params, {p: sign * rel})
        recs, _ = trajectory_records(name, nm, [adapter], T_END, {adapter.name: params})
        return _first_failing(recs, adapter.name)

    how = (
        f"no instantaneous check sees it (a change alters the engine's model, its fingerprint, "
        f"but no compared figure at the consistent states), so the trajectory comparison of "
        f"`crosscheck run {name} --engines {adapter.name} --perturb {adapter.name}:{p}=REL` "
        f"was searched: {T_END:g} s from the model's initial state at its textbook defaults"
    )
    key = (name, adapter.name)
    if key not in base:
        base[key] = evaluate(0.0)
    if base[key]:
        reason = f"{how}; the unperturbed trajectory comparison already fails ({base[key]})"
        return search(name, adapter.name, p, evaluate, reason, comparison="trajectory")
    return search(name, adapter.name, p, evaluate, largest=k, comparison="trajectory", how=how)


def _largest_change(name, nm, states, adapter, p):
    """(sign, decade, figures there, refusal) of the largest change the engine accepts: an
    increase of 10 % first, else a decrease, else smaller decades (a principal inertia at the
    edge of the triangle inequality admits only small changes)."""
    refused = ""
    for k in reversed(DECADES):
        for sign in (1.0, -1.0):
            try:
                _, moved = _engine_figures(name, nm, states, adapter, {p: sign * 10.0**k})
                return sign, k, moved, ""
            except ValueError as exc:  # the engine's own refusal of the changed model
                refused = str(exc).splitlines()[0]
    return 1.0, DECADES[0], None, refused
