"""Exudyn on floating-base MJCF files: a ball or free joint with joints below it is built as
Euler-angle links of the tree (crosscheck.engines.exudyn.user_system), checked against the
reference at seeded states: accelerations, multipliers, J^T lambda, the mass matrix, energy."""

from __future__ import annotations

from pathlib import Path

import pytest

from crosscheck.checks.instantaneous import engine_records
from crosscheck.engines.registry import get_engine
from crosscheck.run.checks import consistent_states
from crosscheck.user_models import load_model_file, register_all
from reference import NumericModel, models

DATA = Path(__file__).parent / "data"


def _judged(path: Path, states: int) -> dict:
    (name,) = register_all(load_model_file(path))
    nm = NumericModel(models.get(name))
    recs = engine_records(name, nm, consistent_states(nm, states), get_engine("exudyn"), nm.params)
    return {r["quantity"]: r for r in recs if r["passed"] is not None}


def _assert_all_pass(judged: dict) -> None:
    expected = {"accelerations", "multipliers", "constraint_forces", "mass_matrix", "energy"}
    assert expected <= set(judged), judged
    bad = [(r["quantity"], r["error"], r["tolerance"]) for r in judged.values() if not r["passed"]]
    assert not bad, bad


def test_floating_bases_with_hinges_pass():
    """A free torso with a hinged arm, a free base with a damped ball-jointed link and a hinged
    grandchild, and a loop closed by a connect on a free base."""
    _assert_all_pass(_judged(DATA / "floating_hinges.xml", 3))


def test_floating_joint_is_tree_links():
    """The three free joints and the ball are links of the tree: no Euler-parameter body."""
    (name,) = register_all(load_model_file(DATA / "floating_hinges.xml"))
    em = get_engine("exudyn").build(name)
    assert not em.ep and len(em.euler) == 4
    assert len(em.links) == 3 * 6 + 3 + 5  # free joints 6 each, the ball 3, five hinges


@pytest.mark.slow
def test_cassie_passes():
    """Cassie (a free pelvis, damped ball joints on the achilles rods, four connects)."""
    _assert_all_pass(_judged(DATA / "real" / "pinocchio_cassie.xml", 2))
