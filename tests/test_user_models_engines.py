"""Engines on users' MJCF files (issue 11 items 3 and 4): MuJoCo loads the file as it is,
Pinocchio gets a complete model built from MuJoCo's compiled one; dependent rows compare the
accelerations and J^T lambda (the minimum-norm multipliers)."""
from __future__ import annotations

from pathlib import Path

import pytest

from crosscheck.comparison import engine_records
from crosscheck.engines.registry import get_engine
from crosscheck.run import consistent_states
from crosscheck.user_models import load_model_file, register_all
from reference import NumericModel, models

DATA = Path(__file__).parent / "data"


def _records(file: str, engine: str, n_states: int = 3):
    (name,) = register_all(load_model_file(DATA / file))
    nm = NumericModel(models.get(name))
    adapter = get_engine(engine)
    assert name in adapter.models()
    return engine_records(name, nm, consistent_states(nm, n_states), adapter, nm.params)


@pytest.mark.parametrize("engine", ["mujoco", "pinocchio"])
@pytest.mark.parametrize("file", ["fourbar_connect.xml", "weld_sites.xml", "pendulum_hinge.xml"])
def test_user_file_passes_in_engine(file, engine):
    recs = _records(file, engine)
    judged = {r["quantity"]: r for r in recs if r["passed"] is not None}
    assert "accelerations" in judged, recs
    bad = [(r["quantity"], r["error"], r["tolerance"]) for r in judged.values() if not r["passed"]]
    assert not bad, bad
