"""Exercise 6.4: a disk D turning about the vertical Z axis carrying a slender bar B pinned at P,
Lagrange's equations with the dependent coordinates (phi, theta, y_G, z_G), two multipliers.

The figure was lost in the text extraction; the text says: disk D (mass m_d, radius R) turns
about Z (angle phi); uniform slender bar B (mass m, length l) turns about an X axis (angle theta)
at the pin P on the disk; a linear torsional spring k (unstretched at theta = 0) and damper c act
between B and D at P; motor torques M_phi on D about Z and M_theta on B about the X axis;
(y_G, z_G) are the disk-fixed coordinates of B's mass center G relative to O.
ASSUMED GEOMETRY, reconstructed from the printed answers:
- Z points UP (the printed "m z_G'' + m g = lambda2"), O is the disk's center on the Z axis;
  disk-fixed axes (x, y, z) with z = Z;
- P is on the rim at disk-fixed (0, R, 0), the pin axis is parallel to the disk-fixed x axis
  (tangent to the rim), so G stays in the disk-fixed plane x = 0 (no x_G coordinate);
- at theta = 0 the bar hangs straight down from P, and theta > 0 swings G outward (+y):
  y_G = R + (l/2) S, z_G = -(l/2) C. The printed constraint rows are the second derivatives,
  y_G'' = (l/2) theta'' C - (l/2) theta'^2 S and z_G'' = (l/2) theta'' S + (l/2) theta'^2 C, which
  fix the signs but not the constants R and 0 (where P sits): the pin radius R is an assumption
  that only moves y_G by a constant;
- the disk's inertia about Z is (1/2) m_d R^2 (uniform disk), the bar's central inertia is
  (1/12) m l^2 about axes normal to it and 0 about its axis;
- M_theta and the spring-damper act between D and B (their power uses the relative rate
  theta'); M_phi acts on D (power M_phi phi').
The derived equations equal the printed ones:
  ((1/2) m_d R^2 + m y_G^2 + (1/12) m l^2 S^2) phi'' + 2 m y_G y_G' phi'
      + (1/6) m l^2 S C theta' phi' = M_phi
  (1/12) m l^2 theta'' - (1/12) m l^2 S C phi'^2 + c theta' + k theta
      = M_theta - (l/2) lambda1 C - (l/2) lambda2 S
  m y_G'' - m y_G phi'^2 = lambda1
  m z_G'' + m g = lambda2
with f1 = y_G - R - (l/2) S, f2 = z_G + (l/2) C; (lambda1, lambda2) is the force of the pin P on
the bar along the disk-fixed y (radial) and z (vertical) axes.
"""

from __future__ import annotations

import math

import sympy as sp

from reference.models.common import T_SYM
from reference.system import Body, Model, Parameter, Torque, rate, rot_x, rot_z, symbols, vec

R_DISK, L_BAR = 0.5, 0.6
PARAMETERS = (
    Parameter("m_d", 4.0, "kg", "mass of the disk D", positive=True),
    Parameter("R", R_DISK, "m", "radius of the disk (the pin P is on its rim)", positive=True),
    Parameter("m", 1.2, "kg", "mass of the slender bar B", positive=True),
    Parameter("l", L_BAR, "m", "length of the bar", positive=True),
    Parameter(
        "k", 6.0, "N m/rad", "torsional spring at P (unstretched at theta = 0)", nonnegative=True
    ),
    Parameter("c", 0.3, "N m s/rad", "torsional damper at P", nonnegative=True),
    Parameter("M_phi", 0.8, "N m", "motor torque on the disk about Z"),
    Parameter("M_theta", 0.2, "N m", "motor torque on the bar about the pin's X axis"),
    Parameter("g", 9.81, "m/s^2", "gravitational acceleration", nonnegative=True),
)
m_d, R, m, l, k, c, M_phi, M_theta, g = (p.symbol for p in PARAMETERS)
GRAVITY = vec(0, 0, -g)  # Z points up
PHI0, PHI_DOT0, THETA0, THETA_DOT0 = 0.2, 3.0, 0.6, -0.8

GEOMETRY_NOTE = (
    "Figure lost; assumed: Z up, O the disk center; pin P on the rim at disk-fixed (0, R, 0) with "
    "its axis along disk-fixed x; at theta = 0 the bar hangs down from P, theta > 0 swings G "
    "outward: y_G = R + (l/2) sin theta, z_G = -(l/2) cos theta; disk inertia (1/2) m_d R^2 about "
    "Z; spring-damper and M_theta act between D and B, M_phi on D. Reproduces the printed "
    "answers exactly (the printed constraints are acceleration-level, so the pin position R, 0 "
    "is an assumption)."
)


def model() -> Model:
    phi, th, yG, zG = symbols("phi theta y_G z_G")
    phid, thd, yGd, zGd = symbols("phi_dot theta_dot y_G_dot z_G_dot")
    q, N = (phi, th, yG, zG), (phid, thd, yGd, zGd)
    disk = Body(
        "disk",
        m_d,
        v_G=vec(0, 0, 0),
        inertia=sp.diag(m_d * R**2 / 4, m_d * R**2 / 4, m_d * R**2 / 2),
        omega=vec(0, 0, phid),
        r_G=vec(0, 0, 0),
        R=rot_z(phi),
    )
    # bar frame: disk frame turned by theta about x; its 3-axis points from G to P
    R_bar = rot_z(phi) * rot_x(th)
    r_G = rot_z(phi) * vec(0, yG, zG)
    bar = Body(
        "bar",
        m,
        v_G=rate(r_G, q, N, T_SYM),
        inertia=sp.diag(m * l**2 / 12, m * l**2 / 12, 0),
        omega=vec(thd, phid * sp.sin(th), phid * sp.cos(th)),  # (theta' x + phi' Z) in B
        r_G=r_G,
        R=R_bar,
    )
    theta_rel = vec(thd, 0, 0)  # angular velocity of B relative to D, disk components
    loads = (
        Torque("M_phi", vec(0, 0, phid), vec(0, 0, M_phi)),
        Torque("M_theta", theta_rel, vec(M_theta, 0, 0)),
        Torque("damper_P", theta_rel, vec(-c * thd, 0, 0)),
    )
    s0, c0, h = math.sin(THETA0), math.cos(THETA0), L_BAR / 2
    return Model(
        name="exercise_6_4",
        source="Exercise 6.4",
        title="Rotating disk with a pinned slender bar: dependent coordinates "
        "(phi, theta, y_G, z_G)",
        parameters=PARAMETERS,
        coordinates=q,
        speeds=N,
        kinematics=N,
        bodies=(disk, bar),
        gravity=GRAVITY,
        loads=loads,
        potential=k * th**2 / 2,
        configuration_constraints=(yG - R - l / 2 * sp.sin(th), zG + l / 2 * sp.cos(th)),
        constraint_names=("G_y", "G_z"),
        multiplier_meaning="(lambda1, lambda2): force of the pin P on the bar along the "
        "disk-fixed y (radial) and z (vertical) axes",
        geometry_note=GEOMETRY_NOTE,
        formulations=("lagrange", "dalembert", "kane"),
        initial_q=(PHI0, THETA0, R_DISK + h * s0, -h * c0),
        initial_u=(PHI_DOT0, THETA_DOT0, h * c0 * THETA_DOT0, h * s0 * THETA_DOT0),
        energy_conserved=False,
    )
