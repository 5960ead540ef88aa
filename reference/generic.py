"""A generic parameter set for every model: no two masses, lengths or inertias alike.

The textbook's values are kept as the defaults (they reproduce the printed equations), but they
are symmetric in places: Example 4's links have equal transverse inertias, several bodies share
a mass. A permutation or sign error between equal values cancels (swapping I11 and I33 of a link
whose I11 = I33 changes nothing), so the cross-check also runs every model here, where each
parameter is its default times its own factor:

- every parameter gets a distinct factor in [0.85, 1.22] from a low-discrepancy sequence over
  its position in the model (deterministic: the same set on every machine and run);
- inertia matrices stay physical: for each body whose principal inertias are three parameters,
  the triangle inequalities I_a + I_b >= I_c hold (the largest is lowered to the middle one plus
  98 % of the smallest when the factors broke it; MuJoCo refuses a body otherwise);
- the geometry stays valid: the caller checks that the model's initial state still projects onto
  the constraint manifold (`generic_parameters` takes that check as an argument so this module
  stays free of the numeric layer).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import sympy as sp

from reference.system import Model

GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
FACTOR_RANGE = (0.85, 1.22)
TRIANGLE_MARGIN = 0.98


def generic_factor(index: int) -> float:
    """The k-th factor of the sequence: fractional parts of k * golden ratio, spread over
    FACTOR_RANGE, so any two factors differ by at least ~1 % for the parameter counts here."""
    lo, hi = FACTOR_RANGE
    return lo + (hi - lo) * math.modf((index + 1) * GOLDEN)[0]


def zero_default_value(index: int, signed: bool) -> float:
    """The generic value of a parameter whose default is 0: between 0.5 and 0.87 in its SI unit
    (a load of the size of the models' own), negative for every other signed one so that loads
    of both signs are exercised."""
    value = 0.5 + (generic_factor(index) - FACTOR_RANGE[0])
    return -value if signed and index % 2 else value


def inertia_triples(model: Model) -> list[tuple[str, str, str]]:
    """Names of the parameters that are a body's three principal inertias (diagonal inertia
    whose entries are each a single parameter symbol), one triple per such body."""
    names = {p.symbol: p.name for p in model.parameters}
    out = []
    for body in model.bodies:
        diag = [body.inertia[i, i] for i in range(3)]
        off = [body.inertia[i, j] for i in range(3) for j in range(3) if i != j]
        if (
            all(isinstance(d, sp.Symbol) and d in names for d in diag)
            and all(o == 0 for o in off)
            and len(set(diag)) == 3
        ):
            out.append(tuple(names[d] for d in diag))
    return out


def _physical_inertias(values: dict[str, float], triples) -> None:
    for triple in triples:
        vals = sorted(triple, key=lambda n: values[n])
        small, mid, large = vals
        if values[large] > values[small] + values[mid]:
            # a slender body (Example 4's links): I_small << I_mid ~ I_large, so the largest
            # must stay within I_small of the middle one, and above it to stay distinct
            values[large] = values[mid] + TRIANGLE_MARGIN * values[small]


def generic_parameters(
    model: Model, geometry_ok: Callable[[dict[str, float]], bool] | None = None
) -> dict[str, float]:
    """Every parameter with a nonzero default times its own factor. A zero default (an absent
    applied torque, no damping) gets a value of its own, `zero_default_value`: a load that is
    zero at both ends of a comparison cannot show a sign or lever-arm error. If `geometry_ok`
    rejects the set, the factors are pulled halfway towards 1 (still distinct) until it
    accepts, at most 8 times; a model that needs more than that is refused with the reason."""
    triples = inertia_triples(model)
    shrink = 1.0
    for _ in range(9):
        values = {}
        for k, p in enumerate(model.parameters):
            factor = 1.0 + shrink * (generic_factor(k) - 1.0)
            values[p.name] = (
                p.default * factor
                if p.default != 0.0
                else zero_default_value(k, signed=not (p.positive or p.nonnegative))
            )
        _physical_inertias(values, triples)
        if geometry_ok is None or geometry_ok(values):
            return values
        shrink /= 2.0
    raise ValueError(
        f"{model.name}: no generic parameter set near the defaults keeps the "
        f"initial state consistent; declare the model's valid parameter ranges"
    )
