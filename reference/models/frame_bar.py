"""Example 3: the three-dimensional rotating frame F and bar B, Kane with dependent speeds.

The light frame F turns about the fixed vertical k by phi; its horizontal arm carries the bar B,
which turns about the arm direction n2 = e2 by theta. Frames: F = (n1, n2, n3 = k) is k-rotated
by phi from the ground (n1 = (cos phi, sin phi, 0), n2 = (-sin phi, cos phi, 0)); the bar's
e = (e1, e2 = n2, e3) is n2-rotated by theta, so k = -sin(theta) e1 + cos(theta) e3 and
n1 = cos(theta) e1 + sin(theta) e3. Body -> inertial: R = rot_z(phi) rot_y(theta).

Speeds: the bar's body-fixed angular velocity components (omega1, omega2, omega3), dependent:
theta' = omega2, phi' = -omega1 sin(theta) + omega3 cos(theta), and the motion constraint
omega1 cos(theta) + omega3 sin(theta) = 0 (omega . n1 = 0), written exactly as the textbook's
row (a11, a12, a13) = (C, 0, S). The mass center G lies on the arm at distance d from the axis,
and its velocity is written as the textbook does, v_G = d(-omega3 e1 + omega1 e3) in BODY
components: (omega1 e1 + omega3 e3) x d n2. No gravity. Motor torques: M_phi on F about k,
transferred to the bar because F is light, and M_theta on B about n2 (both dotted with the bar's
partial angular velocities e_k, as the textbook's generalized forces F_k).

Printed equations (docs/textbook.md, Example 3), reproduced exactly by Kane's equations here:
  (I1 + m d^2) omega1' + (I3 + m d^2 - I2) omega2 omega3 = -S M_phi + lambda C
  I2 omega2' + (I1 - I3) omega1 omega3 = M_theta
  (I3 + m d^2) omega3' + (I2 - I1 - m d^2) omega1 omega2 = C M_phi + lambda S

Multiplier. With these partial velocities, C*(k=1) + S*(k=3) gives
lambda = m d a_G . k + (I alpha + omega x H) . n1: the n1 component of the moment about O that
the ground's bearing exerts on F (and F, being light, passes on to B). How v_G is written in
the dependent speeds sets the partial velocities and with them lambda, not the motion: adding
c d (omega1 C + omega3 S) n2 (zero on the manifold) shifts lambda by m c d a_G . n2
= -c m d^2 phi'^2. (Writing v_G = -d phi'(C e1 + S e3) instead changes the partial velocities
by -d k (C, 0, S), which leaves lambda unchanged because a_G . k = 0.)

Default bar: a rectangular bar of length 0.5 m along e1 with a 0.04 m (along e2) x 0.02 m
(along e3) cross-section, m = 2 kg, so I1 = m(b^2 + h^2)/12, I2 = m(l^2 + h^2)/12,
I3 = m(l^2 + b^2)/12 (three different values, so every inertia term of the equations is
exercised); the figure's bar orientation is lost in the extraction and plays no part in the
equations, which hold for any central principal inertias.
"""

from __future__ import annotations

import math

import sympy as sp

from reference.system import Body, Model, Parameter, Torque, rot_z, symbols, vec

BAR_M, BAR_LEN, BAR_B, BAR_H = 2.0, 0.5, 0.04, 0.02
PARAMETERS = (
    Parameter("m", BAR_M, "kg", "mass of the bar", positive=True),
    Parameter(
        "d", 0.25, "m", "distance of the bar's mass center G from the vertical axis", positive=True
    ),
    Parameter(
        "I1",
        BAR_M * (BAR_B**2 + BAR_H**2) / 12,
        "kg m^2",
        "bar central inertia about e1",
        positive=True,
    ),
    Parameter(
        "I2",
        BAR_M * (BAR_LEN**2 + BAR_H**2) / 12,
        "kg m^2",
        "bar central inertia about e2 = n2 (the arm)",
        positive=True,
    ),
    Parameter(
        "I3",
        BAR_M * (BAR_LEN**2 + BAR_B**2) / 12,
        "kg m^2",
        "bar central inertia about e3",
        positive=True,
    ),
    Parameter("M_phi", 0.0, "N m", "motor torque on F about the vertical k (from the ground)"),
    Parameter("M_theta", 0.0, "N m", "motor torque on B about the arm n2 (from F)"),
)
m, d, I1, I2, I3, M_phi, M_theta = (p.symbol for p in PARAMETERS)
PHI0, THETA0, PHI_DOT0, THETA_DOT0 = 0.2, 0.4, 3.0, 1.5


def rot_y(a) -> sp.Matrix:
    """Rotation body -> inertial about the y axis by angle a."""
    c, s = sp.cos(a), sp.sin(a)
    return sp.Matrix([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def speeds_from_rates(theta: float, phi_dot: float, theta_dot: float):
    """Consistent (omega1, omega2, omega3) = phi' k + theta' n2 in bar components."""
    return (-math.sin(theta) * phi_dot, theta_dot, math.cos(theta) * phi_dot)


def _sampler(rng, params):
    """Random consistent state: phi, theta uniform on the circle, rates of a few rad/s."""
    phi, theta = rng.uniform(-math.pi, math.pi, 2)
    phi_dot, theta_dot = rng.uniform(-4, 4, 2)
    return (phi, theta), speeds_from_rates(theta, phi_dot, theta_dot)


def model() -> Model:
    phi, theta = symbols("phi theta")
    w1, w2, w3 = symbols("omega1 omega2 omega3")
    S, C = sp.sin(theta), sp.cos(theta)
    q, u = (phi, theta), (w1, w2, w3)
    kin = (-w1 * S + w3 * C, w2)
    omega = vec(w1, w2, w3)
    k_body = vec(-S, 0, C)  # the vertical k in bar components
    bar = Body(
        "bar",
        m,
        v_G=d * vec(-w3, 0, w1),
        v_frame="body",
        inertia=sp.diag(I1, I2, I3),
        omega=omega,
        r_G=d * vec(-sp.sin(phi), sp.cos(phi), 0),  # d n2
        R=rot_z(phi) * rot_y(theta),
    )
    return Model(
        name="frame_bar",
        source="Example 3",
        title="Rotating light frame and bar, Kane with the bar's body-fixed omega as dependent "
        "speeds",
        parameters=PARAMETERS,
        coordinates=q,
        speeds=u,
        kinematics=kin,
        bodies=(bar,),
        loads=(
            Torque("M_phi", omega, M_phi * k_body),
            Torque("M_theta", omega, vec(0, M_theta, 0)),
        ),
        motion_constraints=(w1 * C + w3 * S,),
        constraint_names=("omega_n1",),
        multiplier_meaning="lambda: n1 component of the moment of the ground's bearing on the "
        "light frame F about O (= m d a_G.k + (I alpha + omega x H).n1 with "
        "the textbook's partial velocities)",
        geometry_note="bar orientation in the figure lost; defaults: a rectangular bar along e1",
        formulations=("kane",),
        initial_q=(PHI0, THETA0),
        initial_u=speeds_from_rates(THETA0, PHI_DOT0, THETA_DOT0),
        energy_conserved=False,  # the motor torques do work unless M_phi = M_theta = 0
        state_sampler=_sampler,
    )
