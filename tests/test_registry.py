"""Every registered model loads, validates, and carries what the CLI contract needs."""

from __future__ import annotations

import pytest

from reference import models
from reference.errors import ModelInputError


@pytest.mark.parametrize("name", models.names())
def test_every_registered_model_loads(name):
    model = models.get(name)
    assert model.name == name
    assert model.source, "each model cites its place in the unit"
    assert model.formulations
    assert len(model.initial_q) == len(model.coordinates)


def test_unknown_model_lists_valid_names():
    with pytest.raises(ModelInputError, match=r"valid: .*pendulum_xy"):
        models.get("no_such_model")


def test_every_system_of_the_unit_is_modelled():
    sources = " | ".join(models.get(n).source for n in models.names())
    for place in [
        "Example 1(a)",
        "Example 1(b)",
        "Example 2(a)",
        "Example 2(b)",
        "Exercise 6.3",
        "Example 3",
        "Example 4",
        "Exercise 6.1",
        "Exercise 6.2",
        "Exercise 6.4",
        "6.5",
        "6.6",
        "Exercise 6.7",
    ]:
        assert place in sources, f"no model declares source {place!r}"


def test_engine_modules_of_the_named_engines_only():
    """What the workers' server preloads for `--engines mujoco`: that engine's module alone,
    read from the entry points; a name that is not registered adds nothing (the run reports
    it), and no names means every registered engine."""
    from crosscheck.engines.entry_points import engine_modules
    from crosscheck.engines.registry import engine_names

    everything = engine_modules()
    assert len(everything) == len(engine_names())
    assert engine_modules(("mujoco",)) == ("crosscheck.engines.mujoco",)
    assert engine_modules(("mujoco", "no_such_engine")) == ("crosscheck.engines.mujoco",)
    assert engine_modules(()) == ()
