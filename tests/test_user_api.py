"""crosscheck.check / assert_passes: the Python API for users' test suites."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

import crosscheck
from reference import models

DATA = Path(__file__).parent / "data"


def test_check_a_file_returns_its_records():
    records = crosscheck.check(
        DATA / "fourbar_connect.xml", engines=["pinocchio", "mujoco"], states=2
    )
    assert {r["model"] for r in records} == {"fourbar_connect"}
    acc = [r for r in records if r["quantity"] == "accelerations" and r["check"] == "instantaneous"]
    assert {r["engine"] for r in acc} == {"pinocchio", "mujoco"}
    assert all(r["passed"] for r in acc)


def test_assert_passes_returns_records_when_all_pass():
    records = crosscheck.assert_passes("pendulum_angle", engines=["pinocchio"], states=2)
    assert any(r["engine"] == "pinocchio" and r["passed"] for r in records)


def test_assert_passes_fails_with_the_worst_record():
    # a Model object whose mass differs from the file's: the engines (loading the MJCF) and
    # the reference (this Model) disagree, and the message names the worst record
    from crosscheck.user_models import load_model_file, register_all

    register_all(load_model_file(DATA / "pendulum_hinge.xml"))
    good = models.get("pendulum_hinge")
    src = models.user_source("pendulum_hinge")
    heavier = [dataclasses.replace(b, mass=b.mass * 2) for b in good.bodies[:1]]
    wrong = dataclasses.replace(good, bodies=(*heavier, *good.bodies[1:]))
    models.register(wrong, "test", src)
    try:
        with pytest.raises(AssertionError, match=r"pendulum_hinge \w+ instantaneous "):
            crosscheck.assert_passes("pendulum_hinge", engines=["mujoco"], states=2)
    finally:
        models.register(good, "test", src)


def test_check_refuses_an_unknown_name():
    from reference.errors import ModelInputError

    with pytest.raises(ModelInputError, match="unknown model"):
        crosscheck.check("no_such_model")
