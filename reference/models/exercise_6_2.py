"""Exercise 6.2: a block on a spring-damper carrying a pendulous slender bar, dependent coordinates
(x, theta, x_G, y_G) with two multipliers (six equations).

The figure (first drawn with Exercises 4.4 and 5.2) was lost in the text extraction. ASSUMED
GEOMETRY, reconstructed from the printed answers (vertical plane, X right, Y DOWN, gravity +g Y):
- block (cart) of mass m1 sliding horizontally, x its displacement; a linear spring k
  (unstretched at x = 0) and a viscous damper c tie it to the ground; the force F(t) acts on it
  along +X (F(t) is the constant parameter F here);
- uniform slender bar (mass m2, length l) pinned at its end A to the block, hanging below it;
  theta is its angle from the downward vertical;
- (x_G, y_G) are the X and Y coordinates of the bar's mass center G relative to A, so G is at
  (x + x_G, y_G) and the constraints are x_G - (l/2) S = 0, y_G - (l/2) C = 0.
Their derivatives give the printed rows x_G'' - (l/2) theta'' C + (l/2) theta'^2 S = 0 and
y_G'' + (l/2) theta'' S + (l/2) theta'^2 C = 0, and the derived equations are, exactly as printed,
  (m1 + m2) x'' + m2 x_G'' + c x' + k x = F(t)
  m2 x'' + m2 x_G'' = lambda1
  m2 y_G'' - m2 g = lambda2
  (1/12) m2 l^2 theta'' = (l/2)(-lambda1 C + lambda2 S)
(the printed order is x, x_G, y_G, theta; the coordinates here follow the exercise's list
(x, theta, x_G, y_G)). "m2 y_G'' - m2 g" is what fixes Y pointing down. (lambda1, lambda2) is the
force of the pin A on the bar (X and Y components). Part (b), the reduction to the two equations
of Exercises 4.4 and 5.2:
  (m1 + m2) x'' + (1/2) m2 l (C theta'' - S theta'^2) + c x' + k x = F(t)
  (1/3) m2 l^2 theta'' + (1/2) m2 l C x'' + (1/2) m2 g l S = 0
is checked in tests/test_models_exercises.py.
"""

from __future__ import annotations

import math

import sympy as sp

from reference.models.common import particle, planar_body
from reference.system import Force, Model, Parameter, symbols, vec

L_BAR = 0.8
PARAMETERS = (
    Parameter("m1", 3.0, "kg", "mass of the block", positive=True),
    Parameter("m2", 1.5, "kg", "mass of the slender bar", positive=True),
    Parameter("l", L_BAR, "m", "length of the bar", positive=True),
    Parameter(
        "k", 40.0, "N/m", "stiffness of the block's spring (unstretched at x = 0)", nonnegative=True
    ),
    Parameter("c", 1.5, "N s/m", "coefficient of the block's damper", nonnegative=True),
    Parameter("F", 4.0, "N", "force F(t) on the block along +X, held constant"),
    Parameter("g", 9.81, "m/s^2", "gravitational acceleration", nonnegative=True),
)
m1, m2, l, k, c, F, g = (p.symbol for p in PARAMETERS)
GRAVITY = vec(0, g, 0)  # Y points down
X0, X_DOT0, THETA0, THETA_DOT0 = 0.05, -0.2, 0.5, 1.2

GEOMETRY_NOTE = (
    "Figure lost; assumed: vertical plane, X right, Y down; block m1 at x on spring k "
    "(unstretched at x = 0) and damper c to ground, F(t) (constant F) on it along +X; slender bar "
    "(m2, l) pinned at its end A to the block and hanging, theta from the downward vertical; "
    "(x_G, y_G) = G relative to A = ((l/2) sin theta, (l/2) cos theta). Reproduces the printed "
    "answers exactly."
)


def model() -> Model:
    x, th, xG, yG = symbols("x theta x_G y_G")
    xd, thd, xGd, yGd = symbols("x_dot theta_dot x_G_dot y_G_dot")
    q, N = (x, th, xG, yG), (xd, thd, xGd, yGd)
    block = particle("block", m1, vec(x, 0, 0), q, N)
    # bar axis from A to G is (sin theta, cos theta): its angle from +X is pi/2 - theta
    bar = planar_body("bar", m2, m2 * l**2 / 12, vec(x + xG, yG, 0), sp.pi / 2 - th, q, N)
    loads = (
        Force("damper", vec(xd, 0, 0), vec(-c * xd, 0, 0)),
        Force("F", vec(xd, 0, 0), vec(F, 0, 0)),
    )
    s0, c0 = math.sin(THETA0), math.cos(THETA0)
    h = L_BAR / 2
    return Model(
        name="exercise_6_2",
        source="Exercise 6.2",
        title="Block on spring-damper with a pendulous bar: dependent coordinates "
        "(x, theta, x_G, y_G)",
        parameters=PARAMETERS,
        coordinates=q,
        speeds=N,
        kinematics=N,
        bodies=(block, bar),
        gravity=GRAVITY,
        loads=loads,
        potential=k * x**2 / 2,
        configuration_constraints=(xG - l / 2 * sp.sin(th), yG - l / 2 * sp.cos(th)),
        constraint_names=("G_x", "G_y"),
        multiplier_meaning="(lambda1, lambda2): force of the pin A on the bar, X and Y (down) "
        "components",
        geometry_note=GEOMETRY_NOTE,
        formulations=("lagrange", "dalembert", "kane"),
        initial_q=(X0, THETA0, h * s0, h * c0),
        initial_u=(X_DOT0, THETA_DOT0, h * c0 * THETA_DOT0, -h * s0 * THETA_DOT0),
        energy_conserved=False,
    )
