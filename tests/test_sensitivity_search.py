"""The decade search of `crosscheck sensitivity`: smallest caught decade, bounded cost."""

from __future__ import annotations

import math

import pytest

from crosscheck.checks.sensitivity import DECADES, search, threshold


@pytest.mark.parametrize("true_k", list(DECADES))
def test_finds_the_smallest_caught_decade(true_k):
    calls = []

    def evaluate(rel):
        calls.append(rel)
        return "m/e/instantaneous/accelerations" if rel >= 10.0**true_k * 0.999 else ""

    k, below, name, n = threshold(evaluate)
    assert k == true_k and name.endswith("accelerations")
    assert below == (true_k - 1 if true_k > DECADES[0] else None)
    assert n == len(calls) <= 1 + math.ceil(math.log2(len(DECADES)))


def test_nothing_caught_is_reported_with_the_reason():
    t = search("m", "e", "p", lambda rel: "")
    assert t.caught_at is None and t.not_caught_below == pytest.approx(0.1)
    assert "up to 1e-01" in t.reason and t.evaluations == 1


def test_an_unused_parameter_is_not_searched():
    t = search(
        "m",
        "e",
        "L",
        lambda rel: pytest.fail("must not evaluate"),
        unused_reason="the engine's model has no L",
    )
    assert t.caught_at is None and t.reason == "the engine's model has no L"


def test_a_trajectory_search_keeps_how_it_ran():
    """A search by another comparison says which, and keeps how it ran as the reason, caught
    or not (the horizon and parameter set of a trajectory search)."""
    how = "the trajectory comparison over 5 s at the textbook defaults"
    caught = search(
        "m",
        "e",
        "L",
        lambda rel: "m/e/trajectory/constraint_drift" if rel >= 1e-6 else "",
        comparison="trajectory",
        how=how,
    )
    assert caught.caught_at == pytest.approx(1e-6) and caught.reason == how
    assert caught.comparison == "trajectory" and caught.to_json()["comparison"] == "trajectory"
    missed = search("m", "e", "L", lambda rel: "", comparison="trajectory", how=how)
    assert missed.caught_at is None
    assert missed.reason == f"no trajectory check failed for a change of up to 1e-01: {how}"
