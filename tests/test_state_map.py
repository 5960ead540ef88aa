"""The state map's round trip (reference -> engine -> reference) on angles read back with
atan2: a whole turn is the same configuration only where the engine says so."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crosscheck.checks.instantaneous import build, whole_turns_removed
from crosscheck.engines.registry import available_engines, get_engine
from reference import NumericModel, models

# sweep seed 4 sample 322: theta21 = -3.28 (outside (-pi, pi]) came back as 3.00
Q_TURNED = [-1.5633, 1.9119, 0.9827, -3.2804, 0.8815, 1.8680]


@pytest.mark.parametrize("engine", available_engines())
def test_an_angle_beyond_pi_round_trips_to_the_same_configuration(engine):
    adapter = get_engine(engine)
    if "double_pendulum_3d" not in adapter.models():
        pytest.skip(f"{engine} does not express double_pendulum_3d")
    nm = NumericModel(models.get("double_pendulum_3d"))
    q, u = nm.project(Q_TURNED, np.linspace(-0.5, 0.5, nm.n))
    em = build(adapter, "double_pendulum_3d", None, None)
    qe, ve = em.to_engine_state(q, u)
    q2, _ = em.from_engine_state(qe, ve)
    assert abs(q2[3] - q[3]) > math.pi  # read back a turn away: the case at hand
    fixed = whole_turns_removed(em, q, u, q2, qe)
    assert np.max(np.abs(fixed - q)) < 1e-12


def test_a_turn_the_engine_does_not_confirm_stays_an_error():
    """pendulum_xy's coordinates are Cartesian: a map that added 2 pi to x would be a wrong
    configuration, and to_engine_state says so; the difference is kept."""
    adapter = get_engine(available_engines()[0])
    nm = NumericModel(models.get("pendulum_xy"))
    q, u = nm.project([0.3, -0.9], [0.2, 0.1])
    em = build(adapter, "pendulum_xy", None, None)
    qe, _ = em.to_engine_state(q, u)
    wrong = np.asarray(q, float) + np.array([2 * math.pi, 0.0])
    assert np.allclose(whole_turns_removed(em, q, u, wrong, qe), wrong)
