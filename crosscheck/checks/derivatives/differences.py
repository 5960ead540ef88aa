"""Central differences of an engine's answer along consistent directions, with the reference's
answer on the same states.

A direction d = (dq, du) tangent to the state manifold at a consistent state x is followed on
the manifold itself: x(s) = P(x + s d), P the projection (Gauss-Newton on the position rows to
round-off, then the least velocity correction; `project`), whose curve has tangent d at
s = 0. Every engine is answered at consistent states only, as in every other check, and the
fourth-order stencil (8 (g(h) - g(-h)) - (g(2h) - g(-2h))) / 12h of s -> answer(x(s)) is
its derivative along d up to h^4 terms. The reference's forward answer on the same four
states gives the same stencil of the reference, whose exact derivative is known: their
difference is the truncation the engine's stencil has too (crosscheck.checks.derivatives
.tolerances).

Where a stencil state at the balanced step h would reach what an MJCF file's monitor watches (a
limit, a contact, a force clamp: other equations), the block's step is halved until every
direction's stencil clears, down to the floor (tolerances.step_floor); the block is judged at
the step used, and a state whose stencil reaches something even at the floor is left out
(StencilLeaves).

A soft engine (MuJoCo) is differenced twice on the same states: its rigid recovery (judged
against the reference's exact derivative) and its raw answer, beside the raw answer its
documented impedance predicts from the reference's accelerations there (predict_soft).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from crosscheck.checks.derivatives.tolerances import STENCIL, STEP_ROUND_OFF_BAR
from crosscheck.engines.base import EngineModel
from reference.numeric.redundant import RANK_RTOL

# the answers differenced, by name: the judged one, the raw soft one, its prediction, and the
# reference's
KINDS = ("engine", "raw", "predicted", "reference")


class StencilLeaves(Exception):
    """A stencil state where something an MJCF file's monitor watches acts (a contact, a
    limit): the equations the engine answers are other ones there, so the state's differences
    are not compared."""


def project(nm, q, u, t: float, iterations: int = 50) -> tuple[np.ndarray, np.ndarray]:
    """The consistent state nearest (q, u): Gauss-Newton on the position rows, then the least
    velocity correction, both with the reference's rank cut (RANK_RTOL) on dependent rows. The
    projection of NumericModel keeps a dependent row's round-off singular value (4.5e-15 of a
    weld's Jacobian) as a direction and moves u by its round-off over it: 0.02 on
    weld_sites.xml, a wrong curve."""
    q, u = np.array(q, float), np.array(u, float)
    rows = bool(nm.model.configuration_constraints)
    for _ in range(iterations if rows else 0):
        pos, _vel = nm.residuals(q, u, t)
        if np.max(np.abs(pos)) <= 1e-15 * (1 + np.max(np.abs(q))):
            break
        q -= np.linalg.lstsq(nm._position_jacobian(q, t), pos, rcond=RANK_RTOL)[0]
    A = nm.matrices(q, u, t)[2]
    if A.shape[0]:
        u -= np.linalg.lstsq(A, nm.residuals(q, u, t)[1], rcond=RANK_RTOL)[0]
    return q, u


def stencil_states(
    nm, q, u, t: float, dq, du, h: float, on_manifold: bool = True
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The states of the stencil's offsets: on the manifold, x(k h) = P(x + k h d); off it
    (whole Jacobians), x + k h d."""
    if not on_manifold:
        return [(q + k * h * dq, u + k * h * du) for k, _w in STENCIL]
    return [project(nm, q + k * h * dq, u + k * h * du, t) for k, _w in STENCIL]


def stencil(values: list[np.ndarray], h: float) -> np.ndarray:
    """The fourth-order central difference of values taken at the stencil's offsets."""
    return sum(w * v for (_k, w), v in zip(STENCIL, values, strict=True)) / (12.0 * h)  # type: ignore


@dataclass
class Differenced:
    """Per block ('dq', 'du') and quantity ('accelerations', 'multipliers'): the difference
    columns of each kind (KINDS) and the largest value scale max(max |g|, 1) met on the
    stencil states (the round-off bound's scale); per block the step used where the balanced
    step h was shrunk, and why."""

    h: float
    columns: dict = field(default_factory=dict)  # (block, quantity, kind) -> list of columns
    scales: dict = field(default_factory=dict)  # (block, quantity) -> float
    steps: dict = field(default_factory=dict)  # block -> (step, why) where shrunk

    def step(self, block: str) -> tuple[float, str]:
        """The block's step and, where shrunk, the clause saying why."""
        return self.steps.get(block, (self.h, ""))

    def add(self, block: str, quantity: str, kind: str, column: np.ndarray) -> None:
        self.columns.setdefault((block, quantity, kind), []).append(column)

    def get(self, block: str, quantity: str, kind: str) -> np.ndarray | None:
        cols = self.columns.get((block, quantity, kind))
        if not cols:
            return None
        return np.array(cols).T


def _answers(em: EngineModel, nm, qq, uu, t: float, soft: bool) -> dict:
    """Every kind's (accelerations, multipliers, constraint forces A^T lambda) at one state
    (None where absent). A^T lambda is the reference's A at the state times the multipliers,
    on both sides (where rows are dependent every side reports the minimum-norm lambda)."""
    ef = em.forward(qq, uu, t)
    ref = nm.forward(qq, uu, t)
    A = nm.matrices(qq, uu, t)[2] if nm.redundant else None

    def with_forces(acc, lam):
        return (acc, lam, None if A is None or lam is None else A.T @ np.asarray(lam, float))

    out = {"reference": with_forces(ref.accelerations, ref.multipliers)}
    if ef.soft:
        out["engine"] = with_forces(ef.rigid_accelerations, ef.rigid_multipliers)
        out["raw"] = with_forces(ef.accelerations, ef.multipliers)
        if soft:
            out["predicted"] = with_forces(*em.predict_soft(qq, uu, ref.accelerations))
    else:
        out["engine"] = with_forces(ef.accelerations, ef.multipliers)
    return out


def _acting(monitor, states: list) -> list:
    """What the monitor (sampling.monitor_of) sees act at any of the states."""
    return [a for qq, uu in states for a in monitor.active(qq, uu)] if monitor is not None else []


def _cleared(nm, monitor, q, u, t: float, DQ, DU, h: float, floor: float, on: bool):
    """The largest step h / 2^k (at least `floor`) at which no direction's stencil reaches
    what the monitor watches, with the stencils' states there and the clause saying why it
    is below h; StencilLeaves where none down to the floor clears."""
    step, first = h, []
    while True:
        states, acts = [], []
        for k in range(DQ.shape[1]):
            states.append(stencil_states(nm, q, u, t, DQ[:, k], DU[:, k], step, on))
            acts = _acting(monitor, states[-1])
            if acts:
                break
        if not acts:
            why = f", shrunk from {h:.1e}: at that step {'; '.join(map(str, first))}"
            return step, states, why if first else ""
        first = first or sorted(set(map(str, acts)))
        if step / 2 < floor:
            what = "; ".join(sorted(set(map(str, acts))))
            if step == h:
                raise StencilLeaves(f"{what} within the difference stencil (step {h:.1e})")
            raise StencilLeaves(
                f"{what} within the difference stencil at every step from {h:.1e} halved down "
                f"to {step:.1e} (the floor {floor:.1e}: below it the round-off bound "
                f"1.5 delta / h passes {STEP_ROUND_OFF_BAR:.0e} of the answer)"
            )
        step /= 2


def engine_differences(
    em: EngineModel,
    nm,
    dirs,
    q,
    u,
    t: float,
    h: float,
    soft_prediction: bool,
    monitor=None,
    floor: float | None = None,
) -> Differenced:
    """The stencils of every kind along every q- and u-direction (module docstring), at the
    step h, or where a stencil would reach what `monitor` watches, the block's step halved, no
    further than `floor` (tolerances.step_floor; None: not shrunk); raises StencilLeaves
    where even the smallest step's stencil reaches something."""
    q, u = np.asarray(q, float), np.asarray(u, float)
    out = Differenced(h)
    for block in ("dq", "du"):
        DQ, DU = dirs.state_directions(block)
        step, per_direction, why = _cleared(
            nm, monitor, q, u, t, DQ, DU, h, h if floor is None else floor, not dirs.whole
        )
        if why:
            out.steps[block] = (step, why)
        for states in per_direction:
            answers = [_answers(em, nm, qq, uu, t, soft_prediction) for qq, uu in states]
            for j, quantity in enumerate(("accelerations", "multipliers", "constraint_forces")):
                for kind in KINDS:
                    vals = [a.get(kind, (None, None, None))[j] for a in answers]
                    if any(v is None for v in vals):
                        continue
                    vals = [np.asarray(v, float) for v in vals]
                    out.add(block, quantity, kind, stencil(vals, step))
                    if kind == "engine":
                        key = (block, quantity)
                        big = max(
                            max(float(np.max(np.abs(v))) if v.size else 0.0, 1.0) for v in vals
                        )
                        out.scales[key] = max(out.scales.get(key, 1.0), big)
    return out
