"""Hypothesis strategies over plain floats for random parameters and consistent states.

An `Instance` is the floats a draw is made of: one relative factor per parameter, the time, and
the offsets of q and u from the model's initial state. They shrink towards the smallest factor,
t = 0 and zero offsets (the initial state), so a failure is reported as a small, readable case,
and a known edge case is written down as an Instance in an `@example`.

Parameters: each positive parameter is its default times its own factor in SCALE_RANGE (inertias
drawn independently, not by one common factor, so a swapped axis in an engine cannot hide behind
equal values), with each body's principal inertias kept physical (triangle inequality, as in
reference.generic); signed parameters (applied loads) are their factor mapped onto [-1, 1] times
max(1, |default|). The state is the initial state plus the offsets, projected onto the
constraint manifold.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from hypothesis import strategies as st

from reference import NumericModel
from reference.generic import inertia_triples

SCALE_RANGE = (0.8, 1.25)  # keeps every model's geometry valid (l2 > l1, positive lengths)
T_RANGE = (0.0, 2.0)  # time of the state (rheonomic constraints, time-dependent loads)
Q_SPREAD, U_SPREAD = 0.3, 1.0  # offsets from the initial state before projection


@dataclass(frozen=True)
class Instance:
    factors: tuple[float, ...]
    t: float
    dq: tuple[float, ...]
    du: tuple[float, ...]


def _floats(lo: float, hi: float):
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


def instances(model) -> st.SearchStrategy[Instance]:
    """Draws for one model: len(parameters) factors, t, and q/u offsets in units of the spreads."""
    n_p, n_q, n_u = len(model.parameters), len(model.initial_q), len(model.initial_u)
    return st.builds(
        Instance,
        factors=st.tuples(*[_floats(*SCALE_RANGE)] * n_p),
        t=_floats(*T_RANGE),
        dq=st.tuples(*[_floats(-3.0, 3.0)] * n_q),
        du=st.tuples(*[_floats(-3.0, 3.0)] * n_u),
    )


def parameters(model, factors) -> dict[str, float]:
    lo, hi = SCALE_RANGE
    values = {}
    for p, f in zip(model.parameters, factors, strict=True):
        if p.positive or p.nonnegative:
            values[p.name] = p.default * f
        else:  # a signed load: the factor's place in its range mapped onto [-1, 1]
            values[p.name] = (2.0 * (f - lo) / (hi - lo) - 1.0) * max(1.0, abs(p.default))
    for triple in inertia_triples(model):
        small, mid, large = sorted(triple, key=values.__getitem__)
        if values[large] > values[small] + values[mid]:
            values[large] = values[mid] + 0.98 * values[small]
    return values


def build(base: NumericModel, instance: Instance):
    """(nm, q, u, t): the model at the instance's parameters and its projected state."""
    model = base.model
    nm = base.with_params(parameters(model, instance.factors))
    q = np.asarray(model.initial_q, float) + Q_SPREAD * np.asarray(instance.dq)
    u = np.asarray(model.initial_u, float) + U_SPREAD * np.asarray(instance.du)
    q, u = nm.project(q, u, instance.t)
    return nm, q, u, instance.t
