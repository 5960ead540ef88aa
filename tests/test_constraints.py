"""Eqs. 1-4 and 8: coefficients, independence (rank), the integrability test, rheonomic rows."""

from __future__ import annotations

import dataclasses

import pytest
import sympy as sp

from reference import NumericModel, models
from reference.constraints import configuration_coefficients, integrability, motion_coefficients
from reference.errors import RedundantConstraintError

x, y, th, L, t, xd, yd, thd = sp.symbols("x y theta L t x_dot y_dot theta_dot", real=True)


def test_configuration_coefficients_unit_example_1():
    """The unit's first example: q = (x_G, y_G, theta), f1 = x_G - L/2 sin, f2 = y_G - L/2 cos."""
    f = sp.Matrix([x - L / 2 * sp.sin(th), y - L / 2 * sp.cos(th)])
    A, a0 = configuration_coefficients(f, (x, y, th), t)
    assert A == sp.Matrix([[1, 0, -L / 2 * sp.cos(th)], [0, 1, L / 2 * sp.sin(th)]])
    assert a0 == sp.zeros(2, 1)


def test_configuration_coefficients_rheonomic():
    """A support moving as a sin(W t): a0 = df/dt != 0 (Eq. 4)."""
    a, W = sp.symbols("a W", real=True)
    f = sp.Matrix([((x - a * sp.sin(W * t)) ** 2 + y**2 - L**2) / 2])
    A, a0 = configuration_coefficients(f, (x, y), t)
    assert sp.simplify(A[0] - (x - a * sp.sin(W * t))) == 0
    assert sp.simplify(a0[0] + (x - a * sp.sin(W * t)) * a * W * sp.cos(W * t)) == 0


def test_integrability_holonomic_and_not_exact():
    # x x' + y y' = 0 is the derivative of (x^2 + y^2)/2: exact
    A, a0 = motion_coefficients(sp.Matrix([x * xd + y * yd]), (xd, yd))
    assert integrability(list(A), a0[0], (x, y), t) == "holonomic"
    # the knife edge -sin(theta) x' + cos(theta) y' = 0: not exact as written
    A, a0 = motion_coefficients(sp.Matrix([-sp.sin(th) * xd + sp.cos(th) * yd]), (xd, yd, thd))
    assert integrability(list(A), a0[0], (x, y, th), t) == "not exact as written"
    # a time-dependent exact form: x' - cos(t) = 0 is d/dt (x - sin t) = 0
    A, a0 = motion_coefficients(sp.Matrix([xd - sp.cos(t)]), (xd,))
    assert integrability(list(A), a0[0], (x,), t) == "holonomic"
    # x' - x t = 0 fails da/dt = da0/dq: d(1)/dt = 0 but d(-x t)/dx = -t
    A, a0 = motion_coefficients(sp.Matrix([xd - x * t]), (xd,))
    assert integrability(list(A), a0[0], (x,), t) == "not exact as written"


def test_redundant_constraints_named():
    model = models.get("slider_crank_split")
    doubled = dataclasses.replace(
        model,
        name="slider_crank_split_doubled",
        configuration_constraints=(
            *model.configuration_constraints,
            2 * model.configuration_constraints[1],
        ),
        constraint_names=("B_x", "B_y", "B_y_again"),
    )
    with pytest.raises(RedundantConstraintError, match=r"B_y_again.*Remove the redundant"):
        NumericModel(doubled)


def test_unknown_symbol_in_model_is_reported():
    from reference.errors import ModelDefinitionError

    model = models.get("pendulum_xy")
    bad = dataclasses.replace(model, potential=sp.Symbol("k") * model.coordinates[0] ** 2)
    with pytest.raises(ModelDefinitionError, match=r"undeclared symbols.*k"):
        bad.validate()
