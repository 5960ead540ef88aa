"""Exercises 6.5-6.7: the symmetric spinning top with Euler parameters.

Top T (mass m, central inertias I1 = I2 = I, I3 about e1, e2, e3) on a fixed point O (a ball
and socket), mass center G at distance L from O along e3; gravity -g N3. Orientation: Euler
parameters eps = (eps1, eps2, eps3, eps4), eps4 the scalar part, with body-fixed
  omega = 2 E(eps) eps',  E = [[e4, e3, -e2, -e1], [-e3, e4, e1, -e2], [e2, -e1, e4, -e3]]
and the body -> inertial rotation consistent with it (R^T R' = skew(omega) on eps.eps = 1,
eps.eps' = 0; checked in tests/test_models_3d.py), every entry a homogeneous quadratic:
  R = (e4^2 - ev.ev) 1 + 2 ev ev^T + 2 e4 skew(ev),   ev = (e1, e2, e3)
so L R e3 = L (2(e1e3 + e2e4), 2(e2e3 - e1e4), e3^2 + e4^2 - e1^2 - e2^2), the printed
position rows of 6.7. The normalization f = (eps.eps - 1)/2 gives the textbook's velocity row
eps . eps' = 0 (the fourth row of its kinematical differential equations).

- Exercises 6.5/6.6 (`euler_model`): coordinates eps, speeds their rates. G's velocity is
  written v_G = omega x L e3 (body components), so its partial velocities 2 E_k x L e3, like
  the partial angular velocities 2 E_k, are orthogonal to eps (E eps = 0): summing eps_k times
  d'Alembert's equation k leaves lambda eps.eps = 0, Exercise 6.6's lambda = 0. Kane's
  equations with the rates as speeds are the same equations. Lagrange's equations differ by a
  multiple of the constraint gradient: K is homogeneous of degree 2 in eps and in eps' and
  eps . dK/deps' = 0, and V = m g L R33 is homogeneous of degree 2 in eps, so
  lambda = 2V - 4K. The motion is the same; the multiplier is formulation-dependent.
- Exercise 6.7 (`cartesian_model`): coordinates (x1, x2, x3, eps1..eps4), G's base-frame
  coordinates added; constraints x - L R e3 = 0 (three rows, +1 on x, as printed) and the
  normalization. (lambda1, lambda2, lambda3) is the force of the socket on the top at O
  (m x'' = lambda - m g N3). lambda4 is again formulation-dependent: with d'Alembert (and
  Kane) eps times the Euler-parameter rows gives lambda4 = 2 x . (lambda1, lambda2, lambda3).

M is singular in the Euler parameters (4 E^T I_O E has rank 3); reference.backends.codegen solves
with M + rho A^T A, which leaves the solution unchanged because M is definite on the null space of
A.

Default top: m = 0.5 kg, L = 0.05 m, I = 2.5e-4 kg m^2, I3 = 4e-4 kg m^2 (a disk-like top of
radius ~4 cm), spun at 60 rad/s about e3 with its axis tilted ~0.5 rad from the vertical.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from reference.system import Body, Model, Parameter, symbols, vec

PARAMETERS = (
    Parameter("m", 0.5, "kg", "mass of the top", positive=True),
    Parameter(
        "L", 0.05, "m", "distance from the fixed point O to the mass center G", positive=True
    ),
    Parameter("I", 2.5e-4, "kg m^2", "central inertia about e1 and e2", positive=True),
    Parameter("I3", 4.0e-4, "kg m^2", "central inertia about the symmetry axis e3", positive=True),
    Parameter("g", 9.81, "m/s^2", "gravitational acceleration (along -N3)", nonnegative=True),
)
m, L, I, I3, g = (p.symbol for p in PARAMETERS)
GRAVITY = vec(0, 0, -g)

_EPS0 = np.array([0.2, 0.15, 0.1, 0.95])
EPS0 = tuple(float(x) for x in _EPS0 / np.linalg.norm(_EPS0))
OMEGA0 = (0.4, -0.3, 60.0)


def E_matrix(e):
    """The textbook's 3x4 E(eps): omega = 2 E eps' (sympy for symbols, numpy for floats)."""
    e1, e2, e3, e4 = e
    rows = [[e4, e3, -e2, -e1], [-e3, e4, e1, -e2], [e2, -e1, e4, -e3]]
    return np.array(rows, float) if all(isinstance(x, float) for x in e) else sp.Matrix(rows)


def rotation(e):
    """Body -> inertial rotation matrix, homogeneous quadratic in eps (sympy or numpy)."""
    e1, e2, e3, e4 = e
    rows = [
        [e4**2 + e1**2 - e2**2 - e3**2, 2 * (e1 * e2 - e3 * e4), 2 * (e1 * e3 + e2 * e4)],
        [2 * (e1 * e2 + e3 * e4), e4**2 - e1**2 + e2**2 - e3**2, 2 * (e2 * e3 - e1 * e4)],
        [2 * (e1 * e3 - e2 * e4), 2 * (e2 * e3 + e1 * e4), e4**2 - e1**2 - e2**2 + e3**2],
    ]
    return np.array(rows, float) if all(isinstance(x, float) for x in e) else sp.Matrix(rows)


def eps_rates(eps, omega) -> tuple[float, ...]:
    """eps' = E^T omega / 2: the rates that give body-fixed omega and keep eps . eps' = 0."""
    return tuple(float(x) for x in 0.5 * E_matrix(tuple(map(float, eps))).T @ np.asarray(omega))


def position_and_velocity(eps, eps_dot, L_value):
    """x = L R e3 and x' = its rate (floats), the consistent G coordinates of Exercise 6.7."""
    e1, e2, e3, e4 = eps
    d1, d2, d3, d4 = eps_dot
    x = L_value * np.array(
        [2 * (e1 * e3 + e2 * e4), 2 * (e2 * e3 - e1 * e4), e3**2 + e4**2 - e1**2 - e2**2]
    )
    xd = L_value * np.array(
        [
            2 * (d1 * e3 + e1 * d3 + d2 * e4 + e2 * d4),
            2 * (d2 * e3 + e2 * d3 - d1 * e4 - e1 * d4),
            2 * (e3 * d3 + e4 * d4 - e1 * d1 - e2 * d2),
        ]
    )
    return tuple(map(float, x)), tuple(map(float, xd))


def _random_orientation(rng):
    eps = rng.standard_normal(4)
    eps = tuple(float(x) for x in eps / np.linalg.norm(eps))
    omega = (rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-80, 80))
    return eps, eps_rates(eps, omega)


def _euler_sampler(rng, params):
    """Random unit eps (uniform rotation) and omega with a fast spin about e3."""
    return _random_orientation(rng)


def _cartesian_sampler(rng, params):
    eps, eps_dot = _random_orientation(rng)
    x, xd = position_and_velocity(eps, eps_dot, params["L"])
    return x + eps, xd + eps_dot


_NORM_REASON = (
    "the Euler-parameter normalization: Lagrange's K(eps, eps') and V(eps) see "
    "variations off the unit sphere that d'Alembert's partial velocities 2 E_k do "
    "not (Exercise 6.6: lambda = 0 with d'Alembert, 2V - 4K with Lagrange)"
)


def _top_body(eps, eps_dot, v_G, v_frame, r_G) -> Body:
    return Body(
        "top",
        m,
        v_G=v_G,
        v_frame=v_frame,
        inertia=sp.diag(I, I, I3),
        omega=2 * E_matrix(eps) * sp.Matrix(eps_dot),
        r_G=r_G,
        R=rotation(eps),
    )


def euler_model() -> Model:
    eps = symbols("eps1 eps2 eps3 eps4")
    eps_dot = symbols("eps1_dot eps2_dot eps3_dot eps4_dot")
    omega = 2 * E_matrix(eps) * sp.Matrix(eps_dot)
    top = _top_body(
        eps,
        eps_dot,
        v_G=omega.cross(vec(0, 0, L)),
        v_frame="body",
        r_G=rotation(eps) * vec(0, 0, L),
    )
    return Model(
        name="top_euler",
        source="Exercises 6.5/6.6",
        title="Symmetric top on a fixed point, four Euler parameters (d'Alembert)",
        parameters=PARAMETERS,
        coordinates=eps,
        speeds=eps_dot,
        kinematics=eps_dot,
        bodies=(top,),
        gravity=GRAVITY,
        configuration_constraints=((sum(e**2 for e in eps) - 1) / 2,),
        constraint_names=("norm",),
        multiplier_meaning="d'Alembert and Kane: lambda = 0 (Exercise 6.6); Lagrange: "
        "lambda = 2V - 4K (V = m g L R33 homogeneous in eps). The "
        "normalization's multiplier is formulation-dependent",
        formulations=("dalembert", "lagrange", "kane"),
        formulation_dependent_rows=(("norm", _NORM_REASON),),
        initial_q=EPS0,
        initial_u=eps_rates(EPS0, OMEGA0),
        energy_conserved=True,
        state_sampler=_euler_sampler,
    )


def cartesian_model() -> Model:
    x = symbols("x1 x2 x3")
    xd = symbols("x1_dot x2_dot x3_dot")
    eps = symbols("eps1 eps2 eps3 eps4")
    eps_dot = symbols("eps1_dot eps2_dot eps3_dot eps4_dot")
    q, u = x + eps, xd + eps_dot
    top = _top_body(eps, eps_dot, v_G=vec(*xd), v_frame="inertial", r_G=vec(*x))
    tie = vec(*x) - L * rotation(eps) * vec(0, 0, 1)  # x - L R e3 = 0, +1 on x (as printed)
    x0, xd0 = position_and_velocity(EPS0, eps_rates(EPS0, OMEGA0), PARAMETERS[1].default)
    return Model(
        name="top_cartesian",
        source="Exercise 6.7",
        title="Symmetric top, mass-center coordinates and Euler parameters (d'Alembert)",
        parameters=PARAMETERS,
        coordinates=q,
        speeds=u,
        kinematics=u,
        bodies=(top,),
        gravity=GRAVITY,
        configuration_constraints=(*tuple(tie), (sum(e**2 for e in eps) - 1) / 2),
        constraint_names=("O_1", "O_2", "O_3", "norm"),
        multiplier_meaning="(lambda1, lambda2, lambda3): force of the socket on the top at O "
        "(N components); lambda4: normalization, formulation-dependent",
        formulations=("dalembert", "kane"),
        formulation_dependent_rows=(("norm", _NORM_REASON),),
        initial_q=x0 + EPS0,
        initial_u=xd0 + eps_rates(EPS0, OMEGA0),
        energy_conserved=True,
        state_sampler=_cartesian_sampler,
    )
