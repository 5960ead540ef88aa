"""Seeded random parameter sets and consistent states: ONE generator for the property tests
(tests/test_properties.py) and the sweeps (crosscheck.commands.sweep); `consistent_states` draws the
states of `crosscheck run` (and of the forward benchmark) at the model's own parameters.

An instance is drawn from one numpy Generator in a fixed order (the property tests' `_instance`):
    params = random_params(model, rng)          # each positive parameter x U(0.8, 1.25)
    t      = rng.uniform(0, 2)
    q, u   = random_consistent_state(nm, rng, t=t)   # initial state + noise, projected
`draw_instance` is that sequence. A sweep seeds sample i of model M in campaign seed S with
`sample_seed(S, M, i)`, a 32-bit integer that is also a valid hypothesis seed of the property
tests: `_instance(M, formulation, sample_seed(S, M, i))` draws exactly the same instance, so a
worst case found by a sweep can be pinned there with `@example(seed=...)`.

Inertias (parameters in kg m^2) are drawn each on its own, U(0.8, 1.25) times its default, so
that a swapped or mislabelled axis shows (one common factor, the earlier rule, kept equal
defaults equal). A body's principal inertias must still satisfy the triangle inequalities
I_a + I_b >= I_c, or MuJoCo refuses the body at compile time (a first sweep lost 13-100 % of
the samples of Example 3's bar, Example 4's slender links and the top to build faults when the
draws ignored it). A body whose three principal inertias are three parameters is drawn in its
second moments J_i = (I_j + I_k - I_i) / 2 >= 0 (I_i = J_j + J_k), each scaled by its own
U(0.8, 1.25): every draw is physical and the three inertias move apart (a slender link, whose
|I_11 - I_33| may not exceed the tiny I_22, would accept 1.2 % of independent draws of the I's
themselves). Any other body with three nonzero principal inertias (the top's I, I, I3) is
drawn again until its triangle holds (rejection sampling).
"""

from __future__ import annotations

import functools
import zlib
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from reference import NumericModel, models
from reference.errors import ModelInputError
from reference.generic import inertia_triples

# Range of the relative scale factor of every positive parameter: wide enough to move the
# dynamics, narrow enough that the geometry of every model stays valid (a slider-crank keeps
# l2 > l1, a pendulum keeps a positive length).
SCALE_RANGE = (0.8, 1.25)
T_RANGE = (0.0, 2.0)  # time of the state (rheonomic constraints and time-dependent loads)


# redraws of one body's inertias before falling back to one common factor (always physical
# when the defaults are): at an acceptance of ~1/2 per draw, 64 redraws all fail with 5e-20
MAX_REDRAWS = 64


def random_params(model, rng) -> dict[str, float]:
    """Random parameters of a model: positive (and nonnegative) ones scaled by U(0.8, 1.25),
    each inertia independently but every body physical (see the module docstring), signed
    ones (applied loads) drawn from U(-1, 1) times max(1, |default|)."""
    out = {}
    for p in model.parameters:
        if p.positive or p.nonnegative:
            out[p.name] = p.default * rng.uniform(*SCALE_RANGE)
        else:  # applied loads and other signed parameters: a random value of the same scale
            out[p.name] = rng.uniform(-1, 1) * max(1.0, abs(p.default))
    defaults = {p.name: p.default for p in model.parameters}
    for triple in _triples(model):
        _second_moment_draw(triple, defaults, out, rng)
    for names, diag in _body_inertias(model):
        for _ in range(MAX_REDRAWS):
            if physical(diag, out):
                break
            for n in names:
                out[n] = defaults[n] * rng.uniform(*SCALE_RANGE)
        else:  # one common factor keeps a physical default physical
            f = rng.uniform(*SCALE_RANGE)
            for n in names:
                out[n] = defaults[n] * f
    return out


def _second_moment_draw(triple, defaults, out, rng) -> None:
    """I_i = J_j + J_k with J = the default second moments, each times U(0.8, 1.25)."""
    a, b, c = (defaults[n] for n in triple)
    J = [max(0.5 * (b + c - a), 0.0), max(0.5 * (a + c - b), 0.0), max(0.5 * (a + b - c), 0.0)]
    J = [j * rng.uniform(*SCALE_RANGE) for j in J]
    for i, n in enumerate(triple):
        out[n] = sum(J) - J[i]


def physical(diag, values: dict[str, float]) -> bool:
    """The triangle inequalities of one body's principal inertias (each entry a parameter name
    or a number), with a relative slack of 1e-12 for the round-off of an inertia at equality."""
    a, b, c = (values[d] if isinstance(d, str) else d for d in diag)
    return all(x <= y + z + 1e-12 * (x + y + z) for x, y, z in ((a, b, c), (b, a, c), (c, a, b)))


def _body_inertias(model):
    """Bodies drawn by rejection: those not among the triples."""
    triples = set(_triples(model))
    bodies = _body_inertias_of(model.name) if _registered(model) else _inertia_bodies(model)
    return [b for b in bodies if b[1] not in triples]


def _triples(model):
    return _triples_of(model.name) if _registered(model) else tuple(inertia_triples(model))


@functools.cache
def _triples_of(name: str):
    return tuple(inertia_triples(models.get(name)))


def _registered(model) -> bool:
    try:
        return models.get(model.name) is model
    except Exception:
        return False


@functools.cache
def _body_inertias_of(name: str):
    return _inertia_bodies(models.get(name))


def _inertia_bodies(model) -> list[tuple[tuple[str, ...], tuple]]:
    """(parameter names, diagonal) of every body whose three principal inertias are nonzero and
    each a parameter or a number (a planar body's [0, 0, I] has no triangle to keep)."""
    names = {p.symbol: p.name for p in model.parameters}
    out = []
    for body in model.bodies:
        diag = []
        for i in range(3):
            d = body.inertia[i, i]
            if isinstance(d, sp.Symbol) and d in names:
                diag.append(names[d])
            elif d.is_number and float(d) != 0.0:
                diag.append(float(d))
            else:
                break
        off = any(body.inertia[i, j] != 0 for i in range(3) for j in range(3) if i != j)
        if len(diag) == 3 and not off:
            params = tuple(sorted({d for d in diag if isinstance(d, str)}))
            if params:
                out.append((params, tuple(diag)))
    return out


def random_consistent_state(nm, rng, q_spread=0.3, u_spread=1.0, t=0.0):
    """A random state near the model's initial state, projected onto its constraint manifold;
    for an MJCF file with contacts or limits (monitor_of), one where none acts, its limited
    joints drawn inside their ranges (ModelInputError after MAX_DRAWS_PER_STATE draws)."""
    m = nm.model
    monitor = monitor_of(m)
    for _ in range(1 if monitor is None else MAX_DRAWS_PER_STATE):
        q = np.asarray(m.initial_q, float) + q_spread * rng.standard_normal(len(m.initial_q))
        u = np.asarray(m.initial_u, float) + u_spread * rng.standard_normal(len(m.initial_u))
        if monitor is None:
            return nm.project(q, u, t)
        try:
            q, u = _project_inside(nm, monitor, monitor.inside_ranges(q, rng), u, t)
        except ModelInputError:
            continue
        if not monitor.active(q, u):
            return q, u
    raise ModelInputError(
        f"{m.name}: no consistent state without a contact, limit or force clamp acting in "
        f"{MAX_DRAWS_PER_STATE} draws"
    )


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


# alternations of the projection onto the constraints and the clamp into the joints' ranges
# per draw: closing a loop moves joints out of their ranges (Cassie's feet: 270 of 300 draws
# rejected at a limit with the projection alone, 3 states of 6 found), and alternating the two
# projections finds a point of both
RANGE_ALTERNATIONS = 5
# draws per requested state before a model whose contacts or limits act at every draw is
# given up on: a file whose checked states lie in a thin part of its configuration space still
# finds them (a robot's joints drawn inside their ranges, then its loops closed by the
# projection), and a file where they act everywhere is told so in seconds
MAX_DRAWS_PER_STATE = 50


@dataclass
class Draws:
    """The states of a run and how they were found: ``drawn`` random draws, ``rejected``
    (why -> how many: "contact", "limit", "force limit", "projection"), and ``initial_acts``,
    what acts at the initial state where it is left out (empty: it is states[0])."""

    states: list
    drawn: int = 0
    rejected: dict[str, int] = field(default_factory=dict)
    initial_acts: list = field(default_factory=list)


def monitor_of(model):
    """The monitor of what acts at some states only (an MJCF file's contacts, limits and force
    clamps: reference.mjcf.unilateral.Monitor) of a registered user model, else None."""
    src = models.user_source(model.name)
    if src is None or getattr(src, "model", None) is not model:
        return None
    return getattr(src, "monitor", None)


def consistent_states(nm: NumericModel, count: int):
    """The model's initial state and count-1 seeded random consistent states: drawn by the
    model's own state_sampler where it has one (it knows the coordinates' singular poses),
    else near the initial state; for an MJCF file with contacts or limits, states where none
    acts (draws).

    The seed is derived from the model name so every run draws the same states (deterministic
    results), and a state whose projection fails is replaced by the next draw.
    """
    return draws(nm, count).states


def draws(nm: NumericModel, count: int) -> Draws:
    """consistent_states with how they were found.

    Where the model has a monitor (monitor_of), every limited hinge and slide is drawn inside
    its range, the projection alternates with the ranges, and a state where a contact, limit or
    force clamp acts (the initial one included) is rejected and counted; at most
    MAX_DRAWS_PER_STATE draws per state are made, so fewer states (none) may come back.

    Parameters
    ----------
    nm : NumericModel
        The model at its parameters.
    count : int
        States asked for.

    Returns
    -------
    Draws
    """
    monitor = monitor_of(nm.model)
    if monitor is not None:
        return _admissible(nm, count, monitor)
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
    return Draws(states, tries)


def _admissible(nm: NumericModel, count: int, monitor) -> Draws:
    """Draws where nothing the monitor watches acts (see draws)."""
    rng = np.random.default_rng(zlib.crc32(nm.model.name.encode()))
    m = nm.model
    out = Draws([])
    initial = nm.project(m.initial_q, m.initial_u)
    out.initial_acts = monitor.active(*initial)
    if not out.initial_acts:
        out.states.append(initial)
    while len(out.states) < count and out.drawn < MAX_DRAWS_PER_STATE * count:
        out.drawn += 1
        q = np.asarray(m.initial_q) + 0.4 * rng.standard_normal(len(m.initial_q))
        u = np.asarray(m.initial_u) + rng.standard_normal(len(m.initial_u))
        try:
            q, u = _project_inside(nm, monitor, monitor.inside_ranges(q, rng), u)
            nm.forward(q, u)
        except ModelInputError:
            out.rejected["projection"] = out.rejected.get("projection", 0) + 1
            continue
        acts = monitor.active(q, u)
        for kind in sorted({a.kind for a in acts}):
            out.rejected[kind] = out.rejected.get(kind, 0) + 1
        if not acts:
            out.states.append((q, u))
    return out


def _project_inside(nm: NumericModel, monitor, q, u, t: float = 0.0):
    """The projection onto the constraints, alternated with the clamp into the limited joints'
    ranges until the projected state lies inside them (at most RANGE_ALTERNATIONS times)."""
    q, u = nm.project(q, u, t)
    for _ in range(RANGE_ALTERNATIONS):
        inside = monitor.clamped_to_ranges(q)
        if np.array_equal(inside, q):
            break
        q, u = nm.project(inside, u, t)
    return q, u
