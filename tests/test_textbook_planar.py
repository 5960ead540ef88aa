"""The derived equations equal the unit's printed ones (docs/textbook.md), symbolically.

Examples 1 and 2 and Note 2 / Exercise 6.3, for every formulation each model declares.
"""

from __future__ import annotations

import pytest
import sympy as sp

from reference import models
from reference.formulations import derive


def _sym(name):
    return sp.Symbol(name, real=True)


def _equations(model_name, formulation):
    eom = derive(models.get(model_name), formulation)
    return eom.residual_equations(), eom.constraint_equations()


def _assert_same(derived, printed):
    assert len(derived) == len(printed)
    for k, (d, p) in enumerate(zip(derived, printed, strict=True)):
        diff = sp.simplify(sp.expand_trig(sp.expand(d - p)))
        assert diff == 0, f"equation {k + 1}: derived - printed = {diff}"


FORMS = ["lagrange", "dalembert", "kane"]


@pytest.mark.parametrize("formulation", FORMS)
def test_example_1a(formulation):
    m, L, g, th, thdd = map(_sym, ["m", "L", "g", "theta", "theta_dot_dot"])
    dyn, _ = _equations("pendulum_angle", formulation)
    # theta'' + (g/L) sin(theta) = 0, times m L^2 (the Lagrangian's scale)
    _assert_same(dyn, [m * L**2 * (thdd + g / L * sp.sin(th))])


@pytest.mark.parametrize("formulation", FORMS)
def test_example_1b(formulation):
    m, g, x, y, xd, yd, xdd, ydd, lam = map(
        _sym, ["m", "g", "x", "y", "x_dot", "y_dot", "x_dot_dot", "y_dot_dot", "lambda1"]
    )
    dyn, con = _equations("pendulum_xy", formulation)
    _assert_same(dyn, [m * xdd - lam * x, m * ydd - m * g - lam * y])
    _assert_same(con, [x * xdd + y * ydd + xd**2 + yd**2])


def test_example_1b_eliminated_form_has_plus_gx():
    """docs/textbook.md: eliminating lambda gives y x'' - x y'' + g x = 0 (the extracted text's
    '- g x' contradicts its own recipe)."""
    m, g, x, y, xdd, ydd, _lam = map(
        _sym, ["m", "g", "x", "y", "x_dot_dot", "y_dot_dot", "lambda1"]
    )
    dyn, _ = _equations("pendulum_xy", "lagrange")
    eliminated = sp.expand((y * dyn[0] - x * dyn[1]) / m)
    assert sp.simplify(eliminated - (y * xdd - x * ydd + g * x)) == 0


# the symbols Example 2 and Exercise 6.3 print (two links on a slider or a crank)
TWO_LINKS = ["m1", "m2", "m3", "l1", "l2", "r1", "r2", "I_G1", "I_G2", "g", "T"]
TWO_LINKS += ["theta1", "theta2", "theta1_dot", "theta2_dot"]


def _ex2_printed(constrained: bool):
    names = [*TWO_LINKS, "theta1_dot_dot", "theta2_dot_dot", "lambda1"]
    s = {n: _sym(n) for n in names}
    th1, th2 = s["theta1"], s["theta2"]
    w1, w2, a1, a2 = s["theta1_dot"], s["theta2_dot"], s["theta1_dot_dot"], s["theta2_dot_dot"]
    m1, m2, m3, l1, l2, r1, r2 = (s[k] for k in ["m1", "m2", "m3", "l1", "l2", "r1", "r2"])
    g, T, lam = s["g"], s["T"], s["lambda1"] if constrained else 0
    C1, S1, C2, S2 = sp.cos(th1), sp.sin(th1), sp.cos(th2), sp.sin(th2)
    C21, S21 = sp.cos(th2 - th1), sp.sin(th2 - th1)
    k = m2 * r2 + m3 * l2
    e1 = (
        (s["I_G1"] + m1 * r1**2 + (m2 + m3) * l1**2) * a1
        + k * l1 * C21 * a2
        - k * l1 * S21 * w2**2
        + (m1 * r1 + (m2 + m3) * l1) * g * C1
        - T
        - lam * l1 * C1
    )
    e2 = (
        k * l1 * C21 * a1
        + (s["I_G2"] + m2 * r2**2 + m3 * l2**2) * a2
        + k * l1 * S21 * w1**2
        + k * g * C2
        - lam * l2 * C2
    )
    con = l1 * C1 * a1 + l2 * C2 * a2 - l1 * S1 * w1**2 - l2 * S2 * w2**2
    return [e1, e2], [con]


@pytest.mark.parametrize("formulation", FORMS)
def test_example_2a(formulation):
    dyn, con = _equations("slider_crank_free", formulation)
    printed, _ = _ex2_printed(constrained=False)
    _assert_same(dyn, printed)
    assert len(con) == 0


@pytest.mark.parametrize("formulation", FORMS)
def test_example_2b(formulation):
    dyn, con = _equations("slider_crank", formulation)
    printed_dyn, printed_con = _ex2_printed(constrained=True)
    _assert_same(dyn, printed_dyn)
    _assert_same(con, printed_con)


@pytest.mark.parametrize("formulation", FORMS)
def test_exercise_6_3(formulation):
    names = [*TWO_LINKS, "x_dot", "theta1_dot_dot", "theta2_dot_dot", "x_dot_dot"]
    s = {n: _sym(n) for n in [*names, "lambda1", "lambda2"]}
    C1, S1 = sp.cos(s["theta1"]), sp.sin(s["theta1"])
    C2, S2 = sp.cos(s["theta2"]), sp.sin(s["theta2"])
    m1, m2, m3, l1, l2, r1, r2, g = (s[k] for k in ["m1", "m2", "m3", "l1", "l2", "r1", "r2", "g"])
    L1, L2 = s["lambda1"], s["lambda2"]
    a1, xdd, a2 = s["theta1_dot_dot"], s["x_dot_dot"], s["theta2_dot_dot"]
    w1, w2 = s["theta1_dot"], s["theta2_dot"]
    printed = [  # coordinate order (theta1, x, theta2)
        (s["I_G1"] + m1 * r1**2) * a1 + m1 * g * r1 * C1 - s["T"] - l1 * (L2 * C1 - L1 * S1),
        (m2 + m3) * xdd - m2 * r2 * S2 * a2 - m2 * r2 * C2 * w2**2 + L1,
        (s["I_G2"] + m2 * r2**2) * a2
        - m2 * r2 * S2 * xdd
        + m2 * g * r2 * C2
        - l2 * (L1 * S2 - L2 * C2),
    ]
    # f1 = l1 C1 - l2 C2 - x and f2 = l1 S1 - l2 S2, differentiated twice
    printed_con = [
        -l1 * S1 * a1 - l1 * C1 * w1**2 + l2 * S2 * a2 + l2 * C2 * w2**2 - xdd,
        l1 * C1 * a1 - l1 * S1 * w1**2 - l2 * C2 * a2 + l2 * S2 * w2**2,
    ]
    dyn, con = _equations("slider_crank_split", formulation)
    _assert_same(dyn, printed)
    _assert_same(con, printed_con)
