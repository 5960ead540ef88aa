"""The hand-out order of `crosscheck run --jobs N` (crosscheck/run/order.py): models without a
time first, then the longest; the times file survives damage and keeps other settings."""

from __future__ import annotations

import pytest

from crosscheck.run import order as run_order


@pytest.fixture
def times_file(tmp_path, monkeypatch):
    path = tmp_path / run_order.FILE
    monkeypatch.setattr(run_order, "_path", lambda: path)
    return path


def test_unknown_models_first_then_the_longest():
    names = ["a", "b", "c", "d", "e"]
    times = {"a": 1.0, "c": 5.0, "d": 1.0, "e": 2.0}
    # b has no time: first; then c (5), e (2), and a before d (a tie, in the models' order)
    assert run_order.hand_out_order(names, times) == [1, 2, 4, 0, 3]
    assert run_order.hand_out_order(names, {}) == [0, 1, 2, 3, 4]


def test_times_are_merged_per_setting(times_file):
    key = run_order.setting_key(("pinocchio", "mujoco"), 6, True, 5.0)
    other = run_order.setting_key(("pinocchio",), 6, False, 5.0)
    assert key != other
    run_order.remember_times(key, {"a": 1.5, "b": 2.0})
    run_order.remember_times(other, {"a": 9.0})
    run_order.remember_times(key, {"b": 3.0})  # a run of b alone keeps a's time
    assert run_order.known_times(key) == {"a": 1.5, "b": 3.0}
    assert run_order.known_times(other) == {"a": 9.0}


@pytest.mark.parametrize(
    "content", ["{not json", "[1, 2]", '{"k": [1]}', '{"k": {"a": "slow", "b": -1, "c": true}}']
)
def test_a_damaged_times_file_only_loses_the_order(times_file, content):
    """Unreadable content gives no times (the models' order) and the next run rewrites it."""
    times_file.write_text(content)
    assert run_order.known_times("k") == {}
    run_order.remember_times("k", {"a": 2.0})
    assert run_order.known_times("k") == {"a": 2.0}


def test_an_unwritable_cache_leaves_the_run_alone(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setattr(run_order, "_path", lambda: blocker / run_order.FILE)  # not a directory
    run_order.remember_times("k", {"a": 1.0})  # no exception
    assert run_order.known_times("k") == {}
