"""The agreement matrix: every engine against every other and each against the reference.

The records hold each engine's error against the reference. When a record fails, that alone
cannot say whether the engine or the reference is wrong; the matrix can. At the same states, each
side's judged answer (the reference's u' and lambda; an exact engine's own; a soft engine's rigid
recovery) is compared with every other side's, with the symmetric metric

    d(a, b) = max |a - b| / max(max |a|, max |b|, 1)

and a pair is held to the sum of its two sides' tolerances against the reference (if both are
within theirs, the triangle inequality keeps them within the sum). A side that disagrees with
every other side while those agree among themselves is the odd one out: the report names it.
Reported beside the records, never judged on its own (each pair's verdict is already a record's).
"""

from __future__ import annotations

import math
from itertools import combinations

import numpy as np

from crosscheck.checks.tolerances import Tolerance

# pairs of exact sides whose tolerances are tiny are still allowed round-off
ROUND_OFF_FLOOR = 1e-13

REFERENCE = "reference"
QUANTITIES = ("accelerations", "multipliers")


def pair_error(a, b) -> float:
    """d(a, b) above: symmetric, relative to the larger answer (1 SI unit at least)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.size == 0:
        return 0.0
    scale = max(float(np.max(np.abs(a))), float(np.max(np.abs(b))), 1.0)
    err = float(np.max(np.abs(a - b))) / scale
    return err if math.isfinite(err) else math.inf


class Answers:
    """Each side's answers at a run's states, collected while the records are made."""

    def __init__(self, model: str):
        self.model = model
        self.sides: dict[str, list[dict]] = {}  # side -> per state {quantity: array or None}
        self.tolerances: dict[str, Tolerance] = {REFERENCE: Tolerance(0.0, "the reference")}

    def add(self, side: str, state: int, quantity: str, value, tolerance: Tolerance) -> None:
        per_state = self.sides.setdefault(side, [])
        while len(per_state) <= state:
            per_state.append({})
        per_state[state][quantity] = None if value is None else np.asarray(value, float)
        self.tolerances.setdefault(side, tolerance)

    def matrices(self) -> list[dict]:
        """One matrix per quantity with at least two sides answering it (results.json
        "agreement")."""
        out = []
        for qty in QUANTITIES:
            sides = [
                s
                for s, states in self.sides.items()
                if states and all(st.get(qty) is not None for st in states)
            ]
            if len(sides) < 2:
                continue
            errors = {
                (a, b): max(
                    pair_error(sa[qty], sb[qty])
                    for sa, sb in zip(self.sides[a], self.sides[b], strict=True)
                )
                for a, b in combinations(sides, 2)
            }
            out.append(self._matrix(qty, sides, errors))
        return out

    def _matrix(self, qty: str, sides: list[str], errors: dict) -> dict:
        tol = {s: self.tolerances[s].value for s in sides}

        def bound(a, b):
            return max(tol[a] + tol[b], ROUND_OFF_FLOOR)

        grid = [
            [0.0 if a == b else errors.get((a, b), errors.get((b, a))) for b in sides]
            for a in sides
        ]
        bounds = [[0.0 if a == b else bound(a, b) for b in sides] for a in sides]
        return {
            "model": self.model,
            "quantity": qty,
            "sides": sides,
            "errors": grid,
            "bounds": bounds,
            "odd_one_out": odd_one_out(sides, grid, bounds),
            "metric": "max |a - b| / max(max |a|, max |b|, 1)",
            "bound_reason": "the sum of the two sides' tolerances against the reference "
            "(triangle inequality), at least the round-off floor",
        }


def odd_one_out(sides: list[str], grid, bounds) -> str | None:
    """The one side outside its bound against every other side while all the other pairs are
    within theirs (at least three sides); None when there is no single culprit."""
    if len(sides) < 3:
        return None
    n = len(sides)

    def bad(i, j):
        return not grid[i][j] <= bounds[i][j]

    for k in range(n):
        others = [i for i in range(n) if i != k]
        if all(bad(k, i) for i in others) and not any(
            bad(i, j) for i, j in combinations(others, 2)
        ):
            return sides[k]
    return None


def reference_answers(model: str, refs, n_rows: int) -> Answers:
    """An Answers holding the reference's u' and lambda at the run's states (refs: one
    comparison.ReferenceAnswer per state, the ones the records are judged against)."""
    answers = Answers(model)
    ref_tol = answers.tolerances[REFERENCE]
    for i, ref in enumerate(refs):
        answers.add(REFERENCE, i, "accelerations", ref.accelerations, ref_tol)
        if n_rows:
            answers.add(REFERENCE, i, "multipliers", ref.multipliers, ref_tol)
    return answers
