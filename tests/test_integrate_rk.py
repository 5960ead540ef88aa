"""reference.integrate.rk.LeanDOP853: scipy's DOP853 with a leaner step takes scipy's steps.

Tolerances and why:
- SAME_STATE: the stage sums are formed in another order ((h a_s) . K[:s] against scipy's
  (K[:s]^T a_s) h), so states differ by round-off propagated over ~140 steps: measured
  2.5e-13 on the slider-crank at rtol 1e-10 (states of size ~10); 1e-11 leaves a margin and is
  100x below the run's own error (5e-9).
- STEP_TIMES: the error estimate is a difference of stages, ~1e-10 of their size at rtol 1e-10,
  so their round-off moves it by ~1e-6 relative and each step size by ~1e-7 relative (the
  exponent 1/8): measured max |t_lean - t_scipy| 1.3e-8 over the 137 steps; 1e-6 is still a
  thousandth of the smallest step (8e-3).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate as si

from crosscheck.bench import workprecision
from reference import NumericModel, models
from reference.integrate import common as ic
from reference.integrate.driver import simulate
from reference.integrate.rk import LeanDOP853
from reference.minimal import reference_final_state

SAME_STATE = 1e-11
STEP_TIMES = 1e-6


@pytest.fixture(scope="module")
def sc():
    return NumericModel(models.get("slider_crank"))


@pytest.mark.parametrize("method", ["index1", "projection"])
def test_lean_dop853_takes_scipys_steps(sc, method, monkeypatch):
    m = sc.model
    runs = {}
    for cls in (si.DOP853, LeanDOP853):
        monkeypatch.setitem(ic.INTEGRATORS, "DOP853", cls)
        runs[cls] = simulate(
            sc, m.initial_q, m.initial_u, 2.0, method, rtol=1e-10, atol=1e-10, stepper="python"
        )
    a, b = runs[si.DOP853], runs[LeanDOP853]
    assert (a.nfev, a.nsteps) == (b.nfev, b.nsteps)
    np.testing.assert_allclose(b.t, a.t, rtol=0, atol=STEP_TIMES)
    assert np.max(np.abs(b.final_state - a.final_state)) < SAME_STATE
    if method == "projection":
        assert b.stats["projections"] == b.nsteps


def test_lean_dop853_dense_output_matches_scipys(sc, monkeypatch):
    m = sc.model
    te = np.linspace(0.0, 1.0, 11)
    runs = []
    for cls in (si.DOP853, LeanDOP853):
        monkeypatch.setitem(ic.INTEGRATORS, "DOP853", cls)
        runs.append(
            simulate(sc, m.initial_q, m.initial_u, 1.0, "projection", t_eval=te, stepper="python")
        )
    assert np.array_equal(runs[0].t, runs[1].t)
    assert np.max(np.abs(runs[0].q - runs[1].q)) < SAME_STATE
    assert np.max(np.abs(runs[0].u - runs[1].u)) < SAME_STATE


def test_timed_reference_runs_leave_out_the_work_but_keep_the_energy_check(sc):
    """The work-precision timing integrates the motion only; the slider-crank's work-energy
    balance still comes out of an untimed run with W (its torque does work)."""
    ref = reference_final_state("slider_crank", workprecision.horizon("slider_crank"))
    (rec,) = workprecision.reference_records(
        "slider_crank", True, ref, sc, methods=("projection",), ladder=(1e-8,)
    )
    assert rec["timed_energy"] == "none"
    assert rec["bookkeeping"] is True
    assert rec["energy_drift"] is not None and rec["energy_drift"] < 1e-6
    assert rec["error"] < 1e-5 and rec["residual"] < 1e-12
