"""Supplement (not in Unit 6): Example 1(b) with a support moving x_s(t) = a sin(Omega t), a
rheonomic constraint.

The simple pendulum of Example 1(b) (X horizontal, Y pointing DOWN, bob of mass m at (x, y), rod
of length L) whose support slides along X with the prescribed motion x_s(t) = a sin(Omega t).
The configuration constraint

    f = ((x - a sin(Omega t))^2 + y^2 - L^2) / 2 = 0

depends on t explicitly (rheonomic, Eq. 1), so its velocity form (Eqs. 2-4)
(x - x_s) x' + y y' + a0 = 0 has a0 = df/dt = -(x - x_s) a Omega cos(Omega t) != 0. The constraint
force then does work: from M u' - f = A^T lambda, its power is u^T A^T lambda = -lambda a0 on the
manifold, and dE/dt equals it (there are no other non-conservative loads). As in Example 1(b),
lambda = -T/L with T the rod tension. In the angle theta from the vertical
(x = x_s + L sin theta, y = L cos theta): theta'' = -(g sin theta + x_s'' cos theta)/L.
"""

from __future__ import annotations

import math

import sympy as sp

from reference.models.common import T_SYM, particle
from reference.system import Model, Parameter, symbols, vec

L_ROD, A_SUPPORT, OMEGA = 0.8, 0.1, 4.0
PARAMETERS = (
    Parameter("m", 1.5, "kg", "mass of the bob", positive=True),
    Parameter("L", L_ROD, "m", "length of the light rod", positive=True),
    Parameter("a", A_SUPPORT, "m", "amplitude of the support motion"),
    Parameter("Omega", OMEGA, "rad/s", "circular frequency of the support motion"),
    Parameter("g", 9.81, "m/s^2", "gravitational acceleration", nonnegative=True),
)
m, L, a, Omega, g = (p.symbol for p in PARAMETERS)
GRAVITY = vec(0, g, 0)  # Y points down
THETA0, THETA_DOT0 = 0.3, 1.0


def support_position(t):
    """x_s(t) = a sin(Omega t) (symbolic)."""
    return a * sp.sin(Omega * t)


def model() -> Model:
    x, y = symbols("x y")
    xd, yd = symbols("x_dot y_dot")
    q, N = (x, y), (xd, yd)
    bob = particle("bob", m, vec(x, y, 0), q, N)
    xs = support_position(T_SYM)
    # at t = 0 the support is at x_s = 0 moving with x_s' = a Omega
    s0, c0 = math.sin(THETA0), math.cos(THETA0)
    return Model(
        name="pendulum_moving_support",
        source="Supplement (rheonomic)",
        title="Example 1(b) with a support moving x_s(t) = a sin(Omega t): a rheonomic "
        "constraint (not in Unit 6)",
        parameters=PARAMETERS,
        coordinates=q,
        speeds=N,
        kinematics=N,
        bodies=(bob,),
        gravity=GRAVITY,
        configuration_constraints=(((x - xs) ** 2 + y**2 - L**2) / 2,),
        constraint_names=("rod",),
        multiplier_meaning="lambda = -T/L: the rod tension per unit length (as in Example 1(b))",
        geometry_note="Y down; the support slides along X with x_s(t) = a sin(Omega t).",
        formulations=("lagrange", "dalembert", "kane"),
        initial_q=(L_ROD * s0, L_ROD * c0),
        initial_u=(L_ROD * THETA_DOT0 * c0 + A_SUPPORT * OMEGA, -L_ROD * THETA_DOT0 * s0),
        energy_conserved=False,
    )
