"""Issue 14: the blind spots of the suite, each closed and held here."""
from __future__ import annotations

import numpy as np
import pytest

from crosscheck.sampling import physical, random_params
from reference import models


@pytest.mark.parametrize("name", ["double_pendulum_3d", "frame_bar", "top_euler"])
def test_sampler_draws_inertias_apart_and_physical(name):
    """No two inertias of a draw keep one common factor (a swapped axis would cancel), and
    every body's principal inertias satisfy the triangle inequalities."""
    model = models.get(name)
    defaults = {p.name: p.default for p in model.parameters}
    inertias = [p.name for p in model.parameters if p.unit == "kg m^2"]
    rng = np.random.default_rng(3)
    for _ in range(50):
        params = random_params(model, rng)
        factors = {round(params[n] / defaults[n], 12) for n in inertias}
        assert len(factors) == len(inertias), factors
        for body in model.bodies:
            diag = [body.inertia[i, i] for i in range(3)]
            if all(d != 0 for d in diag):
                assert physical([params[str(d)] for d in diag], {}), params


def test_run_checks_the_generic_parameter_set_as_records_of_their_own():
    """`run` repeats the instantaneous checks at reference.generic's parameter set, under
    check names of their own (the gate sees them as new records, not as changed ones)."""
    from crosscheck.run import generic_model, run
    records, _ = run(["pendulum_xy"], ["pinocchio"], n_states=2, trajectories=False)
    checks = {r["check"] for r in records if r["engine"] == "pinocchio"}
    assert checks == {"instantaneous", "instantaneous_generic"}
    generic = [r for r in records if r["check"] == "instantaneous_generic"]
    assert generic and all(r["passed"] is not False for r in generic)
    defaults = {p.name: p.default for p in models.get("pendulum_xy").parameters}
    assert all(v != defaults[k] for k, v in generic_model("pendulum_xy").params.items())
