"""What size of error the suite would catch: the smallest relative change of one parameter in
one engine's model that makes a check fail.

For each model, engine and parameter, the parameter of the ENGINE's model alone is multiplied by
(1 + rel) while the reference keeps its value, and the instantaneous comparison at the run's
consistent states is repeated (or, for a parameter that changes the engine's model but no
instantaneous figure, the trajectory comparison: crosscheck/commands/sensitivity.py).
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
