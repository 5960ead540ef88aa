"""Example 4: the three-dimensional double pendulum, Kane with twelve dependent speeds.

Two bars joined to the ground at O and to each other at A by ball-and-socket joints. The ground
frame N = (N1, N2, N3) has N2 vertical UP, gravity -g N2 (an engine may use Z up: map
N2 -> Z there). Link i (length l_i, mass m_i, central principal inertias I_i11, I_i22, I_i33
along n_i1, n_i2, n_i3) hangs along -n_i2: G1 = O - l1/2 n12, A = O - l1 n12,
G2 = A - l2/2 n22.

Orientation: body-fixed 3-1-3 angles (theta_i1, theta_i2, theta_i3) per link. The textbook's
R_i maps N components to n_i components (its rows are the n_ij in N components):
  R_i = [[C1C3 - S1C2S3,  S1C3 + C1C2S3, S2S3],
         [-C1S3 - S1C2C3, -S1S3 + C1C2C3, S2C3],
         [S1S2,           -C1S2,          C2  ]]      (Cj = cos theta_ij, Sj = sin theta_ij)
so the Body.R (body -> inertial) given here is R_i^T.

Speeds u = (w11, w12, w13, w21, w22, w23, v11, v12, v13, v21, v22, v23): the body-fixed angular
velocity components of the links, then the N components of the mass-center velocities. The
kinematic equations are the inverse of omega_i = (S2S3 th1' + C3 th2', S2C3 th1' - S3 th2',
C2 th1' + th3'):
  th1' = (w1 S3 + w2 C3)/S2,  th2' = w1 C3 - w2 S3,  th3' = w3 - C2 (w1 S3 + w2 C3)/S2
(singular at S2 = 0: keep theta_i2 away from 0 and pi; the hanging pose is theta_i2 = pi/2,
theta_i1 = -pi/2, theta_i3 = pi/2).

Six motion constraints, written with +1 on the v's as the textbook's rows:
  v_G1 - omega1 x r_G1 = v_G1 + (l1/2) R1^T (-w13, 0, w11) = 0
  v_G2 - (omega1 x r_A + omega2 x r_G2/A)
       = v_G2 + l1 R1^T (-w13, 0, w11) + (l2/2) R2^T (-w23, 0, w21) = 0
so Kane's equations are the printed Eqs. 10-21: Euler's equations of each link with the
multiplier moments, and m_i v_ij' = lambda - delta_j2 m_i g.

Multipliers (checked by Newton-Euler in tests/test_models_3d.py): lambda[3:6] is the force
of link 1 on link 2 at A (N components); lambda[0:3] = F_O - lambda[3:6], the net joint force
on link 1 (F_O, the ground's force on link 1 at O, plus the reaction -lambda[3:6] at A).

Inertia: the textbook's links are slender bars (I_11 = I_33, I_22 "small"); a truly slender
bar (I_22 = 0) makes M singular (omega_i2 has no inertia), so the defaults give each bar a
radius r = 0.02 m: I_22 = m r^2/2, I_11 = I_33 = m l^2/12 (docs/textbook.md, Example 4).
"""

from __future__ import annotations

import math

import numpy as np
import sympy as sp

from reference.system import Body, Model, Parameter, symbols, vec

L1, L2, M1, M2, RADIUS = 1.0, 0.7, 1.0, 0.5, 0.02
PARAMETERS = (
    Parameter("l1", L1, "m", "length of link 1 (O to A)", positive=True),
    Parameter("l2", L2, "m", "length of link 2", positive=True),
    Parameter("m1", M1, "kg", "mass of link 1", positive=True),
    Parameter("m2", M2, "kg", "mass of link 2", positive=True),
    Parameter(
        "I1_11", M1 * L1**2 / 12, "kg m^2", "link 1 central inertia about n11", positive=True
    ),
    Parameter(
        "I1_22",
        M1 * RADIUS**2 / 2,
        "kg m^2",
        "link 1 axial inertia about n12 (r = 0.02 m)",
        positive=True,
    ),
    Parameter(
        "I1_33", M1 * L1**2 / 12, "kg m^2", "link 1 central inertia about n13", positive=True
    ),
    Parameter(
        "I2_11", M2 * L2**2 / 12, "kg m^2", "link 2 central inertia about n21", positive=True
    ),
    Parameter(
        "I2_22",
        M2 * RADIUS**2 / 2,
        "kg m^2",
        "link 2 axial inertia about n22 (r = 0.02 m)",
        positive=True,
    ),
    Parameter(
        "I2_33", M2 * L2**2 / 12, "kg m^2", "link 2 central inertia about n23", positive=True
    ),
    Parameter("g", 9.81, "m/s^2", "gravitational acceleration (along -N2)", nonnegative=True),
)
(l1, l2, m1, m2, I1_11, I1_22, I1_33, I2_11, I2_22, I2_33, g) = (p.symbol for p in PARAMETERS)
GRAVITY = vec(0, -g, 0)  # N2 up

# Default state: both links swung away from the hanging pose (theta_i2 = pi/2 is regular)
ANGLES0 = (
    (-math.pi / 2 + 0.4, math.pi / 2 + 0.3, math.pi / 2 - 0.2),
    (-math.pi / 2 - 0.5, math.pi / 2 - 0.6, math.pi / 2 + 0.35),
)
OMEGA0 = ((0.8, 0.3, -1.1), (-0.6, 0.5, 1.4))


def R313(a, b, c):
    """The textbook's 3-1-3 matrix R (N components -> body components), sympy or float."""
    if all(isinstance(x, (int, float)) for x in (a, b, c)):
        C1, S1, C2, S2, C3, S3 = (
            math.cos(a),
            math.sin(a),
            math.cos(b),
            math.sin(b),
            math.cos(c),
            math.sin(c),
        )
        mk = np.array
    else:
        C1, S1, C2, S2, C3, S3 = (sp.cos(a), sp.sin(a), sp.cos(b), sp.sin(b), sp.cos(c), sp.sin(c))
        mk = sp.Matrix
    return mk(
        [
            [C1 * C3 - S1 * C2 * S3, S1 * C3 + C1 * C2 * S3, S2 * S3],
            [-C1 * S3 - S1 * C2 * C3, -S1 * S3 + C1 * C2 * C3, S2 * C3],
            [S1 * S2, -C1 * S2, C2],
        ]
    )


def kinematics_313(angles, w):
    """3-1-3 kinematic differential equations: angle rates from body-fixed omega."""
    _, b, c = angles
    S2, C2, S3, C3 = sp.sin(b), sp.cos(b), sp.sin(c), sp.cos(c)
    p = (w[0] * S3 + w[1] * C3) / S2
    return (p, w[0] * C3 - w[1] * S3, w[2] - C2 * p)


def mass_center_velocities(angles1, angles2, w1, w2, lengths=(L1, L2)):
    """Consistent (v_G1, v_G2) in N components from the angles and body-fixed omegas (floats)."""
    a, b = lengths
    R1, R2 = R313(*angles1), R313(*angles2)
    h1, h2 = np.array([-w1[2], 0.0, w1[0]]), np.array([-w2[2], 0.0, w2[0]])
    v1 = -(a / 2) * R1.T @ h1
    v2 = -a * R1.T @ h1 - (b / 2) * R2.T @ h2
    return v1, v2


def consistent_speeds(angles1, angles2, w1, w2, lengths=(L1, L2)) -> tuple[float, ...]:
    v1, v2 = mass_center_velocities(angles1, angles2, w1, w2, lengths)
    return tuple(float(x) for x in (*w1, *w2, *v1, *v2))


def _sampler(rng, params):
    """Random consistent state: theta_i2 in [0.3, pi - 0.3] (away from the 3-1-3 singularity),
    the other angles on the circle, omega ~ U(-3, 3)^3 per link."""
    ang = []
    for _ in range(2):
        ang.append(
            (
                rng.uniform(-math.pi, math.pi),
                rng.uniform(0.3, math.pi - 0.3),
                rng.uniform(-math.pi, math.pi),
            )
        )
    w = [tuple(rng.uniform(-3, 3, 3)) for _ in range(2)]
    u = consistent_speeds(ang[0], ang[1], w[0], w[1], (params["l1"], params["l2"]))
    return (*ang[0], *ang[1]), u


def model() -> Model:
    th1 = symbols("theta11 theta12 theta13")
    th2 = symbols("theta21 theta22 theta23")
    w1 = symbols("w11 w12 w13")
    w2 = symbols("w21 w22 w23")
    v1 = symbols("v11 v12 v13")
    v2 = symbols("v21 v22 v23")
    R1, R2 = R313(*th1), R313(*th2)  # N -> n_i (textbook)
    om1, om2 = vec(*w1), vec(*w2)
    rho1, rhoA, rho2 = vec(0, -l1 / 2, 0), vec(0, -l1, 0), vec(0, -l2 / 2, 0)  # body components
    r_G1 = R1.T * rho1
    r_A = R1.T * rhoA
    r_G2 = r_A + R2.T * rho2
    kin = kinematics_313(th1, w1) + kinematics_313(th2, w2)
    # v_G - omega x r written with +1 on the v's; omega x r in N components is R^T (omega_b x r_b)
    c1 = vec(*v1) - R1.T * om1.cross(rho1)
    c2 = vec(*v2) - R1.T * om1.cross(rhoA) - R2.T * om2.cross(rho2)
    links = (
        Body(
            "link1",
            m1,
            v_G=vec(*v1),
            v_frame="inertial",
            inertia=sp.diag(I1_11, I1_22, I1_33),
            omega=om1,
            r_G=r_G1,
            R=R1.T,
        ),
        Body(
            "link2",
            m2,
            v_G=vec(*v2),
            v_frame="inertial",
            inertia=sp.diag(I2_11, I2_22, I2_33),
            omega=om2,
            r_G=r_G2,
            R=R2.T,
        ),
    )
    return Model(
        name="double_pendulum_3d",
        source="Example 4",
        title="3D double pendulum (ball joints at O and A), Kane with 12 dependent speeds",
        parameters=PARAMETERS,
        coordinates=th1 + th2,
        speeds=w1 + w2 + v1 + v2,
        kinematics=kin,
        bodies=links,
        gravity=GRAVITY,
        motion_constraints=tuple(c1) + tuple(c2),
        constraint_names=("G1_1", "G1_2", "G1_3", "G2_1", "G2_2", "G2_3"),
        multiplier_meaning="lambda[3:6]: force of link 1 on link 2 at A (N components); "
        "lambda[0:3] = F_O - lambda[3:6], with F_O the ground's force on "
        "link 1 at O",
        geometry_note="N2 vertical up; links hang along -n_i2; bars of radius 0.02 m for the "
        "axial inertias",
        formulations=("kane",),
        initial_q=ANGLES0[0] + ANGLES0[1],
        initial_u=consistent_speeds(ANGLES0[0], ANGLES0[1], OMEGA0[0], OMEGA0[1]),
        energy_conserved=True,
        state_sampler=_sampler,
    )
