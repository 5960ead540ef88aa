"""The tiers hold by construction: a test starts child processes only through the `child`
fixtures (so it is in the subprocess tier), and every mark a test module uses is a declared
tier or one of pytest's own."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from tests.conftest import FIXTURE_TIERS, TIERS

TESTS = Path(__file__).resolve().parent
# the one module that runs child processes, behind the fixtures of conftest.py
SUPPORT = TESTS / "support.py"
STARTS_A_PROCESS = {
    ("subprocess", name) for name in ("run", "Popen", "call", "check_call", "check_output")
} | {("os", name) for name in ("system", "popen", "spawnv", "execv", "fork")}
PYTEST_MARKS = {"parametrize", "skipif", "skip", "xfail", "usefixtures", "filterwarnings"}


def _modules():
    return sorted(p for p in TESTS.rglob("*.py") if p != SUPPORT)


def _attribute_calls(tree):
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            if isinstance(node.func.value, ast.Name):
                yield node.func.value.id, node.func.attr, node.lineno


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(TESTS)))
def test_child_processes_start_only_through_the_fixtures(path):
    tree = ast.parse(path.read_text())
    found = [
        f"{path.name}:{line}: {mod}.{name}()"
        for mod, name, line in _attribute_calls(tree)
        if (mod, name) in STARTS_A_PROCESS
    ]
    assert not found, (
        "a test starts a process without the `child` fixture, so the quick tier would run it: "
        + "; ".join(found)
    )


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(TESTS)))
def test_every_mark_is_a_tier_or_pytests_own(path):
    tree = ast.parse(path.read_text())
    marks = {
        node.attr
        for node in ast.walk(tree)
        if isinstance(node, ast.Attribute)
        and isinstance(node.value, ast.Attribute)
        and node.value.attr == "mark"
    }
    assert marks <= set(TIERS) | PYTEST_MARKS, marks - set(TIERS) - PYTEST_MARKS


def test_each_tier_deciding_fixture_names_a_declared_tier():
    assert set(FIXTURE_TIERS.values()) <= set(TIERS)


def test_the_guard_sees_a_direct_call():
    """The first check can fail: a module calling subprocess.run is caught."""
    tree = ast.parse("import subprocess\nsubprocess.run(['true'])\n")
    assert [(m, n) for m, n, _ in _attribute_calls(tree)] == [("subprocess", "run")]
