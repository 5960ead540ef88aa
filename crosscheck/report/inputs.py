"""Loading and checking the JSON files the report and the gate read (results.json, bench.json,
sweep.json): a missing or malformed input is one line naming the file and the way out.

A results file is held to the JSON Schema shipped with the package
(crosscheck/schema/results.schema.json, described in docs/results.md): the gate then refuses a
results.json that breaks the contract instead of comparing it.
"""

from __future__ import annotations

import json
import math
from functools import cache
from pathlib import Path

from reference.errors import ModelInputError


class ReportInputError(ModelInputError):
    """A report input is missing or malformed (printed as one line, exit status 2)."""


def load_json(path: str | Path, what: str) -> dict:
    path = Path(path)
    if not path.is_file():
        raise ReportInputError(f"{what} file {str(path)!r} not found")
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ReportInputError(f"{what} file {str(path)!r} is not valid JSON: {exc}") from None
    if not isinstance(data, dict):
        raise ReportInputError(f"{what} file {str(path)!r}: expected a JSON object at the top")
    return data


def _record_problem(r) -> tuple[str, str] | None:
    """What is wrong with the names of one record (what every message of the report and the
    gate names it by) and the field it is in, or None; the schema checks the rest."""
    if not isinstance(r, dict):
        return "", "is not an object"
    for key in ("model", "engine", "check", "quantity"):
        if not isinstance(r.get(key), str) or not r[key]:
            return f".{key}", f"has no {key!r} name"
    return None


def _within(error, tolerance) -> bool:
    numbers = all(
        isinstance(x, (int, float)) and not isinstance(x, bool) for x in (error, tolerance)
    )
    return numbers and math.isfinite(error) and error <= tolerance


HINT = "is it a results.json written by `crosscheck run`? docs/results.md describes the fields"


def check_results(data: dict, path) -> dict:
    """A results file's records and the rest of its contract (the results.json schema, or for
    the gate's baseline the schema's "baseline").

    Parameters
    ----------
    data
        The file's contents (load_json).
    path
        The file, for the message.

    Returns
    -------
    dict
        data, unchanged.

    Raises
    ------
    ReportInputError
        The first violation, with its JSON path, and how many more there are.
    """
    recs = data.get("records")
    if not isinstance(recs, list):
        raise ReportInputError(
            f'results file {str(path)!r} has no "records" list of objects ({HINT})'
        )
    for i, r in enumerate(recs):
        problem = _record_problem(r)
        if problem:
            field, what = problem
            raise ReportInputError(
                f"results file {str(path)!r}: record {i} {what} ($.records[{i}]{field}; {HINT})"
            )
    violations = schema_violations(data)
    if violations:
        more = len(violations) - 1
        raise ReportInputError(
            f"results file {str(path)!r}: {violations[0]}"
            + (f" ({more} more violation{'s' * (more > 1)} after it)" if more else "")
            + f" ({HINT})"
        )
    for i, r in enumerate(recs):
        # the suite passes a record only on a finite error within its tolerance (records.record):
        # a file that says otherwise was not written by it, and no verdict may come from it
        if r.get("passed") is True and not _within(r.get("error"), r.get("tolerance")):
            raise ReportInputError(
                f"results file {str(path)!r}: record {i} says passed although its error "
                f"{r.get('error')!r} is not a finite number within its tolerance "
                f"{r.get('tolerance')!r} ($.records[{i}].passed; {HINT})"
            )
    return data


def is_baseline(data: dict) -> bool:
    """Whether a results file is the gate's baseline (`crosscheck gate --update` writes
    meta.results_meta), which holds results.json records under a top level of its own."""
    meta = data.get("meta")
    return isinstance(meta, dict) and "results_meta" in meta


@cache
def _validator(baseline: bool):
    from jsonschema import Draft202012Validator

    from crosscheck.schema import results_schema

    root = results_schema()
    # the baseline is a $def of the same schema: its records are held to the same record schema
    schema = {"$defs": root["$defs"], "$ref": "#/$defs/baseline"} if baseline else root
    return Draft202012Validator(schema)


def schema_violations(data: dict) -> list[str]:
    """Every way `data` breaks the results.json schema, one line each, in the validator's order
    (the document's top level, then its records, series and agreement in turn); [] when it
    follows it. A gate baseline (is_baseline) is held to the schema's "baseline".

    Parameters
    ----------
    data
        A results file as json.loads read it.

    Returns
    -------
    list of str
        Each violation as "<JSON path>: <what is wrong>[; <the record rule it breaks>]".
    """
    validator = _validator(is_baseline(data))
    return [_describe(e, validator.schema) for e in validator.iter_errors(data)]


def _short(value) -> str:
    """A value as JSON, cut to a readable length."""
    text = json.dumps(value, default=repr)
    return text if len(text) <= 60 else text[:57] + "..."


def _describe(error, schema: dict) -> str:
    """One violation on one line: where, what, and the record rule it breaks."""
    kind, expected = error.validator, error.validator_value
    if kind == "const":
        what = f"expected {_short(expected)}, got {_short(error.instance)}"
    elif kind == "type":
        types = [expected] if isinstance(expected, str) else expected
        what = f"expected {' or '.join(types)}, got {_short(error.instance)}"
    elif kind == "enum":
        what = f"{_short(error.instance)} is not one of {', '.join(map(_short, expected))}"
    elif kind == "not" and expected == {}:  # {"not": {}}: the field is not allowed here
        what = f"not allowed here (got {_short(error.instance)})"
    else:
        what = error.message if len(error.message) <= 200 else error.message[:197] + "..."
    rule = _rule(schema, list(error.schema_path))
    line = f"{error.json_path}: {what}" + (f"; {rule}" if rule else "")
    return " ".join(line.split())  # one line, whatever the values hold


def _rule(schema: dict, schema_path: list) -> str | None:
    """The description of the innermost allOf rule on the error's schema path (the record's
    rules: passed null exactly when skipped, ...), or None."""
    node, rule, previous = schema, None, None
    try:
        for key in schema_path:
            # the validator's path steps through a $ref without naming it
            while isinstance(node, dict) and key not in node and "$ref" in node:
                node = _resolve(schema, node["$ref"])
            node = node[key]
            if previous == "allOf" and isinstance(node, dict) and "description" in node:
                rule = node["description"]
            previous = key
    except (KeyError, IndexError, TypeError):
        pass
    return rule


def _resolve(schema: dict, ref: str):
    """A local reference (#/$defs/...) in the schema."""
    node = schema
    for part in ref.removeprefix("#/").split("/"):
        node = node[part]
    return node


def check_bench(data: dict, path) -> dict:
    for key in ("forward", "work_precision"):
        rows = data.get(key, [])
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            raise ReportInputError(
                f'bench file {str(path)!r}: "{key}" must be a list of '
                f"objects (is it a bench.json written by `crosscheck bench`?)"
            )
    if "forward" not in data and "work_precision" not in data:
        raise ReportInputError(
            f'bench file {str(path)!r} has neither "forward" nor '
            f'"work_precision" (is it a bench.json?)'
        )
    return data


def check_sweep(data: dict, path) -> dict:
    rows = data.get("results")
    if (
        not isinstance(rows, list)
        or not all(isinstance(r, dict) for r in rows)
        or not isinstance(data.get("status"), dict)
    ):
        raise ReportInputError(
            f'sweep file {str(path)!r} has no "results" list of objects '
            f'and "status" object (is it a sweep.json written by '
            f"`crosscheck sweep`?)"
        )
    return data
