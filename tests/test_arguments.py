"""The shared argument rules: every command refuses the same bad value the same way."""

from __future__ import annotations

import argparse

import pytest

from crosscheck.commands.arguments import (
    MAX_T_END,
    horizon,
    name_list,
    positive_int,
    resolve_models,
    unique,
)
from reference.errors import ModelInputError


@pytest.mark.parametrize(
    "rule,text,fragment",
    [
        (positive_int, "0", "at least 1"),
        (positive_int, "-3", "at least 1"),
        (positive_int, "2.5", "not a whole number"),
        (horizon, "inf", "not a finite horizon"),
        (horizon, "nan", "not a finite horizon"),
        (horizon, "0", "must be > 0"),
        (horizon, "-1", "must be > 0"),
        (horizon, "1e9", "longer than"),
        (horizon, "five", "not a number"),
        (name_list, ",", "names nothing"),
        (name_list, "", "names nothing"),
        (name_list, "pinocchio,,mujoco", "empty name"),
        (name_list, "mujoco,mujoco", "more than once"),
    ],
)
def test_bad_values_are_refused_with_the_reason(rule, text, fragment):
    with pytest.raises(argparse.ArgumentTypeError, match=fragment):
        rule(text)


@pytest.mark.parametrize(
    "rule,text,value",
    [
        (positive_int, "6", 6),
        (horizon, "0.1", 0.1),
        (horizon, "1e-9", 1e-9),
        (horizon, str(MAX_T_END), MAX_T_END),
        (name_list, "pinocchio, mujoco", ["pinocchio", "mujoco"]),
    ],
)
def test_good_values_pass_unchanged(rule, text, value):
    assert rule(text) == value


def test_models_repeated_or_unknown_are_refused():
    with pytest.raises(ModelInputError, match="more than once"):
        unique(["pendulum_angle", "pendulum_angle"], "model")
    with pytest.raises(ModelInputError, match="unknown model"):
        resolve_models(["pendulum_angle", "no_such_model"])
    assert resolve_models(["slider_crank"]) == ["slider_crank"]
    assert "slider_crank" in resolve_models([])
