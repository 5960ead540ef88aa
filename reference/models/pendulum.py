"""Example 1: the simple planar pendulum (X horizontal, Y pointing DOWN, theta from the vertical).

(a) one coordinate theta; (b) two dependent coordinates (x, y) with x^2 + y^2 = L^2, whose
velocity row the unit writes x x' + y y' = 0 (a11 = x, a12 = y), so f = (x^2 + y^2 - L^2)/2.
Addendum: relaxing the rod gives m x'' + (x/L) T = 0, so the rod tension is T = -lambda L.
"""

from __future__ import annotations

import math

import sympy as sp

from reference.models.common import particle
from reference.system import Model, Parameter, symbols, vec

PARAMETERS = (
    Parameter("m", 1.5, "kg", "mass of the bob", positive=True),
    Parameter("L", 0.8, "m", "length of the light rod", positive=True),
    Parameter("g", 9.81, "m/s^2", "gravitational acceleration", nonnegative=True),
)
m, L, g = (p.symbol for p in PARAMETERS)
GRAVITY = vec(0, g, 0)  # Y points down
THETA0, THETA_DOT0 = 0.3, 1.0


def angle_model() -> Model:
    (theta,) = symbols("theta")
    (theta_dot,) = symbols("theta_dot")
    q, N = (theta,), (theta_dot,)
    bob = particle("bob", m, vec(L * sp.sin(theta), L * sp.cos(theta), 0), q, N)
    return Model(
        name="pendulum_angle",
        source="Example 1(a)",
        title="Simple pendulum, one coordinate theta",
        parameters=PARAMETERS,
        coordinates=q,
        speeds=N,
        kinematics=N,
        bodies=(bob,),
        gravity=GRAVITY,
        formulations=("lagrange", "dalembert", "kane"),
        initial_q=(THETA0,),
        initial_u=(THETA_DOT0,),
        energy_conserved=True,
    )


def xy_model() -> Model:
    x, y = symbols("x y")
    x_dot, y_dot = symbols("x_dot y_dot")
    q, N = (x, y), (x_dot, y_dot)
    bob = particle("bob", m, vec(x, y, 0), q, N)
    return Model(
        name="pendulum_xy",
        source="Example 1(b)",
        title="Simple pendulum, dependent coordinates (x, y)",
        parameters=PARAMETERS,
        coordinates=q,
        speeds=N,
        kinematics=N,
        bodies=(bob,),
        gravity=GRAVITY,
        formulations=("lagrange", "dalembert", "kane"),
        configuration_constraints=((x**2 + y**2 - L**2) / 2,),
        constraint_names=("rod",),
        multiplier_meaning="lambda = -T/L: the rod tension per unit length (Addendum)",
        initial_q=(0.8 * math.sin(THETA0), 0.8 * math.cos(THETA0)),
        initial_u=(0.8 * THETA_DOT0 * math.cos(THETA0), -0.8 * THETA_DOT0 * math.sin(THETA0)),
        energy_conserved=True,
    )


def rod_tension(lam: float, L_value: float) -> float:
    """Addendum: the multiplier is the rod force per unit length, T = -lambda L."""
    return -lam * L_value
