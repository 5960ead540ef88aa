"""Loading and checking the JSON files the report and the gate read (results.json, bench.json,
sweep.json): a missing or malformed input is one line naming the file and the way out."""

from __future__ import annotations

import json
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


def _record_problem(r) -> str | None:
    """What is wrong with one record, or None: the fields every report and gate reads."""
    if not isinstance(r, dict):
        return "is not an object"
    for key in ("model", "engine", "check", "quantity"):
        if not isinstance(r.get(key), str) or not r[key]:
            return f"has no {key!r} name"
    if r.get("passed") not in (True, False, None):
        return f'has "passed": {r.get("passed")!r} (expected true, false or null)'
    for key in ("error", "tolerance"):
        v = r.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))):
            return f"has {key!r}: {v!r} (expected a number or null)"
    if r.get("passed") is not None and r.get("tolerance") is None:
        return 'is judged ("passed" set) but has no tolerance'
    return None


def check_results(data: dict, path) -> dict:
    recs = data.get("records")
    if not isinstance(recs, list):
        raise ReportInputError(
            f'results file {str(path)!r} has no "records" list of objects '
            f"(is it a results.json written by `crosscheck run`?)"
        )
    for i, r in enumerate(recs):
        problem = _record_problem(r)
        if problem:
            raise ReportInputError(
                f"results file {str(path)!r}: record {i} {problem} (is it "
                f"a results.json written by `crosscheck run`?)"
            )
    series = data.get("series")
    if series is not None and not (
        isinstance(series, list) and all(isinstance(s, dict) for s in series)
    ):
        raise ReportInputError(f'results file {str(path)!r}: "series" must be a list of objects')
    return data


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
