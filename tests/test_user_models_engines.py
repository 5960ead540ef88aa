"""Engines on users' MJCF files: MuJoCo loads the file as it is,
Pinocchio gets a complete model built from MuJoCo's compiled one; dependent rows compare the
accelerations and J^T lambda (the minimum-norm multipliers)."""

from __future__ import annotations

from pathlib import Path

import pytest

from crosscheck.checks.instantaneous import engine_records
from crosscheck.engines.registry import get_engine
from crosscheck.run.checks import consistent_states
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


def test_pin_parser_findings_name_the_lost_elements():
    from crosscheck.engines.pinocchio.parser_findings import findings_isolated

    found = findings_isolated(DATA / "fourbar_connect.xml")
    kinds = {(f["kind"], f["element"]) for f in found}
    # pin 4.1 reads only the first subtree of <worldbody> and no geom-derived masses
    assert ("body", "rocker") in kinds and ("joint", "B") in kinds
    assert ("mass", "crank") in kinds


def test_pin_user_file_trajectory_follows_reference():
    import numpy as np

    (name,) = register_all(load_model_file(DATA / "fourbar_connect.xml"))
    mdl = models.get(name)
    em = get_engine("pinocchio").build(name)
    tr = em.simulate(
        np.array(mdl.initial_q),
        np.array(mdl.initial_u),
        [0.0, 0.5, 1.0],
        integrator="DOP853",
        rtol=1e-10,
    )
    assert tr.failure is None and tr.q.shape == (3, 3)
    assert np.max(tr.violation) < 1e-7  # no stabilization: drift of the integrator's size
    assert abs(tr.energy[-1] - tr.energy[0]) < 1e-7 * max(1.0, abs(tr.energy[0]))
