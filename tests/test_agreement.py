"""The agreement matrix: every side against every other, so that a fault
shows which side is the odd one out."""

from __future__ import annotations

import math

import pytest

from crosscheck.checks.agreement import odd_one_out, pair_error
from crosscheck.engines.registry import available_engines
from crosscheck.run.checks import run


def test_pair_error_is_symmetric_and_relative_to_the_larger_answer():
    assert pair_error([1.0, 2.0], [1.0, 2.0 + 1e-9]) == pytest.approx(1e-9 / (2.0 + 1e-9))
    assert pair_error([3.0], [1.0]) == pair_error([1.0], [3.0]) == pytest.approx(2.0 / 3.0)
    assert pair_error([0.1], [0.2]) == pytest.approx(0.1)  # at least 1 SI unit of scale
    assert pair_error([math.nan], [0.0]) == math.inf


def test_odd_one_out_needs_one_culprit_against_agreeing_others():
    sides = ["reference", "a", "b"]
    bounds = [[0.0, 1e-11, 1e-11], [1e-11, 0.0, 1e-11], [1e-11, 1e-11, 0.0]]
    bad_a = [[0.0, 1e-6, 1e-15], [1e-6, 0.0, 1e-6], [1e-15, 1e-6, 0.0]]
    assert odd_one_out(sides, bad_a, bounds) == "a"
    everyone = [[0.0, 1e-6, 1e-6], [1e-6, 0.0, 1e-6], [1e-6, 1e-6, 0.0]]
    assert odd_one_out(sides, everyone, bounds) is None  # no single side to blame
    assert odd_one_out(sides[:2], [[0.0, 1e-6], [1e-6, 0.0]], bounds) is None  # two: no vote


@pytest.mark.skipif(len(available_engines()) < 2, reason="needs two engines besides the reference")
def test_a_fault_in_one_engine_makes_it_the_odd_one_out():
    engines = list(available_engines())
    faulty = engines[0]
    clean, faulted = [], []
    run(["slider_crank"], engines, 2, trajectories=False, agreement=clean)
    run(["slider_crank"], engines, 2, {faulty: {"m2": 1e-6}}, trajectories=False, agreement=faulted)
    for m in clean:
        assert m["odd_one_out"] is None
        n = len(m["sides"])
        assert all(m["errors"][i][j] <= m["bounds"][i][j] for i in range(n) for j in range(n))
    acc = next(m for m in faulted if m["quantity"] == "accelerations")
    assert acc["sides"][0] == "reference" and faulty in acc["sides"]
    assert acc["odd_one_out"] == faulty
