"""The JSON Schema of results.json (draft 2020-12), shipped with the package: the contract the
report and the gate validate every results file against (crosscheck.report.inputs), described
for users in docs/results.md and for Python in crosscheck.checks.records."""

from __future__ import annotations

import json
from functools import cache
from importlib import resources

RESULTS_SCHEMA = "results.schema.json"


@cache
def results_schema() -> dict:
    """The schema of results.json, as shipped in this package.

    Returns
    -------
    dict
        The schema; its "$defs" hold the record, series and agreement-matrix schemas, and the
        gate's baseline file (which holds results.json records).
    """
    return json.loads(resources.files(__name__).joinpath(RESULTS_SCHEMA).read_text("utf-8"))
