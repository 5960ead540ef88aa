"""Shared test configuration: deterministic hypothesis profiles."""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, settings

# CI: derandomized (the same examples every run) so a red build is reproducible; dev: random
# exploration with the same example budget. Select with HYPOTHESIS_PROFILE.
settings.register_profile(
    "ci",
    derandomize=True,
    max_examples=25,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "dev", max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci" if os.environ.get("CI") else "dev"))


@pytest.fixture(autouse=True)
def _in_own_tmp_path(tmp_path, monkeypatch):
    """Every test runs in its own temporary directory, so the commands' default paths (out/,
    out/results.json) resolve there and no test reads what an earlier command left in the
    checkout (the README's second command once failed after its first)."""
    monkeypatch.chdir(tmp_path)
