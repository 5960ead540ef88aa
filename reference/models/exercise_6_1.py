"""Exercise 6.1: a slender bar whose ends slide in a horizontal and a vertical guide, coordinates
(x, y, theta) with two multipliers (five equations).

The figure (first drawn with Exercises 4.3 and 5.1) was lost in the text extraction. ASSUMED
GEOMETRY, reconstructed from the printed answers (vertical plane, X right, Y UP, gravity -g Y):
- uniform slender bar B (mass m, length l); its end A slides along the X axis, its end B along
  the Y axis; theta is the bar's angle from the vertical, so A = (l sin(theta), 0) and
  B = (0, l cos(theta)) (a "ladder" leaning on the Y axis);
- x is the X coordinate of end A, y the Y coordinate of end B; the bar's mass center is the
  midpoint G = (x/2, y/2);
- a linear spring k (unstretched at x = 0) and a viscous damper c act horizontally on A;
- a block P of mass m_p is fixed to end B (it moves with B along the Y guide) and the force
  F(t) pushes P DOWN (along -Y). F(t) is the constant parameter F here.
Constraints f1 = x - l sin(theta) = 0, f2 = y - l cos(theta) = 0, so that
  x'' - l (theta'' C - theta'^2 S) = 0,  y'' + l (theta'' S + theta'^2 C) = 0
as printed. The equations derived from this declaration are
  (1/4) m x'' + c x' + k x = lambda1
  ((1/4) m + m_p) y'' + ((1/2) m + m_p) g = lambda2 - F(t)
  (1/12) m l^2 theta'' = l (-lambda1 C + lambda2 S)
How they compare with the garbled printed answers (symbols and stacked fractions were lost; what
survives is the letters, the signs, the parentheses and the digits, partly moved to lines of
their own): the legible letters and signs match term by term (m x'' + c x' + k x = lambda1;
(m + m_p) y'' + (m + m_p) g = ... with the sign run "+ + + = -"; (1/12) m l^2 theta'' =
(...)(-lambda1 C + lambda2 S); x'' - (...) theta'' C + (...) theta'^2 S = 0 and
y'' + (...) theta'' S + (...) theta'^2 C = 0). The digits left over in the answers' fraction
lines, "1 4" and "1 1 4 2", are exactly the 1/4, 1/4 and 1/2 of the first two equations, and the
small-font run "2 1 1 2 1 2" is exactly l^2, lambda1, lambda2 and 1/12 of the third; the
constraint rows and the third equation's factor carry no digit, i.e. their factor is l itself
(Exercise 6.2's answers, whose factor is l/2, show a "1 2" for it). The second equation's sign
run is met by "... = lambda2 - F(t)" (F pushing the block down); "F(t) - lambda2" (F pushing up)
would need the row l cos(theta) - y, whose theta coefficient puts "- lambda2 S" into the third
equation, against the printed "+ lambda2 S" (sign and scale of lambda follow the row). See
tests/test_models_exercises.py for the symbolic comparison and part (b), the reduction to the
single equation in theta of Exercises 4.3 and 5.1:
  (m l^2/3 + m_p l^2 S^2) theta'' + m_p l^2 S C theta'^2 + c l^2 C^2 theta' + k l^2 S C
    - ((1/2) m + m_p) g l S - F l S = 0.
"""

from __future__ import annotations

import math

import sympy as sp

from reference.models.common import particle, planar_body
from reference.system import Force, Model, Parameter, symbols, vec

L_BAR = 1.0
PARAMETERS = (
    Parameter("m", 2.0, "kg", "mass of the slender bar B", positive=True),
    Parameter("m_p", 1.0, "kg", "mass of the block P at end B", positive=True),
    Parameter("l", L_BAR, "m", "length of the bar", positive=True),
    Parameter(
        "k",
        50.0,
        "N/m",
        "stiffness of the horizontal spring at end A (unstretched at x = 0)",
        nonnegative=True,
    ),
    Parameter("c", 2.0, "N s/m", "coefficient of the horizontal damper at end A", nonnegative=True),
    Parameter("F", 5.0, "N", "force F(t) on the block P, pointing down (-Y), held constant"),
    Parameter("g", 9.81, "m/s^2", "gravitational acceleration", nonnegative=True),
)
m, m_p, l, k, c, F, g = (p.symbol for p in PARAMETERS)
GRAVITY = vec(0, -g, 0)  # Y points up
THETA0, THETA_DOT0 = 0.4, 0.5

GEOMETRY_NOTE = (
    "Figure lost; assumed: vertical plane, X right, Y up; slender bar (m, l) with end A on the X "
    "axis at (x, 0) and end B on the Y axis at (0, y), theta from the vertical "
    "(x = l sin theta, y = l cos theta), mass center G = (x/2, y/2); spring k (unstretched at "
    "x = 0) and damper c horizontal at A; block P (m_p) fixed to B; F(t) (constant F) pushes P "
    "down (-Y). Reproduces the printed answers' legible parts and sign patterns."
)


def model() -> Model:
    x, y, th = symbols("x y theta")
    xd, yd, thd = symbols("x_dot y_dot theta_dot")
    q, N = (x, y, th), (xd, yd, thd)
    # bar axis from B to A is (sin theta, -cos theta): its angle from +X is theta - pi/2
    bar = planar_body("bar", m, m * l**2 / 12, vec(x / 2, y / 2, 0), th - sp.pi / 2, q, N)
    block = particle("block", m_p, vec(0, y, 0), q, N)
    loads = (
        Force("damper_A", vec(xd, 0, 0), vec(-c * xd, 0, 0)),
        Force("F_on_P", vec(0, yd, 0), vec(0, -F, 0)),
    )
    s0, c0 = math.sin(THETA0), math.cos(THETA0)
    return Model(
        name="exercise_6_1",
        source="Exercise 6.1",
        title="Bar with ends in horizontal/vertical guides, spring-damper and block: "
        "dependent coordinates (x, y, theta)",
        parameters=PARAMETERS,
        coordinates=q,
        speeds=N,
        kinematics=N,
        bodies=(bar, block),
        gravity=GRAVITY,
        loads=loads,
        potential=k * x**2 / 2,
        configuration_constraints=(x - l * sp.sin(th), y - l * sp.cos(th)),
        constraint_names=("end_A", "end_B"),
        multiplier_meaning="(lambda1, lambda2): generalized constraint forces (Addendum) conjugate "
        "to x and y that tie the end coordinates to the bar angle "
        "(x = l sin theta, y = l cos theta)",
        geometry_note=GEOMETRY_NOTE,
        formulations=("lagrange", "dalembert", "kane"),
        initial_q=(L_BAR * s0, L_BAR * c0, THETA0),
        initial_u=(L_BAR * c0 * THETA_DOT0, -L_BAR * s0 * THETA_DOT0, THETA_DOT0),
        energy_conserved=False,
    )
