"""crosscheck.check / assert_passes: the Python API for users' test suites."""

from __future__ import annotations

import dataclasses
import re
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


@pytest.mark.parametrize(
    "kw,problem",
    [
        ({"states": 0}, "states=0"),
        ({"states": 2.5}, "states=2.5"),
        ({"states": True}, "states=True"),
        ({"states": 10**20}, "states=100000000000000000000"),
        ({"t_end": float("nan")}, "t_end=nan"),
        ({"t_end": float("inf")}, "t_end=inf"),
        ({"t_end": 0}, "t_end=0"),
    ],
)
def test_check_refuses_bad_numbers_before_any_work(kw, problem):
    from reference.errors import ModelInputError

    with pytest.raises(ModelInputError, match=re.escape(problem)):
        crosscheck.check("pendulum_xy", ["mujoco"], **kw)


def test_check_names_every_bad_number_at_once():
    from reference.errors import ModelInputError

    with pytest.raises(ModelInputError) as exc:
        crosscheck.check("pendulum_xy", ["mujoco"], states=-1, t_end=-2.0)
    assert "states=-1" in str(exc.value) and "t_end=-2.0" in str(exc.value)


def test_an_engines_string_is_comma_separated_names_not_letters():
    records = crosscheck.check("pendulum_xy", "mujoco", states=1)
    assert {r["engine"] for r in records} == {"reference", "mujoco"}
    from reference.errors import ModelInputError

    with pytest.raises(ModelInputError, match="'muj'"):
        crosscheck.check("pendulum_xy", "muj", states=1)
