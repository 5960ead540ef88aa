"""Shared test configuration: the tiers, the fixtures that decide a test's tier, and the
hypothesis profiles.

Tiers. `python -m pytest` runs the quick tier: every module, each engine on its representative
models, each command once in this process, the property tests with a small example budget.
`python -m pytest --full` (CI) runs every tier and the property tests at their CI budget. A
test's tier follows from what it asks for, not from a mark written on it:
- subprocess: the `child` fixture (the `crosscheck` program or Python in a child process);
- cold: the `fresh_cache` fixture (derivations and builds in an empty cache);
- browser: the `chromium` fixture (the report rendered in headless Chromium);
- slow: a long check of its own (a full-length stress scene, `crosscheck bench --quick`), or a
  case beyond a parametrization's representative ones (tests.support.representative).
Every other test shares the derivation cache of the session (CROSSCHECK_CACHE_DIR, or the
user's cache), so only the cold tier pays for derivations more than once.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

from tests.support import Child

TIERS = {
    "subprocess": "starts the crosscheck program or Python in a child process (fixture child)",
    "cold": "derives and builds in an empty derivation cache (fixture fresh_cache)",
    "browser": "renders the report in headless Chromium (fixture chromium)",
    "slow": "a long check, or a case beyond a parametrization's representative ones",
}
FIXTURE_TIERS = {
    "child": "subprocess",
    "session_child": "subprocess",
    "fresh_cache": "cold",
    "chromium": "browser",
}
QUICK = "not (" + " or ".join(TIERS) + ")"

# CI and --full: derandomized (the same examples every run, so a red build is reproducible) at
# the CI budget; the quick tier: random exploration with a small budget. HYPOTHESIS_PROFILE
# chooses explicitly.
settings.register_profile(
    "ci",
    derandomize=True,
    max_examples=50,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "dev", max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


def pytest_addoption(parser):
    parser.addoption(
        "--full",
        action="store_true",
        help="run every tier (" + ", ".join(TIERS) + ") with the CI hypothesis budget",
    )


def pytest_configure(config):
    for name, what in TIERS.items():
        config.addinivalue_line("markers", f"{name}: {what}")
    full = config.getoption("--full")
    if full:
        config.option.markexpr = ""  # every tier
    elif not config.option.markexpr:
        config.option.markexpr = QUICK
    ci = full or os.environ.get("CI")
    settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci" if ci else "dev"))


def pytest_collection_modifyitems(config, items):
    for item in items:
        for fixture in FIXTURE_TIERS.keys() & set(getattr(item, "fixturenames", ())):
            item.add_marker(FIXTURE_TIERS[fixture])


def pytest_report_header(config):
    expr = config.option.markexpr
    return f"tiers: {'all (--full)' if not expr else expr} (see tests/conftest.py)"


@pytest.fixture(autouse=True)
def _in_own_tmp_path(tmp_path, monkeypatch):
    """Every test runs in its own temporary directory, so the commands' default paths (out/,
    out/results.json) resolve there and no test reads what an earlier command left in the
    checkout (the README's second command once failed after its first)."""
    monkeypatch.chdir(tmp_path)


@pytest.fixture
def child(tmp_path) -> Child:
    """Child processes of this test (the subprocess tier)."""
    return Child(tmp_path)


@pytest.fixture(scope="session")
def session_child(tmp_path_factory) -> Child:
    """Child processes for a fixture that outlives one test (a module's real runs), in the
    subprocess tier like `child`."""
    return Child(tmp_path_factory.mktemp("children"))


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch) -> Path:
    """An empty derivation cache for this test and its child processes (the cold tier)."""
    cache = tmp_path / "derivation-cache"
    cache.mkdir()
    monkeypatch.setenv("CROSSCHECK_CACHE_DIR", str(cache))
    return cache


CHROMIUM = "/usr/bin/chromium"


@pytest.fixture
def chromium() -> str:
    """Headless Chromium's path (the browser tier). scripts/install-test-deps installs it where
    apt-get can; elsewhere the test is skipped, saying why."""
    path = shutil.which("chromium") or (CHROMIUM if os.path.exists(CHROMIUM) else None)
    if path is None:
        pytest.skip(
            f"{CHROMIUM} not installed (Debian package `chromium`: apt-get install -y chromium); "
            "the browser check needs it"
        )
    return path
