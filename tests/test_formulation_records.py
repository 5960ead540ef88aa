"""The reference's formulations against each other: a comparison where the two derivations
generated different code, a skipped record that says so where they generated the same."""

from __future__ import annotations

import json

from crosscheck.checks.sampling import consistent_states
from crosscheck.run.checks import _formulation_records, _same_code
from reference import NumericModel, models
from tests.support import ROOT


def _records(name: str) -> list[dict]:
    nm = NumericModel(models.get(name))
    return _formulation_records(name, nm, consistent_states(nm, 2))


def test_identical_code_is_a_skip_that_says_so():
    records = _records("pendulum_xy")  # Lagrange, d'Alembert and Kane give the same code
    assert records and all(r["skipped"] and r["passed"] is None for r in records)
    assert all(r["error"] is None for r in records)
    assert all("generated the same code as lagrange" in r["reason"] for r in records)


def test_different_code_is_compared():
    records = _records("slider_crank")
    assert records and all(r["passed"] is True and not r["skipped"] for r in records)
    assert all(r["tolerance"] and r["error"] is not None for r in records)


def test_the_comparison_ignores_only_comments():
    src = "# generated for x / lagrange\nMETA = {}\ndef f(q):\n    return q\n"
    assert _same_code(src, src.replace("lagrange", "kane"))
    assert not _same_code(src, src.replace("return q", "return -q"))


def test_the_baseline_judges_no_formulation_whose_code_is_identical():
    """The committed baseline agrees with the rule: no passed record where the two
    formulations generate the same code (it would be a regression to a skip otherwise)."""
    baseline = json.loads((ROOT / "reports" / "baseline.json").read_text())
    judged = {
        (r["model"], r["formulation"])
        for r in baseline["records"]
        if r["engine"] == "reference" and r["check"].startswith("formulations") and r["passed"]
    }
    for name, formulation in sorted(judged):
        model = models.get(name)
        first = NumericModel(model, model.formulations[0], backend="python").source
        other = NumericModel(model, formulation, backend="python").source
        assert not _same_code(first, other), (name, formulation)
