"""An engine integrated by the reference's own DOP853 stepper (Capabilities.reference_integrators,
Pinocchio) is run once per trajectory, its state tolerance the reference's measured error at
that rtol; any other error-controlled engine integrator is also run at 10x the rtol, and that
run's difference is added to the tolerance (its error per rtol is not the reference's)."""

from __future__ import annotations

import dataclasses

import pytest

from crosscheck.checks.trajectory import check as T
from crosscheck.engines.base import Capabilities
from crosscheck.engines.pinocchio.engine_model import INTEGRATORS, PinEngineModel, ivp_method
from crosscheck.engines.registry import get_engine
from reference import NumericModel, models
from reference.integrate.rk import LeanDOP853


def _state_records_and_rtols(monkeypatch, adapter):
    rtols = []
    simulate = PinEngineModel.simulate

    def counted(self, *args, **kwargs):
        rtols.append(kwargs["rtol"])
        return simulate(self, *args, **kwargs)

    monkeypatch.setattr(PinEngineModel, "simulate", counted)
    nm = NumericModel(models.get("pendulum_xy"))
    records, _ = T.trajectory_records("pendulum_xy", nm, [adapter], 0.2)
    state = [r for r in records if r["engine"] == "pinocchio" and r["quantity"] == "state_error"]
    assert len(state) == 1 and state[0]["passed"], state
    return state[0], rtols


def test_the_reference_stepper_runs_once_and_says_why(monkeypatch):
    adapter = get_engine("pinocchio")
    assert adapter.capabilities.reference_integrators == INTEGRATORS
    assert all(ivp_method(i) is LeanDOP853 for i in adapter.capabilities.reference_integrators)
    record, rtols = _state_records_and_rtols(monkeypatch, adapter)
    assert rtols == [T.ENGINE_RTOL]
    assert "integrated by that same stepper" in record["reason"]
    assert "own error" not in record["reason"]


def test_another_adaptive_integrator_adds_its_own_error(monkeypatch):
    adapter = get_engine("pinocchio")
    caps = dataclasses.replace(adapter.capabilities, reference_integrators=())
    monkeypatch.setattr(type(adapter), "capabilities", caps)
    record, rtols = _state_records_and_rtols(monkeypatch, adapter)
    assert rtols == [T.ENGINE_RTOL, 10 * T.ENGINE_RTOL]
    assert "own error estimated against its run at rtol 1e-09" in record["reason"]


def test_reference_integrators_must_be_adaptive():
    with pytest.raises(ValueError, match="reference_integrators"):
        Capabilities(
            multipliers=True,
            exact=True,
            integrators=("DOP853", "Euler"),
            adaptive_integrators=("DOP853",),
            reference_integrators=("Euler",),
        )
