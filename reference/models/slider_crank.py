"""Example 2 and Note 2 / Exercise 6.3: the planar slider-crank (X right, Y UP, angles from +X).

Crank 1 (m1, l1, r1 = |A G1|, I_G1) pinned at A and driven by torque T; rod 2 (m2, l2,
I_G2); end mass m3 at C, translating only.
- Example 2(a): the slider constraint removed, coordinates (theta1, theta2), r2 = |B G2|.
- Example 2(b): with the slider row l1 S1 + l2 S2 = 0; lambda is the vertical guide force on C.
- Note 2 / Exercise 6.3: crank (theta1) and rod + slider (x, theta2) joined at B by
  f1 = l1 C1 - l2 C2 - x = 0, f2 = l1 S1 - l2 S2 = 0. In 6.3 theta2 is the rod angle measured
  from C to B (Example 2's theta2 + pi) and r2 = |C G2| (Example 2's l2 - r2); (lambda1, lambda2)
  is the force of the rod on the crank at B.
"""

from __future__ import annotations

import math

import sympy as sp

from reference.models.common import particle, planar_body
from reference.system import Model, Parameter, Torque, symbols, vec

L1, L2 = 0.3, 0.8
M1, M2 = 1.0, 2.0
PARAMETERS = (
    Parameter("m1", M1, "kg", "crank mass", positive=True),
    Parameter("m2", M2, "kg", "connecting-rod mass", positive=True),
    Parameter("m3", 0.5, "kg", "end (slider) mass", positive=True),
    Parameter("l1", L1, "m", "crank length", positive=True),
    Parameter("l2", L2, "m", "rod length", positive=True),
    Parameter("r1", L1 / 2, "m", "distance A to G1", nonnegative=True),
    Parameter(
        "r2", L2 / 2, "m", "distance to G2 (from B in Example 2, from C in 6.3)", nonnegative=True
    ),
    Parameter(
        "I_G1", M1 * L1**2 / 12, "kg m^2", "crank central inertia (slender bar)", positive=True
    ),
    Parameter(
        "I_G2", M2 * L2**2 / 12, "kg m^2", "rod central inertia (slender bar)", positive=True
    ),
    Parameter("g", 9.81, "m/s^2", "gravitational acceleration", nonnegative=True),
    Parameter("T", 0.0, "N m", "driving torque on the crank at A"),
)
m1, m2, m3, l1, l2, r1, r2, I_G1, I_G2, g, T = (p.symbol for p in PARAMETERS)
GRAVITY = vec(0, -g, 0)
THETA1_0, THETA1_DOT0 = 0.5, 8.0


def _closure(theta1, theta1_dot):
    """Example 2's rod angle on the +x branch (C right of A) and its rate, from
    l1 S1 + l2 S2 = 0."""
    theta2 = math.asin(-L1 * math.sin(theta1) / L2)
    theta2_dot = -L1 * math.cos(theta1) * theta1_dot / (L2 * math.cos(theta2))
    return theta2, theta2_dot


def _two_link(name: str, constrained: bool) -> Model:
    th1, th2 = symbols("theta1 theta2")
    w1, w2 = symbols("theta1_dot theta2_dot")
    q, N = (th1, th2), (w1, w2)
    e1, e2 = vec(sp.cos(th1), sp.sin(th1), 0), vec(sp.cos(th2), sp.sin(th2), 0)
    bodies = (
        planar_body("crank", m1, I_G1, r1 * e1, th1, q, N),
        planar_body("rod", m2, I_G2, l1 * e1 + r2 * e2, th2, q, N),
        particle("slider", m3, l1 * e1 + l2 * e2, q, N),
    )
    th2_0, th2_dot0 = _closure(THETA1_0, THETA1_DOT0)
    return Model(
        name=name,
        source="Example 2(b)" if constrained else "Example 2(a)",
        title="Slider-crank" if constrained else "Slider-crank with the slider constraint removed",
        parameters=PARAMETERS,
        coordinates=q,
        speeds=N,
        kinematics=N,
        bodies=bodies,
        gravity=GRAVITY,
        loads=(Torque("T", vec(0, 0, w1), vec(0, 0, T)),),
        configuration_constraints=(l1 * sp.sin(th1) + l2 * sp.sin(th2),) if constrained else (),
        constraint_names=("slider",) if constrained else (),
        multiplier_meaning="lambda: vertical force of the guide on the slider C"
        if constrained
        else "",
        formulations=("lagrange", "dalembert", "kane"),
        initial_q=(THETA1_0, th2_0),
        initial_u=(THETA1_DOT0, th2_dot0),
    )


def free_model() -> Model:
    return _two_link("slider_crank_free", constrained=False)


def model() -> Model:
    return _two_link("slider_crank", constrained=True)


def split_model() -> Model:
    th1, x, th2 = symbols("theta1 x theta2")
    w1, xd, w2 = symbols("theta1_dot x_dot theta2_dot")
    q, N = (th1, x, th2), (w1, xd, w2)
    e2 = vec(sp.cos(th2), sp.sin(th2), 0)  # from C towards B
    bodies = (
        planar_body("crank", m1, I_G1, r1 * vec(sp.cos(th1), sp.sin(th1), 0), th1, q, N),
        planar_body("rod", m2, I_G2, vec(x, 0, 0) + r2 * e2, th2, q, N),
        particle("slider", m3, vec(x, 0, 0), q, N),
    )
    th2_ex2, th2_dot = _closure(THETA1_0, THETA1_DOT0)
    x0 = L1 * math.cos(THETA1_0) + L2 * math.cos(th2_ex2)
    x_dot0 = -L1 * math.sin(THETA1_0) * THETA1_DOT0 - L2 * math.sin(th2_ex2) * th2_dot
    return Model(
        name="slider_crank_split",
        source="Note 2 / Exercise 6.3",
        title="Slider-crank as crank + (rod, slider) joined at B by two constraints",
        parameters=PARAMETERS,
        coordinates=q,
        speeds=N,
        kinematics=N,
        bodies=bodies,
        gravity=GRAVITY,
        loads=(Torque("T", vec(0, 0, w1), vec(0, 0, T)),),
        configuration_constraints=(
            l1 * sp.cos(th1) - l2 * sp.cos(th2) - x,
            l1 * sp.sin(th1) - l2 * sp.sin(th2),
        ),
        constraint_names=("B_x", "B_y"),
        multiplier_meaning="(lambda1, lambda2): force of the rod on the crank at B",
        geometry_note="theta2 is measured from C to B (Example 2's theta2 + pi); "
        "r2 = |C G2| (Example 2's l2 - r2)",
        formulations=("lagrange", "dalembert", "kane"),
        initial_q=(THETA1_0, x0, th2_ex2 + math.pi),
        initial_u=(THETA1_DOT0, x_dot0, th2_dot),
    )
