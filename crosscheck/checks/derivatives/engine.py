"""One engine model's derivatives against the reference's exact ones, state by state.

At each consistent state the reference gives its exact derivatives (reference.derivatives) and
the consistent directions there (reference.derivatives.directions): q-directions, u-directions
and the unit generalized forces. The engine's derivative along the same directions comes from
its own routine where it has one (Capabilities.derivatives, EngineModel.derivatives:
Pinocchio's analytical derivatives, mapped through the maps' Jacobians), else from central
differences of its forward answer on the manifold (crosscheck.checks.derivatives.differences).
Each block (du'/dq, du'/du, du'/dtau, dlambda/dq, dlambda/du, dlambda/dtau: the quantities
``daccelerations_dq`` ... ``dmultipliers_dtau``) is judged on its own, against the tolerance
derived at the state (crosscheck.checks.derivatives.tolerances), so an error planted in one
block fails that block's record alone (crosscheck.checks.derivatives.faults).

A soft engine's rigid recovery is differenced and judged like an exact answer; its raw answer's
derivative is judged against the derivative of the raw answer its impedance predicts
(``*_soft_vs_predicted``, metric relative_miss), as the forward answers are.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from crosscheck.checks import tolerances as C
from crosscheck.checks.derivatives import tolerances as D
from crosscheck.checks.derivatives.differences import StencilLeaves, engine_differences
from crosscheck.checks.derivatives.faults import ENGINE_BLOCKS, Fault
from crosscheck.checks.sampling import monitor_of
from crosscheck.engines.base import EngineAdapter, EngineModel, EngineUnsupported
from reference.derivatives import DerivativeModel
from reference.derivatives.directions import Directions, along, consistent_directions

OF = ("accelerations", "multipliers", "constraint_forces")
BLOCKS = ("dq", "du", "dtau")
QUATERNION_ROWS = (
    "the model has rows whose multiplier depends on the formulation (a quaternion's unit-norm "
    "row), which no engine has: its generalized constraint force is not compared"
)
NO_FORCE_INPUT = (
    "the engine's answer is differenced and forward() takes no applied generalized force: "
    "the tau-derivatives (the columns of K^-1) are compared where the engine gives its own "
    "derivatives"
)
NO_ROWS = "no constraints: no multipliers to differentiate"


def compared(nm) -> tuple[str, str]:
    """The two answers differentiated: u' and lambda, or, where rows are dependent (a user's
    MJCF file), u' and the generalized constraint force A^T lambda (lambda is a convention
    there, its derivative too where the dependency moves with the state)."""
    return ("accelerations", "constraint_forces" if nm.redundant else "multipliers")


def quantity(of: str, block: str) -> str:
    """The record's quantity: daccelerations_dq, dmultipliers_dtau, ..."""
    return f"d{of}_{block}"


@dataclass
class StateDerivatives:
    """One engine model at one state: judged comparisons by quantity, skips by quantity, and
    reported figures (quantity -> {field: value}); the judged differences' shrunk steps by
    block (a limit or contact within the stencil at the balanced step)."""

    judged: dict[str, D.Judged] = field(default_factory=dict)
    skips: dict[str, str] = field(default_factory=dict)
    reported: dict[str, dict] = field(default_factory=dict)
    soft: bool = False
    steps: dict[str, float] = field(default_factory=dict)


class ReferenceAtState:
    """The reference's exact derivatives along the consistent directions at one state."""

    def __init__(self, dm: DerivativeModel, q, u, t: float):
        self.q, self.u, self.t = np.asarray(q, float), np.asarray(u, float), float(t)
        self.d = dm.at(q, u, t)
        self.dirs: Directions = consistent_directions(dm, q, u, t)
        M, _f, A, _b = dm.nm.matrices(q, u, t)
        self.kappa = D.condition(M, A)
        self.m = dm.m
        self.of = compared(dm.nm)
        self.skip: str | None = None  # why the second answer is not compared
        if self.m == 0:
            self.skip = NO_ROWS
        elif dm.nm.redundant and dm.nm.model.formulation_dependent_rows:
            self.skip = QUATERNION_ROWS

    def exact(self, of: str, block: str) -> np.ndarray | None:
        return along(self.d, self.dirs, of, block)

    def go_whole(self) -> None:
        """Compare whole Jacobians (every coordinate and speed) from now on."""
        self.dirs = self.dirs.whole_jacobians()


# off the manifold, at this step along each coordinate and speed, an engine whose answer equals
# the reference's within 10x its exact tolerance extends the equations as the reference does
# (the same coordinates and rows): its whole Jacobians are compared, block by block
PROBE_STEP = 1e-3
PROBE_SLACK = 10.0


def same_extension(em: EngineModel, nm, ref: ReferenceAtState, delta: float) -> bool:
    """Whether the engine's answer equals the reference's off the manifold too (module
    docstring): probed one step along every coordinate and speed."""
    n, nq = ref.u.size, ref.q.size
    for k in range(nq + n):
        dq = np.eye(nq)[k] if k < nq else np.zeros(nq)
        du = np.eye(n)[k - nq] if k >= nq else np.zeros(n)
        q, u = ref.q + PROBE_STEP * dq, ref.u + PROBE_STEP * du
        try:
            ef, rf = em.forward(q, u, ref.t), nm.forward(q, u, ref.t)
        except Exception:
            return False
        pairs = [(ef.rigid_accelerations if ef.soft else ef.accelerations, rf.accelerations)]
        lam = ef.rigid_multipliers if ef.soft else ef.multipliers
        if lam is not None and not nm.redundant and lam.size:
            pairs.append((lam, rf.multipliers))
        for got, want in pairs:
            if not C.scaled_error(got, want) <= PROBE_SLACK * delta:
                return False
    return True


def _engine_own(em, caps, ref: ReferenceAtState, fault: Fault | None):
    """The engine's own derivatives (EngineDerivatives) or None, with the reason."""
    if caps.derivatives == "numerical":
        return None, None
    em.planted_fault = None if fault is None else fault.in_jacobians
    try:
        return em.derivatives(ref.q, ref.u, ref.t, ref.dirs), None
    except EngineUnsupported as exc:
        return None, str(exc)
    finally:
        em.planted_fault = None


def _judge_analytic(out: StateDerivatives, ed, ref: ReferenceAtState) -> None:
    for block in BLOCKS:
        for j, of in enumerate(ref.of):
            qty = quantity(of, block)
            if j and ref.skip:
                out.skips[qty] = ref.skip
                continue
            got = ed.blocks.get(block, (None, None))[j]
            if got is None:
                out.skips[qty] = ed.notes.get(f"{of}_{block}", ed.notes.get(block, "not given"))
                continue
            exact = ref.exact(of, block)
            assert exact is not None
            err = C.scaled_error(got, exact) if exact.size else 0.0
            out.judged[qty] = D.analytic(err, ref.kappa, ed.map_error, ed.method, ed.conditioning)


def _judge_differences(
    out: StateDerivatives, diff, ref: ReferenceAtState, delta: float, fault, judged: bool
) -> None:
    """The differenced blocks: judged (the engine has no derivatives of its own) or reported
    beside its own ones (`differences_error`)."""
    for block in ("dq", "du"):
        for j, of in enumerate(ref.of):
            qty = quantity(of, block)
            got = diff.get(block, of, "engine")
            if j and ref.skip:
                got = None
            if got is None:
                if judged:
                    out.skips.setdefault(qty, (j and ref.skip) or "the engine gives no multipliers")
                continue
            if fault is not None and fault.hits(j > 0, block):
                got = fault.planted(got)
            exact = ref.exact(of, block)
            assert exact is not None
            err = C.scaled_error(got, exact)
            if not judged:
                out.reported.setdefault(qty, {})["differences_error"] = err
                continue
            trunc = float(np.max(np.abs(diff.get(block, of, "reference") - exact)))
            scale = diff.scales[(block, of)]
            h, why = diff.step(block)
            out.judged[qty] = D.differenced(err, trunc, delta, h, scale, D.scale(exact), why)
    if judged:
        for j, of in enumerate(ref.of):
            out.skips.setdefault(quantity(of, "dtau"), (j and ref.skip) or NO_FORCE_INPUT)


def _judge_soft(out: StateDerivatives, diff, ref, own) -> None:
    """A soft engine's raw answer's derivatives (central differences on the manifold) against
    the ones its impedance predicts, the predicted soft effect differenced against the
    reference's answer on the same stencil states (so the stencil's truncation cancels in
    it). The engine's own differences of its soft accelerations (`own`: MuJoCo's
    mjd_transitionFD) are measured against the same prediction and reported beside
    (``engine_differences_miss``): they are not judged (docs/engines/mujoco.md)."""
    for block in ("dq", "du"):
        for j, of in enumerate(ref.of):
            raw, pred = diff.get(block, of, "raw"), diff.get(block, of, "predicted")
            if raw is None or (j and ref.skip):
                continue
            out.soft = True
            qty = f"{quantity(of, block)}_soft_vs_predicted"
            if pred is None:
                out.skips[qty] = "the engine does not predict its soft answer independently"
                continue
            exact, at_ref = ref.exact(of, block), diff.get(block, of, "reference")
            effect = pred - at_ref
            miss, raw_err, pred_err = C.soft_prediction(exact + raw - at_ref, exact, effect)
            h, why = diff.step(block)
            value_scale = diff.scales[(block, of)]
            out.judged[qty] = D.soft(miss, h, value_scale, D.scale(exact), pred_err, why)
            extra = {"soft_rel_error_max": raw_err, "predicted_rel_error_max": pred_err}
            mine = own.blocks.get(block, (None, None))[j] if own is not None else None
            if mine is not None:
                extra["engine_differences_miss"] = C.soft_prediction(mine, exact, effect)[0]
            out.reported.setdefault(qty, {}).update(extra)


def compare_at_state(
    em: EngineModel,
    adapter: EngineAdapter,
    dm: DerivativeModel,
    model_name: str,
    q,
    u,
    t: float = 0.0,
    fault: Fault | None = None,
) -> StateDerivatives:
    """The engine model's derivatives against the reference's at one consistent state
    (module docstring); `fault` plants an error in one of the engine's blocks: in its own
    Jacobians where it gives derivatives of its own, else in its differenced blocks."""
    ref = ReferenceAtState(dm, q, u, t)
    out = StateDerivatives()
    soft = em.forward(ref.q, ref.u, t).soft
    delta = (C.RIGID_RECOVERY if soft else adapter.exact_tolerance(model_name)).value
    if not soft and same_extension(em, dm.nm, ref, delta):
        ref.go_whole()
    analytic = adapter.capabilities.derivatives == "analytic"
    ed, why = _engine_own(em, adapter.capabilities, ref, fault if analytic else None)
    own_exact = ed if ed is not None and ed.answer == "exact" else None
    own_soft = ed if ed is not None and ed.answer == "soft" else None
    if own_exact is not None:
        _judge_analytic(out, own_exact, ref)
    step, soft_prediction = D.step(delta), adapter.capabilities.soft_prediction
    floor = D.step_floor(delta)
    monitor = monitor_of(dm.nm.model)
    try:
        diff = engine_differences(
            em, dm.nm, ref.dirs, ref.q, ref.u, t, step, soft_prediction, monitor, floor
        )
    except StencilLeaves:
        if own_exact is None:
            raise
        diff = None  # the engine's own derivatives are judged; only differences_error is lost
    if diff is not None:
        planted = fault if own_exact is None else None  # where the judged blocks come from
        _judge_differences(out, diff, ref, delta, planted, own_exact is None)
        _judge_soft(out, diff, ref, own_soft)
        if own_exact is None:
            out.steps = {block: h for block, (h, _why) in diff.steps.items()}
    mode = "whole Jacobians" if ref.dirs.whole else "consistent directions"
    for qty in out.judged:
        out.reported.setdefault(qty, {})["directions"] = mode
    if own_exact is None and why is not None:
        for qty in out.judged:
            if not qty.endswith("_soft_vs_predicted"):
                out.reported.setdefault(qty, {})["derivative_method"] = (
                    f"central differences ({why})"
                )
    return out


__all__ = ["ENGINE_BLOCKS", "StateDerivatives", "compare_at_state", "quantity"]
