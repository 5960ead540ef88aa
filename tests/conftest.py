"""Shared test configuration: deterministic hypothesis profiles and consistent-state helpers."""
from __future__ import annotations

import os

import numpy as np
from hypothesis import HealthCheck, settings

# CI: derandomized (the same examples every run) so a red build is reproducible; dev: random
# exploration with the same example budget. Select with HYPOTHESIS_PROFILE.
settings.register_profile("ci", derandomize=True, max_examples=25, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("dev", max_examples=25, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci" if os.environ.get("CI") else "dev"))


def random_consistent_state(nm, rng, q_spread=0.3, u_spread=1.0, t=0.0):
    """A random state near the model's initial state, projected onto its constraint manifold."""
    m = nm.model
    q = np.asarray(m.initial_q, float) + q_spread * rng.standard_normal(len(m.initial_q))
    u = np.asarray(m.initial_u, float) + u_spread * rng.standard_normal(len(m.initial_u))
    return nm.project(q, u, t)


def loadable_models() -> list[str]:
    """Registered models whose module imports; test_registry fails loudly for any other."""
    from reference import models
    out = []
    for name in models.names():
        try:
            models.get(name)
        except ModuleNotFoundError:
            continue
        out.append(name)
    return out
