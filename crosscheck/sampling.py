"""Seeded random parameter sets and consistent states: ONE generator for the property tests
(tests/test_properties.py) and the sweeps (crosscheck.sweep); `consistent_states` draws the
states of `crosscheck run` (and of the forward benchmark) at the model's own parameters.

An instance is drawn from one numpy Generator in a fixed order (the property tests' `_instance`):
    params = random_params(model, rng)          # each positive parameter x U(0.8, 1.25)
    t      = rng.uniform(0, 2)
    q, u   = random_consistent_state(nm, rng, t=t)   # initial state + noise, projected
`draw_instance` is that sequence. A sweep seeds sample i of model M in campaign seed S with
`sample_seed(S, M, i)`, a 32-bit integer that is also a valid hypothesis seed of the property
tests: `_instance(M, formulation, sample_seed(S, M, i))` draws exactly the same instance, so a
worst case found by a sweep can be pinned there with `@example(seed=...)`.

Inertias (parameters in kg m^2) share one scale factor per draw: scaled independently, the
principal inertias of a body near the triangle inequality (I1 + I2 >= I3: Example 3's bar,
Example 4's slender links, the top) became non-physical in a fraction of the draws, which the
reference accepts but MuJoCo refuses at compile time (a first sweep lost 13-100 % of those
samples to build faults).
"""
from __future__ import annotations

import zlib

import numpy as np

from reference import NumericModel
from reference.errors import ModelInputError

# Range of the relative scale factor of every positive parameter: wide enough to move the
# dynamics, narrow enough that the geometry of every model stays valid (a slider-crank keeps
# l2 > l1, a pendulum keeps a positive length).
SCALE_RANGE = (0.8, 1.25)
T_RANGE = (0.0, 2.0)  # time of the state (rheonomic constraints and time-dependent loads)


def random_params(model, rng) -> dict[str, float]:
    """Random parameters of a model: positive (and nonnegative) ones scaled by U(0.8, 1.25)
    (one common factor for all inertias), signed ones (applied loads) drawn from U(-1, 1)
    times max(1, |default|)."""
    out = {}
    inertia_scale = rng.uniform(*SCALE_RANGE)  # one factor: keeps every body's inertia physical
    for p in model.parameters:
        if p.unit == "kg m^2":
            out[p.name] = p.default * inertia_scale
        elif p.positive or p.nonnegative:
            out[p.name] = p.default * rng.uniform(*SCALE_RANGE)
        else:  # applied loads and other signed parameters: a random value of the same scale
            out[p.name] = rng.uniform(-1, 1) * max(1.0, abs(p.default))
    return out


def random_consistent_state(nm, rng, q_spread=0.3, u_spread=1.0, t=0.0):
    """A random state near the model's initial state, projected onto its constraint manifold."""
    m = nm.model
    q = np.asarray(m.initial_q, float) + q_spread * rng.standard_normal(len(m.initial_q))
    u = np.asarray(m.initial_u, float) + u_spread * rng.standard_normal(len(m.initial_u))
    return nm.project(q, u, t)


def sample_seed(seed: int, model_name: str, index: int) -> int:
    """The seed of sample `index` of model `model_name` in a campaign with seed `seed`: a
    32-bit integer from numpy's SeedSequence over (seed, crc32(model name), index). It depends
    on nothing else (not the worker, not the chunking, not the other models)."""
    ss = np.random.SeedSequence([int(seed), zlib.crc32(model_name.encode()), int(index)])
    return int(ss.generate_state(1, np.uint32)[0])


def with_params(base: NumericModel, params: dict) -> NumericModel:
    """`NumericModel(base.model, base.formulation, params)` sharing base's compiled code (a
    sweep draws a parameter set per sample); tests/test_sweep.py checks both routes agree."""
    return base.with_params(params)


def draw_instance(base: NumericModel, rng):
    """(nm, t, q, u): the property tests' instance from `rng` (see the module docstring)."""
    nm = with_params(base, random_params(base.model, rng))
    t = float(rng.uniform(*T_RANGE))
    q, u = random_consistent_state(nm, rng, t=t)
    return nm, t, q, u


def draw_sample(base: NumericModel, seed: int, index: int):
    """Sample `index` of a campaign with seed `seed`: (sample seed, nm, t, q, u)."""
    s = sample_seed(seed, base.model.name, index)
    return (s, *draw_instance(base, np.random.default_rng(s)))


def consistent_states(nm: NumericModel, count: int):
    """The model's initial state and count-1 seeded random consistent states: drawn by the
    model's own state_sampler where it has one (it knows the coordinates' singular poses),
    else near the initial state.

    The seed is derived from the model name so every run draws the same states (deterministic
    results), and a state whose projection fails is replaced by the next draw.
    """
    rng = np.random.default_rng(zlib.crc32(nm.model.name.encode()))
    m = nm.model
    states = [nm.project(m.initial_q, m.initial_u)]
    tries = 0
    while len(states) < count and tries < 20 * count:
        tries += 1
        if m.state_sampler is not None:
            q, u = m.state_sampler(rng, nm.params)
        else:
            q = np.asarray(m.initial_q) + 0.4 * rng.standard_normal(len(m.initial_q))
            u = np.asarray(m.initial_u) + rng.standard_normal(len(m.initial_u))
        try:
            q, u = nm.project(q, u)
            nm.forward(q, u)
        except ModelInputError:
            continue
        states.append((q, u))
    return states
