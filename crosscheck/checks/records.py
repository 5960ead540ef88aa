"""The results.json contract in Python: what a record holds, and the one way to make one.

A record is one model x formulation x engine x check x quantity: the measured error, the
tolerance it is judged against (the named tolerances of crosscheck.checks.tolerances), the
verdict, the reason, and the details its producer adds. Records stay plain dicts (run writes
them as they are, the report and the gate read them back); `Record` states their fields for a
type checker and a reader, and `record()`, `annotated()` and `reported()` are how every
producer makes or changes one, so a field name that is not declared here is refused where it
is added.

The same fields, with their meaning and units, are in the JSON Schema shipped with the package
(crosscheck/schema/results.schema.json, crosscheck.schema.results_schema()), which the report
and the gate validate every results.json against; docs/results.md describes them for users. A
test keeps the TypedDicts below and the schema in agreement, field by field.
"""

# no `from __future__ import annotations` here: Python 3.11 reads NotRequired from a TypedDict's
# evaluated annotations only (with string annotations every key would count as required)
from collections.abc import Mapping
from typing import Any, Literal, NotRequired, TypedDict, Unpack, cast

import numpy as np

from crosscheck.checks.tolerances import Tolerance

Formulation = Literal["lagrange", "dalembert", "kane"]
# the checks of a run; "_generic": the same checks at the model's generic parameter set
Check = Literal[
    "formulations",
    "formulations_generic",
    "instantaneous",
    "instantaneous_generic",
    "trajectory",
    "parser",
    "derivatives",
]
# the keys of crosscheck.checks.tolerances.METRICS
Metric = Literal["scaled_error", "relative_energy_error", "relative_miss"]


class Finding(TypedDict):
    """One element Pinocchio's own MJCF parser lost or changed (the "parser" record)."""

    element: str
    kind: str
    finding: str


class Projection(TypedDict):
    """How far a user's MJCF file's initial state was moved onto its constraint manifold."""

    violation: float
    position_change: float
    velocity_change: float


class Details(TypedDict, total=False):
    """The fields a producer adds to a record beside the common ones (each only where it
    applies; the schema's descriptions say where)."""

    worst_state: int
    against: Formulation
    iterations_max: int
    answer: str
    soft_rel_error_max: float
    predicted_rel_error_max: float
    variant: str
    engine_model: str
    findings: list[Finding]
    t_end: float
    t_requested: float
    label: str
    nfev: int | None
    steps: int | None
    engine_warnings: dict[str, int]
    failure: bool
    judged_tolerance: float
    derivative_method: str
    difference_step: float
    truncation_estimate: float
    round_off_estimate: float
    kkt_condition: float
    map_error: float
    differences_error: float
    engine_differences_miss: float
    directions: Literal["whole Jacobians", "consistent directions"]
    contact_pairs: int
    limits: int
    states_rejected: dict[str, int]
    controls: dict[str, float]
    projection: Projection
    rows_left_out: list[str]


class Record(Details):
    """One results.json record: the common fields (metric only where an error is measured)
    and the Details."""

    model: str
    formulation: Formulation
    engine: str
    check: Check
    quantity: str
    error: float | None
    tolerance: float | None
    passed: bool | None
    skipped: bool
    reason: str
    metric: NotRequired[Metric]


class Series(TypedDict):
    """One line of the report's trajectory plots: one run of one engine (or the reference)."""

    model: str
    engine: str
    formulation: Formulation
    label: str
    t: list[float]
    state_error: list[float]
    residual: list[float]
    energy: list[float]
    work: NotRequired[list[float]]
    energy_kind: NotRequired[str]
    state_error_kind: NotRequired[str]
    reference_label: NotRequired[str]
    variant: NotRequired[str]


class AgreementMatrix(TypedDict):
    """Every side (the reference, each engine model) against every other on one quantity of
    one model (crosscheck.checks.agreement)."""

    model: str
    quantity: Literal["accelerations", "multipliers"]
    sides: list[str]
    errors: list[list[float]]
    bounds: list[list[float]]
    odd_one_out: str | None
    metric: str
    bound_reason: str


class Machine(TypedDict):
    """The machine a run ran on."""

    platform: str
    processor: str
    cpus: int | None


class Metrics(TypedDict):
    """Each metric a record may name, as a formula."""

    scaled_error: str
    relative_energy_error: str
    relative_miss: str


class Meta(TypedDict, total=False):
    """The run's provenance (every `crosscheck run` writes every field)."""

    command: str
    versions: dict[str, str | None]
    machine: Machine
    date: str
    states_per_model: int
    state_seed: str
    jobs: int
    metrics: Metrics


class Results(TypedDict):
    """results.json as `crosscheck run` writes it."""

    meta: Meta
    records: list[Record]
    series: NotRequired[list[Series]]
    agreement: NotRequired[list[AgreementMatrix]]


DETAIL_FIELDS = frozenset(Details.__optional_keys__)


def _check_details(details: Mapping[str, object]) -> None:
    unknown = sorted(set(details) - DETAIL_FIELDS)
    if unknown:
        raise TypeError(
            f"record detail field(s) {', '.join(map(repr, unknown))} are not part of the "
            f"results.json contract: declare them in crosscheck.checks.records.Details and in "
            f"crosscheck/schema/results.schema.json (with docs/results.md), or leave them out"
        )


def record(
    model: str,
    formulation: str,
    engine: str,
    check: str,
    quantity: str,
    error: float | None,
    tolerance: Tolerance | None,
    reason: str = "",
    metric: str = "scaled_error",
    **details: Unpack[Details],
) -> Record:
    """One results.json record.

    Parameters
    ----------
    model, formulation, engine, check, quantity
        What the record is about (the gate's key, with ``variant``).
    error
        The measured figure in ``metric``, or None where nothing was measured.
    tolerance
        The named tolerance it is judged against; None makes the record a skip (not judged,
        no error), with the reason.
    reason
        Why the record is skipped, or the judged record's own reason (default: the
        tolerance's).
    metric
        The name of the error's metric (crosscheck.checks.tolerances.METRICS); judged records
        only.
    **details
        The Details fields that apply.

    Returns
    -------
    Record
        passed is whether the error is finite and within the tolerance (None on a skip).

    Raises
    ------
    TypeError
        A detail field that is not declared in Details.
    """
    _check_details(details)
    base: dict[str, Any] = {
        "model": model,
        "formulation": formulation,
        "engine": engine,
        "check": check,
        "quantity": quantity,
    }
    if tolerance is None:
        base |= {"error": None, "tolerance": None, "passed": None, "skipped": True}
        return cast(Record, base | {"reason": reason} | dict(details))
    passed = bool(error is not None and np.isfinite(error) and error <= tolerance.value)
    base |= {
        "error": None if error is None else float(error),
        "tolerance": tolerance.value,
        "passed": passed,
        "skipped": False,
        "reason": reason or tolerance.reason,
        "metric": metric,
    }
    return cast(Record, base | dict(details))


def annotated(rec: Record, **details: Unpack[Details]) -> Record:
    """The record with more detail fields (an engine's notes on its records).

    Raises
    ------
    TypeError
        A detail field that is not declared in Details.
    """
    _check_details(details)
    return cast(Record, dict(rec) | dict(details))


def reported(rec: Record, reason: str) -> Record:
    """A judged record turned into a reported one: its measured error and metric kept, not
    judged (skipped, passed None), the tolerance it was held to kept as judged_tolerance, with
    the reason it is not judged."""
    out: dict[str, Any] = dict(rec)
    out |= {
        "judged_tolerance": rec["tolerance"],
        "tolerance": None,
        "passed": None,
        "skipped": True,
        "reason": reason,
    }
    return cast(Record, out)
