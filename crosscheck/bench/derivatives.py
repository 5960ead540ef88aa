"""Derivative speed: the reference's exact derivatives of its forward answer at one state
against Pinocchio's analytical ones, timed in the same run, interleaved (bench.json
`derivatives`).

- `reference-checked`: DerivativeModel.at(q, u), the checked call: u', lambda and every block
  (du'/dq, du'/du, du'/dtau and lambda's), a Derivatives record of views;
- `reference-kernel`: the generated kernel alone into a preallocated array (DerivativeModel
  .fast: one C call that solves and differentiates);
- `pinocchio`: what Pinocchio's analytical derivatives cost at the same state from Python: its
  forward call (constraintDynamics with the engine model's constraint models, or aba) and
  then computeConstraintDynamicsDerivatives (or computeABADerivatives), which needs the
  forward call first. Its models with textbook rows given to forwardDynamics (J, gamma) have
  no derivative routine and no row here.

Target: the checked reference call costs at most 2x Pinocchio's per state
(`reference <= 2 x pinocchio derivatives`).
"""

from __future__ import annotations

from functools import partial

import numpy as np

from crosscheck.bench.timing import interleaved_seconds
from crosscheck.engines.base import EngineUnsupported
from reference import NumericModel, models
from reference.derivatives import DerivativeModel

TARGET = 2.0


def _pinocchio_call(em, q, u):
    """Pinocchio's forward call and its derivative routine at the mapped state, or None."""
    import pinocchio as pin

    qe, ve = (np.array(x, float) for x in em.to_engine_state(q, u))
    if hasattr(em, "_eq"):  # a user's file: its rows as Pinocchio's constraint models
        return _user_file_call(em, qe, ve)
    m, d = em.model, em.data
    tau = np.asarray(em._applied(qe, ve, 0.0), float)
    if em.solver == "constraint":
        cms, cds, prox = em.cms, em.cds, em.prox

        def call():
            pin.constraintDynamics(m, d, qe, ve, tau, cms, cds, prox)
            return pin.computeConstraintDynamicsDerivatives(m, d, cms, cds, prox)

        return call, "constraintDynamics + computeConstraintDynamicsDerivatives"
    if em.solver == "aba":
        return (lambda: pin.computeABADerivatives(m, d, qe, ve, tau)), "computeABADerivatives"
    return None, ""


def _user_file_call(em, qe, ve):
    """The same on a user's MJCF file (crosscheck.engines.pinocchio.user_file_derivatives)."""
    import pinocchio as pin

    from crosscheck.engines.pinocchio.user_file_derivatives import UserFileDerivatives

    try:
        ud = UserFileDerivatives(em)
    except EngineUnsupported:  # a joint equality: no constraint model, no routine
        return None, ""
    m, d, cms, cds, prox = em.model, ud.data, ud.cms, ud.cds, ud.prox
    tau = np.asarray(em._tau(qe, ve), float)

    def call():
        pin.constraintDynamics(m, d, qe, ve, tau, cms, cds, prox)
        return pin.computeConstraintDynamicsDerivatives(m, d, cms, cds, prox)

    return call, "constraintDynamics + computeConstraintDynamicsDerivatives (the file's rows)"


def derivative_records(names, engines=()) -> list[dict]:
    """One row per model and path (microseconds per state), and the ratio to Pinocchio's."""
    use_pin = any(e.name == "pinocchio" for e in engines)
    rows: list[dict] = []
    for name in names:
        nm = NumericModel(models.get(name))
        dm = DerivativeModel(nm)
        from crosscheck.checks.sampling import consistent_states

        q, u = (np.asarray(x, float) for x in consistent_states(nm, 2)[1])
        calls: dict = {"reference-checked": partial(dm.at, q, u)}
        if dm.kind == "kkt":
            calls["reference-kernel"] = partial(dm.fast, q, u, 0.0, np.empty(dm._nout))
        what = ""
        variant = None
        if use_pin:
            from crosscheck.engines.registry import get_engine

            adapter = get_engine("pinocchio")
            for variant in adapter.variants(name):
                try:
                    em = adapter.build(name, nm.params, variant=variant)
                except EngineUnsupported:
                    continue
                call, what = _pinocchio_call(em, q, u)
                if call is not None:
                    calls["pinocchio"] = call
                    break
        timed = interleaved_seconds(calls)
        base = {"model": name, "formulation": nm.formulation, "backend": dm.backend}
        for path, t in timed.items():
            row = {**base, "path": path, "us_per_state": t["median"] * 1e6}
            row["us_per_state_min"] = t["min"] * 1e6
            if path == "pinocchio":
                row.update(call=what, variant=variant)
            rows.append(row)
        if "pinocchio" in timed:
            ratio = timed["reference-checked"]["median"] / timed["pinocchio"]["median"]
            rows.append(
                {
                    **base,
                    "path": "ratio",
                    "checked_over_pinocchio": ratio,
                    "met": {f"reference <= {TARGET:g} x pinocchio derivatives": ratio <= TARGET},
                }
            )
    return rows
