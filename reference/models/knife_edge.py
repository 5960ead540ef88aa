"""Supplement (not in Unit 6): the knife edge / Chaplygin sled, a nonholonomic motion constraint.

A rigid body moves on a horizontal plane (no gravity in the plane). It rests on a sharp blade
(or a fixed wheel) at the contact point C, which cannot slip sideways. Coordinates (x, y, theta):
(x, y) the position of C, theta the angle of the body (blade) axis e = (cos theta, sin theta)
from +X. The mass center G lies on the axis at distance a ahead of C, G = C + a e (a = 0 puts G
at the contact: the classical knife edge). The motion constraint (Eq. 8) is

    -sin(theta) x' + cos(theta) y' = 0     (the velocity of C normal to the blade is zero)

It fails the integrability test that follows Eq. 4 (da_x/dtheta = -cos theta != da_theta/dx = 0)
and no integrating factor exists (the sled reaches every (x, y, theta)), so it is nonholonomic;
reference.constraints.classify reports "not exact as written". Applied loads: a force P along the
blade at C and a torque T about Z (both 0 by default). The multiplier is the lateral force of the
ground on the blade at C, along n = (-sin theta, cos theta).

With v = C x' + S y' (the speed of C along the blade) and w = theta', Newton-Euler gives
  m (v' - a w^2) = P,   (I_G + m a^2) w' = -m a v w + T,   lambda = m (v w + a w')
(tests/test_models_exercises.py checks the formulations against these).
"""

from __future__ import annotations

import math

import sympy as sp

from reference.models.common import T_SYM
from reference.system import Body, Force, Model, Parameter, Torque, rate, rot_z, symbols, vec

PARAMETERS = (
    Parameter("m", 2.0, "kg", "mass of the sled", positive=True),
    Parameter("I_G", 0.15, "kg m^2", "central moment of inertia about Z", positive=True),
    Parameter("a", 0.25, "m", "distance from the contact point C to G along the blade axis"),
    Parameter("P", 0.0, "N", "driving force along the blade at C"),
    Parameter("T", 0.0, "N m", "torque about Z"),
)
m, I_G, a, P, T = (p.symbol for p in PARAMETERS)
THETA0, V0, W0 = 0.3, 1.0, 0.8


def model() -> Model:
    x, y, th = symbols("x y theta")
    xd, yd, thd = symbols("x_dot y_dot theta_dot")
    q, N = (x, y, th), (xd, yd, thd)
    e = vec(sp.cos(th), sp.sin(th), 0)
    r_G = vec(x, y, 0) + a * e
    sled = Body(
        "sled",
        m,
        v_G=rate(r_G, q, N, T_SYM),
        inertia=sp.diag(0, 0, I_G),
        omega=vec(0, 0, thd),
        r_G=r_G,
        R=rot_z(th),
    )
    loads = (
        Force("P", vec(xd, yd, 0), P * e),
        Torque("T", vec(0, 0, thd), vec(0, 0, T)),
    )
    return Model(
        name="knife_edge",
        source="Supplement (nonholonomic)",
        title="Knife edge / Chaplygin sled on a horizontal plane, coordinates (x, y, theta): a "
        "nonholonomic motion constraint (not in Unit 6)",
        parameters=PARAMETERS,
        coordinates=q,
        speeds=N,
        kinematics=N,
        bodies=(sled,),
        loads=loads,
        motion_constraints=(-sp.sin(th) * xd + sp.cos(th) * yd,),
        constraint_names=("no_side_slip",),
        multiplier_meaning="lambda: lateral force of the ground on the blade at C, along "
        "(-sin theta, cos theta)",
        geometry_note="Horizontal plane (no gravity); (x, y) is the contact point C, G = C + a "
        "(cos theta, sin theta).",
        formulations=("lagrange", "dalembert", "kane"),
        initial_q=(0.0, 0.0, THETA0),
        initial_u=(V0 * math.cos(THETA0), V0 * math.sin(THETA0), W0),
        energy_conserved=False,
    )  # True only with P = T = 0 (the defaults): see the tests
