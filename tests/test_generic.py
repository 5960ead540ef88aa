"""The generic parameter set: distinct values, physical inertias, valid geometry."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from reference import NumericModel, models
from reference.generic import generic_parameters, inertia_triples


def _geometry_ok(model):
    def ok(values):
        nm = NumericModel(model, params=values)
        q, u = nm.project(model.initial_q, model.initial_u)
        return bool(np.all(np.isfinite(nm.forward(q, u).accelerations)))

    return ok


@pytest.mark.parametrize("name", models.names())
def test_generic_set_separates_every_parameter_and_stays_physical(name):
    model = models.get(name)
    values = generic_parameters(model, _geometry_ok(model))
    assert values == generic_parameters(model, _geometry_ok(model)), "must be deterministic"
    by_unit: dict[str, list[str]] = {}
    for p in model.parameters:
        by_unit.setdefault(p.unit, []).append(p.name)
        assert values[p.name] != 0.0, f"{p.name}: a zero value hides sign errors"
        if p.default != 0.0:
            assert values[p.name] != p.default
    for unit, names in by_unit.items():
        for a, b in itertools.combinations(names, 2):
            assert abs(values[a] - values[b]) > 1e-3 * max(abs(values[a]), abs(values[b])), (
                f"{a} and {b} ({unit}) are alike in the generic set"
            )
    for triple in inertia_triples(model):
        I = sorted(values[n] for n in triple)
        assert I[0] + I[1] >= I[2], f"{triple} breaks the triangle inequality"


def test_inertia_triples_are_found_where_a_body_has_three_principal_inertias():
    assert inertia_triples(models.get("double_pendulum_3d")) == [
        ("I1_11", "I1_22", "I1_33"),
        ("I2_11", "I2_22", "I2_33"),
    ]
    assert inertia_triples(models.get("slider_crank")) == []  # planar bars: I_zz only


def test_the_defaults_themselves_are_symmetric_where_the_generic_set_is_not():
    """Why the generic set exists: Example 4's default links have equal transverse inertias,
    so an I11 <-> I33 swap in an engine's model is invisible at the defaults."""
    model = models.get("double_pendulum_3d")
    d = {p.name: p.default for p in model.parameters}
    g = generic_parameters(model, _geometry_ok(model))
    assert d["I1_11"] == d["I1_33"] and g["I1_11"] != g["I1_33"]
