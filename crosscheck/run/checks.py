"""The checks of `crosscheck run` (the command itself: crosscheck/commands/run.py): each model's
reference against every engine, stage by stage, then in time.
"""

from __future__ import annotations

import numpy as np

from crosscheck.checks import tolerances as C
from crosscheck.checks.agreement import reference_answers
from crosscheck.checks.instantaneous import engine_records, reference_answer
from crosscheck.checks.perturb import parse_perturb, perturbed
from crosscheck.checks.records import record, reported
from crosscheck.checks.sampling import consistent_states, draws
from crosscheck.checks.user_file import file_record
from crosscheck.engines.registry import get_engine
from reference import NumericModel, models
from reference.backends import select
from reference.generic import generic_parameters

__all__ = ["consistent_states", "generic_model", "parse_perturb", "perturbed", "run"]

# the check names of the records at the generic parameter set (reference/generic.py): distinct
# from the textbook-default ones, so a gate sees them as records of their own
GENERIC_SUFFIX = "_generic"


def generic_model(name: str) -> NumericModel:
    """The model at its generic parameter set (reference.generic), whose initial state still
    projects onto the constraints and gives finite accelerations."""
    model = models.get(name)

    def geometry_ok(values) -> bool:
        try:
            nm = NumericModel(model, params=values)
            q, u = nm.project(model.initial_q, model.initial_u)
            return bool(np.all(np.isfinite(nm.forward(q, u).accelerations)))
        except Exception:
            return False

    return NumericModel(model, params=generic_parameters(model, geometry_ok))


def _kkt_condition(nm, q, u) -> float:
    """cond(K) of the KKT matrix at one state (on A's independent rows)."""
    from crosscheck.checks.derivatives.tolerances import condition

    M, _f, A, _b = nm.matrices(q, u)[:4]
    return condition(np.asarray(M), np.asarray(A))


def _formulation_records(name, nm, states):
    """The reference's formulations against its primary one (Lagrange = d'Alembert = Kane)."""
    model = nm.model
    out = []
    dependent = dict(model.formulation_dependent_rows)
    keep = [j for j, c in enumerate(model.constraint_names or [""] * nm.m) if c not in dependent]
    tol = C.formulations_tolerance(max((_kkt_condition(nm, q, u) for q, u in states), default=1.0))
    for other in model.formulations[1:]:
        # the Python path: evaluated at a handful of states here, where a C build would take
        # 1-2 s of compiler time per formulation (benchmarks/c_build_times.py); it equals the
        # compiled path to the bit or within 1e-14 (tests/test_compiled.py)
        on = NumericModel(model, other, nm.params, backend="python")
        if _same_code(on.source, nm.source):
            out += _identical_records(name, other, nm)
            continue
        acc, lam = C.WorstCase(), C.WorstCase()
        for i, (q, u) in enumerate(states):
            a, b = nm.forward(q, u), on.forward(q, u)
            acc.add(C.scaled_error(b.accelerations, a.accelerations), i)
            lam.add(C.scaled_error(b.multipliers[keep], a.multipliers[keep]), i)
        out.append(
            record(
                name,
                other,
                "reference",
                "formulations",
                "accelerations",
                acc.error,
                tol,
                worst_state=acc.state,
                against=nm.formulation,
            )
        )
        if nm.m == 0:
            out.append(_no_multipliers(name, other))
            continue
        reason = ""
        if dependent:
            reason = (
                tol.reason + "; rows not compared because their multiplier depends on "
                "the formulation: " + "; ".join(f"{k}: {v}" for k, v in dependent.items())
            )
        out.append(
            record(
                name,
                other,
                "reference",
                "formulations",
                "multipliers",
                lam.error,
                tol,
                reason,
                worst_state=lam.state,
                against=nm.formulation,
            )
        )
    return out


def _same_code(a: str, b: str) -> bool:
    """Two generated modules with the same code (their comments, which name the formulation
    they were derived with, aside)."""

    def code(src: str) -> list[str]:
        return [line for line in src.splitlines() if not line.lstrip().startswith("#")]

    return code(a) == code(b)


def _identical_records(name, other, nm) -> list[dict]:
    """Skipped records where formulation `other` generated the code `nm`'s did: the two
    derivations agree expression for expression, and evaluating both would compare one function
    with itself (an error of exactly 0 that checks nothing)."""
    why = (
        f"{other} generated the same code as {nm.formulation}, expression for expression (the "
        f"two derivations agree exactly); evaluating both would compare a function with itself"
    )
    quantities = ("accelerations", "multipliers") if nm.m else ("accelerations",)
    out = [
        record(name, other, "reference", "formulations", q, None, None, why, against=nm.formulation)
        for q in quantities
    ]
    return out if nm.m else [*out, _no_multipliers(name, other)]


def _no_multipliers(name, formulation) -> dict:
    return record(
        name,
        formulation,
        "reference",
        "formulations",
        "multipliers",
        None,
        None,
        "no constraints, so no multipliers to compare",
    )


SOFT_FILE = (
    "reported, not judged: MuJoCo integrates the file's own soft equality constraints "
    "(its solref/solimp; MuJoCo's default solimp gives an impedance of 0.9..0.95, "
    "against the 0.9999 the trajectory bounds are sized for), so its motion differs "
    "from the rigid one by design; the instantaneous records judge its soft answer "
    "against the error its impedance predicts"
)


def _soft_file_trajectories(name, recs, adapters):
    """A soft engine's trajectory records on a user's MJCF file with equality constraints (the
    file's own solref/solimp): the measured figure kept, not judged (SOFT_FILE)."""
    from reference.mjcf.loader import MjcfImport  # MuJoCo loads only for a user's MJCF file

    src = models.user_source(name)
    if not (isinstance(src, MjcfImport) and src.mj.neq):
        return recs
    soft = {a.name for a in adapters if not a.capabilities.exact}
    out = []
    for r in recs:
        if r["engine"] in soft and r["passed"] is not None:
            r = reported(
                r,
                f"{SOFT_FILE} (measured {r['error']:.3g}; the built-in models' bound: "
                f"{r['reason']})",
            )
        out.append(r)
    return out


def run(
    model_names,
    engine_names,
    n_states=6,
    perturb=None,
    progress=None,
    trajectories=True,
    t_end=5.0,
    agreement: list | None = None,
    derivatives: bool = False,
):
    """All records (and trajectory series) for the models; see the module docstring.
    ``agreement``, when given, receives the agreement matrices (crosscheck.checks.agreement);
    ``derivatives`` adds the derivatives records (crosscheck.checks.derivatives)."""
    from crosscheck.checks.trajectory.check import trajectory_records

    perturb = perturb or {}
    adapters = [get_engine(e) for e in engine_names]
    records, series = [], []
    model_names = list(model_names)
    for k, name in enumerate(model_names):
        model = models.get(name)
        # the C builds of the next model start now (its derivation here, its compiles on the
        # other core while this model is checked; reference/backends/c_build.py): on a cold cache
        # only the first model waits for its compiler
        for ahead in model_names[k : k + 2] if k == 0 else model_names[k + 1 : k + 2]:
            upcoming = models.get(ahead)
            select.prebuild_model(upcoming, upcoming.formulations[:1])
        nm = NumericModel(model)
        drawn = draws(nm, n_states)
        states = drawn.states
        note = file_record(name, nm.formulation, drawn)  # a user's MJCF file: what it holds
        records += [note] if note else []
        if not states:  # no state where its contacts and limits rest: the record says so
            if progress:
                progress(name)
            continue
        records += _formulation_records(name, nm, states)
        refs = [reference_answer(nm, q, u) for q, u in states]  # once for every engine
        answers = reference_answers(name, refs, nm.m)
        for adapter in adapters:
            params = perturbed(name, nm.params, perturb.get(adapter.name, {}))
            for variant in adapter.variants(name):
                records += adapter.annotate_records(
                    name,
                    engine_records(name, nm, states, adapter, params, variant, answers, refs),
                )
        if agreement is not None:
            agreement += answers.matrices()
        records += _generic_records(name, adapters, n_states, perturb)
        if derivatives:
            from crosscheck.checks.derivatives.records import model_records

            records += model_records(name, nm, states, adapters, perturb)
        if trajectories:
            engine_params = {
                a.name: perturbed(name, nm.params, perturb.get(a.name, {})) for a in adapters
            }
            # the initial state, unless a contact or limit acts there (then checked state 0)
            start = states[0] if drawn.initial_acts else None
            recs, ser = trajectory_records(name, nm, adapters, t_end, engine_params, start)
            records += _soft_file_trajectories(name, recs, adapters)
            series += ser
        else:  # skipped on request: visible in the results, not silently absent
            records.append(
                record(
                    name,
                    nm.formulation,
                    "reference",
                    "trajectory",
                    "state_error",
                    None,
                    None,
                    "instantaneous checks only (--instantaneous)",
                )
            )
        if progress:
            progress(name)
    return records, series


def _generic_records(name, adapters, n_states, perturb) -> list[dict]:
    """The instantaneous checks again at the model's generic parameter set, where no two
    masses, lengths or principal inertias are equal (a swapped axis or sign cannot cancel):
    check names "formulations_generic" and "instantaneous_generic"."""
    if not models.get(name).parameters:
        return [_no_generic_set(name)]
    nm = generic_model(name)
    states = consistent_states(nm, n_states)
    out = _formulation_records(name, nm, states)
    refs = [reference_answer(nm, q, u) for q, u in states]
    for adapter in adapters:
        params = perturbed(name, nm.params, perturb.get(adapter.name, {}))
        for variant in adapter.variants(name):
            out += engine_records(name, nm, states, adapter, params, variant, refs=refs)
    for r in out:
        r["check"] += GENERIC_SUFFIX
    return out


def _no_generic_set(name: str) -> dict:
    """The one record of a model without parameters: its generic set would be its nominal one,
    and records that repeat the nominal ones could not fail on their own."""
    return record(
        name,
        models.get(name).formulations[0],
        "reference",
        "instantaneous" + GENERIC_SUFFIX,
        "parameter_set",
        None,
        None,
        "the model declares no parameters (an MJCF file's numbers are MuJoCo's compiled ones), "
        "so its generic set is its nominal one: the instantaneous records are the check",
    )
