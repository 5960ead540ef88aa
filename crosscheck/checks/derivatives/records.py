"""The derivatives records of `crosscheck run --derivatives`: the reference's exact derivatives
against its own slow path, and each engine model's against the reference's, one record per
block (quantities daccelerations_dq ... dmultipliers_dtau, and a soft engine's
``*_soft_vs_predicted``).

A record's tolerance is derived at each state (crosscheck.checks.derivatives.tolerances); the
record keeps the state where error / tolerance is largest, with that state's error, tolerance,
reason and figures, so it fails exactly when some state fails.
"""

from __future__ import annotations

import numpy as np

from crosscheck.checks.derivatives import tolerances as D
from crosscheck.checks.derivatives.differences import StencilLeaves, stencil, stencil_states
from crosscheck.checks.derivatives.engine import (
    BLOCKS,
    OF,
    ReferenceAtState,
    compare_at_state,
    compared,
    quantity,
)
from crosscheck.checks.derivatives.faults import Fault
from crosscheck.checks.instantaneous import build
from crosscheck.checks.records import Record, record
from crosscheck.engines.base import EngineAdapter, EngineUnsupported
from reference.derivatives import DerivativeModel
from reference.derivatives.differences import STEP, central_differences
from reference.errors import UnsupportedModelError

CHECK = "derivatives"
# the round-off of the reference's forward answer per unit of cond(K): a few ulps per operand
REFERENCE_ROUND_OFF = 16 * float(np.finfo(float).eps)
# a scaled error's tolerance this large judges nothing (a badly scaled file: MuJoCo's weld.xml,
# cond(K) 8.5e11 and multipliers of 3e6, gives 1.4e7): such a record is reported, not judged
VACUOUS = 1.0
# detail fields a judged figure may carry (Details in crosscheck.checks.records)
_FIGURES = {
    "step": "difference_step",
    "truncation_estimate": "truncation_estimate",
    "round_off_estimate": "round_off_estimate",
    "condition_number": "kkt_condition",
    "map_error": "map_error",
    "method": "derivative_method",
}


class _Worst:
    """The largest error / tolerance of one quantity over the states, with its state."""

    def __init__(self) -> None:
        self.judged: D.Judged | None = None
        self.state = -1
        self.extra: dict = {}

    def add(self, judged: D.Judged, state: int, extra: dict) -> None:
        worse = self.judged is None or not judged.ratio <= self.judged.ratio
        if worse:
            self.judged, self.state, self.extra = judged, state, dict(extra)

    def record(self, rec, qty: str, metric: str, note: str = "") -> Record:
        j = self.judged
        assert j is not None
        details = {_FIGURES[k]: v for k, v in j.figures.items() if k in _FIGURES}
        details.update(self.extra)
        kw = {} if metric == "scaled_error" else {"metric": metric}
        if note:
            kw["reason"] = f"{j.reason}; {note}"
        return rec(CHECK, qty, j.error, j.named(), worst_state=self.state, **kw, **details)


def _fold(rec, worst: dict[str, _Worst], skips: dict[str, str], note: str = "") -> list[Record]:
    """The records in a fixed order: every block's accelerations and multipliers, then the
    soft ones (`note`: what the judged ones leave out)."""
    out = []
    order = [quantity(of, b) for b in BLOCKS for of in OF]
    order += [f"{quantity(of, b)}_soft_vs_predicted" for b in ("dq", "du") for of in OF]
    for qty in order:
        if qty in worst:
            metric = "relative_miss" if qty.endswith("_soft_vs_predicted") else "scaled_error"
            out.append(worst[qty].record(rec, qty, metric, note))
        elif qty in skips:
            out.append(rec(CHECK, qty, None, None, skips[qty]))
    return out


def engine_records(
    name: str,
    nm,
    dm: DerivativeModel,
    states,
    adapter: EngineAdapter,
    params: dict,
    variant: str | None = None,
    fault: Fault | None = None,
) -> list[Record]:
    """The derivatives records of one engine model over the states (t = 0)."""
    which = {} if variant is None else {"variant": variant}

    def rec(*a, **k):
        return record(name, nm.formulation, adapter.name, *a, **k, **which)

    try:
        em = build(adapter, name, params, variant, nominal=nm.params)
    except EngineUnsupported as exc:
        reason = f"engine cannot represent the model: {exc}"
        return [rec(CHECK, quantity(of, "dq"), None, None, reason) for of in compared(nm)]
    worst: dict[str, _Worst] = {}
    skips: dict[str, str] = {}
    left: list[str] = []  # states whose stencil leaves the region the equations hold in
    shrunk: list[str] = []  # states whose stencil's step was shrunk to stay inside it
    for i, (q, u) in enumerate(states):
        try:
            sd = compare_at_state(em, adapter, dm, name, q, u, 0.0, fault)
        except EngineUnsupported as exc:
            reason = f"the engine cannot answer at the states: {exc}"
            return [rec(CHECK, quantity(of, "dq"), None, None, reason) for of in compared(nm)]
        except StencilLeaves as exc:
            left.append(f"state {i}: {exc}")
            continue
        for qty, judged in sd.judged.items():
            worst.setdefault(qty, _Worst()).add(judged, i, sd.reported.get(qty, {}))
        for qty, why in sd.skips.items():
            skips.setdefault(qty, why)
        if sd.steps:
            shrunk.append(f"state {i}: " + ", ".join(f"{b} {h:.1e}" for b, h in sd.steps.items()))
    note = _left_note(left, shrunk, len(states))
    if left and not worst:
        return [rec(CHECK, quantity(of, "dq"), None, None, note) for of in compared(nm)]
    return _fold(rec, worst, skips, note)


def _left_note(left: list[str], shrunk: list[str], count: int) -> str:
    """What the judged records leave out, and where their stencil's step was shrunk."""
    parts = [f"not compared at {len(left)} of {count} states ({'; '.join(left)})"] if left else []
    if shrunk:
        parts.append(
            f"the difference step shrunk at {len(shrunk)} of {count} states, where the balanced "
            f"one's stencil reaches a limit or contact ({'; '.join(shrunk)})"
        )
    return "; ".join(parts)


def _slow_blocks(nm, dm: DerivativeModel, q, u) -> list[tuple]:
    """(quantity, exact, slow, truncation) of every block: whole Jacobians against central
    differences of the reference's forward answer; where rows are dependent, the q- and
    u-blocks along the consistent directions on the manifold instead (off it the rows may be
    independent and the equations without a solution)."""
    ref = ReferenceAtState(dm, q, u, 0.0)
    whole = ("dtau",) if nm.redundant else BLOCKS
    slow, trunc = central_differences(nm, q, u, 0.0, STEP, whole)
    exact = ref.d
    A = nm.matrices(q, u)[2]
    out = []
    for j, of in enumerate(compared(nm)):
        if j and ref.skip:
            continue
        for block in BLOCKS:
            if block in whole:
                got = exact.block(of, block)
                if of == "constraint_forces":  # d(A^T lambda)/dtau = A^T dlambda/dtau
                    fd = A.T @ slow.block("multipliers", block)
                    tr = np.abs(A.T) @ trunc.block("multipliers", block)
                else:
                    fd, tr = slow.block(of, block), trunc.block(of, block)
            else:
                got = ref.exact(of, block)
                fd, tr = along_manifold(nm, ref, of, block)
            out.append((quantity(of, block), got, fd, float(np.max(tr)) if tr.size else 0.0))
    return out


def along_manifold(nm, ref: ReferenceAtState, of: str, block: str) -> tuple:
    """The reference's own central differences along the block's consistent directions on the
    manifold, at STEP, and their truncation estimated from 2 STEP."""
    DQ, DU = ref.dirs.state_directions(block)

    def answer(qq, uu):
        fw = nm.forward(qq, uu)
        if of == "accelerations":
            return fw.accelerations
        if of == "multipliers":
            return fw.multipliers
        return nm.matrices(qq, uu)[2].T @ fw.multipliers

    cols, trunc = [], []
    for k in range(DQ.shape[1]):
        d = [
            stencil(
                [answer(*x) for x in stencil_states(nm, ref.q, ref.u, 0.0, DQ[:, k], DU[:, k], h)],
                h,
            )
            for h in (STEP, 2 * STEP)
        ]
        cols.append(d[0])
        trunc.append(np.abs(d[1] - d[0]) / 15.0)
    size = len(answer(ref.q, ref.u))
    return (
        np.array(cols).T.reshape(size, len(cols)),
        np.array(trunc).T.reshape(size, len(cols)),
    )


def reference_records(name: str, nm, dm: DerivativeModel, states) -> list[Record]:
    """The reference's exact derivatives against its slow path (central differences of its own
    forward answer; reference.derivatives.differences), block by block."""

    def rec(*a, **k):
        return record(name, nm.formulation, "reference", *a, **k)

    worst: dict[str, _Worst] = {}
    skips: dict[str, str] = {}
    for i, (q, u) in enumerate(states):
        fw = nm.forward(q, u)
        M, _f, A, _b = nm.matrices(q, u)
        kappa = D.condition(M, A)
        values = np.concatenate([fw.accelerations, fw.multipliers])
        delta = REFERENCE_ROUND_OFF * max(kappa, 1.0)
        for qty, got, fd, t in _slow_blocks(nm, dm, q, u):
            err = float(np.max(np.abs(got - fd))) / D.scale(got) if fd.size else 0.0
            j = D.differenced(err, t, delta, STEP, D.scale(values), D.scale(got))
            j = D.Judged(j.error, j.tolerance, _slow_reason(j, kappa, dm.method), j.figures)
            worst.setdefault(qty, _Worst()).add(j, i, {})
    if states:
        q0, u0 = states[0]
        ref = ReferenceAtState(dm, q0, u0, 0.0)
        for block in BLOCKS:
            if ref.skip:
                skips[quantity(compared(nm)[1], block)] = ref.skip
    for qty in [k for k, w in worst.items() if w.judged and w.judged.tolerance >= VACUOUS]:
        j, i = worst[qty].judged, worst.pop(qty).state
        assert j is not None
        skips[qty] = (
            f"not judged: the derived tolerance {j.tolerance:.1e} is at least {VACUOUS:g}, so "
            f"no error could fail it (measured {j.error:.1e} at state {i}); {j.reason}"
        )
    return _fold(rec, worst, skips)


def _slow_reason(j: D.Judged, kappa: float, method: str) -> str:
    f = j.figures
    how = "complex steps of its generated M, f, A, b" if method == "complex_step" else ""
    return (
        f"the reference's exact derivatives (the implicit function theorem on its KKT "
        f"system, {how or 'generated code'}) against central differences of its own forward "
        f"answer (fourth order, step {f['step']:.0e}, whole Jacobians; d/dtau on a dense LU "
        f"of its M, f, A, b): {D.DIFFERENCE_SLACK:g}x the stencil's truncation estimated from "
        f"the step 2h ({f['truncation_estimate']:.1e}) plus its round-off, 16 eps x cond(K) = "
        f"{kappa:.2g} magnified by 1.5/h ({f['round_off_estimate']:.1e})"
    )


def model_records(name: str, nm, states, adapters, perturb: dict) -> list[Record]:
    """Every derivatives record of one model: the reference's own, then each engine model's,
    at the run's states and the engines' (perturbed) parameters."""
    from crosscheck.checks.perturb import perturbed

    try:
        dm = DerivativeModel(nm)
    except UnsupportedModelError as exc:  # too large to differentiate: said, not attempted
        return [record(name, nm.formulation, "reference", "derivatives", "derivatives",
                       None, None, str(exc))]  # fmt: skip
    out = reference_records(name, nm, dm, states)
    for adapter in adapters:
        params = perturbed(name, nm.params, perturb.get(adapter.name, {}))
        for variant in adapter.variants(name):
            out += engine_records(name, nm, dm, states, adapter, params, variant)
    return out
