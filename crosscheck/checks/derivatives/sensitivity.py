"""What relative error in one block of an engine's derivatives the derivatives records catch
(`crosscheck sensitivity --derivatives`).

For each model, engine model and block (du'/dq, du'/du, du'/dtau and the same of lambda, or of
A^T lambda where rows are dependent), every entry of the engine's block is multiplied by
(1 + rel) (crosscheck.checks.derivatives.faults.Fault, kind 'scale': in the engine's own
Jacobian where it gives derivatives of its own, else in its differenced block), and the
derivatives records are made again at the same states; the search over the decades
1e-13 .. 1e-1 is crosscheck.checks.sensitivity.threshold's (at most 5 evaluations). The error is
planted with both signs and the smaller decade caught is kept, as a parameter's is. A block
the unperturbed records already fail (Pinocchio's du'/dq on the slider-cranks) or skip is
reported with that reason instead of searched.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from crosscheck.checks.derivatives.engine import compared
from crosscheck.checks.derivatives.faults import ENGINE_BLOCKS, Fault
from crosscheck.checks.derivatives.records import engine_records
from crosscheck.checks.sensitivity import STATES, threshold
from crosscheck.engines.registry import get_engine
from reference import NumericModel, models
from reference.derivatives import DerivativeModel


@dataclass(frozen=True)
class DerivativeThreshold:
    """The outcome for one model x engine model x derivative block.

    caught_at: the smallest relative error caught (a decade), or None; not_caught_below: the
    largest decade not caught; failing_check: the record that caught it (it must be the
    block's own); reason: why the block was not searched or nothing caught it.
    """

    model: str
    engine: str
    variant: str | None
    quantity: str
    caught_at: float | None
    not_caught_below: float | None
    failing_check: str = ""
    reason: str = ""
    evaluations: int = 0

    def to_json(self) -> dict:
        return asdict(self)


def _first_failing(recs, base: dict, own: str) -> str:
    """The record that fails and passed unperturbed ("" where none): the block's own where it
    fails, else the first (a tau-block error also reaches the q-records where the applied
    forces depend on the state: exercise 6.1's spring)."""
    failed = [
        str(r["quantity"])
        for r in recs
        if r["passed"] is False and base.get(r["quantity"], {}).get("passed") is not False
    ]
    return own if own in failed else (failed[0] if failed else "")


def _one_block(name, nm, dm, states, adapter, variant, block, target, base) -> DerivativeThreshold:
    qty = Fault(block, target).quantity(compared(nm))
    rec = base.get(qty)
    row = dict(model=name, engine=adapter.name, variant=variant, quantity=qty)
    if rec is None or rec["skipped"]:
        reason = rec["reason"] if rec else "no such record for this model"
        return DerivativeThreshold(**row, caught_at=None, not_caught_below=None, reason=reason)
    if not rec["passed"]:
        reason = f"the unperturbed record fails already (error {rec['error']:.2g})"
        return DerivativeThreshold(**row, caught_at=None, not_caught_below=None, reason=reason)
    found = []
    for sign in (1.0, -1.0):

        def evaluate(rel: float, sign=sign) -> str:
            fault = Fault(block, target, "scale", sign * rel)
            params = nm.params
            recs = engine_records(name, nm, dm, states, adapter, params, variant, fault)
            return _first_failing(recs, base, qty)

        found.append(threshold(evaluate))
    if all(f[0] is None for f in found) and _unchanged(
        name, nm, dm, states, adapter, variant, block, target, rec
    ):
        return DerivativeThreshold(
            **row, caught_at=None, not_caught_below=None, reason=NO_BLOCK, evaluations=10
        )
    k, not_below, failing, calls = min(found, key=lambda f: 99 if f[0] is None else f[0])
    calls = sum(f[3] for f in found)
    return DerivativeThreshold(
        **row,
        caught_at=None if k is None else 10.0**k,
        not_caught_below=None if not_below is None else 10.0**not_below,
        failing_check=failing,
        reason="" if k is not None else "not caught up to a 10 % error",
        evaluations=calls,
    )


NO_BLOCK = (
    "a 10 % error planted in this block moves no record: the engine has no such block of its "
    "own (a tree's multipliers are joint reactions that follow from its accelerations through "
    "the maps)"
)


def _unchanged(name, nm, dm, states, adapter, variant, block, target, rec) -> bool:
    """Whether a 10 % error in the block leaves its record's error as it was."""
    fault = Fault(block, target, "scale", 0.1)
    recs = engine_records(name, nm, dm, states, adapter, nm.params, variant, fault)
    mine = next(r for r in recs if r["quantity"] == rec["quantity"])
    return mine["error"] == rec["error"]


def derivative_thresholds(name: str, engine: str, n_states: int = STATES) -> list:
    """Every derivative block's threshold for one model and engine (module docstring)."""
    from crosscheck.checks.sampling import consistent_states

    nm = NumericModel(models.get(name))
    states = consistent_states(nm, n_states)
    dm = DerivativeModel(nm)
    adapter = get_engine(engine)
    out = []
    for variant in adapter.variants(name):
        recs = engine_records(name, nm, dm, states, adapter, nm.params, variant)
        base = {r["quantity"]: r for r in recs}
        for block in ENGINE_BLOCKS:
            for target in ("accelerations", "forces"):
                out.append(_one_block(name, nm, dm, states, adapter, variant, block, target, base))
    return out
