"""IFToMM multibody benchmark A01, the simple pendulum, as a Python model file.

A point mass m = 1 kg on a massless rigid rod of length L = 1 m, pivoted at the origin, under
gravity g = 9.81 m/s^2 (-Y), released from rest with the rod horizontal, simulated for 10 s.
Written in Cartesian coordinates (x, y) of the mass with the rod as the constraint
(x^2 + y^2 - L^2) / 2 = 0, so the multiplier is the rod force: lambda = -T / L for a rod
tension T, and at the lowest point (speed sqrt(2 g L)) T = 3 m g = 29.43 N.

    crosscheck run --model-file examples/iftomm_a01_pendulum.py --t-end 10 --out out/a01

The loader calls models(); the public API used here is documented in docs/user_models.md.
"""

import sympy as sp

from reference.system import Body, Model, Parameter, rate, symbols, vec

T = sp.Symbol("t", real=True)


def a01_pendulum() -> Model:
    params = (
        Parameter("m", 1.0, "kg", "point mass", positive=True),
        Parameter("L", 1.0, "m", "rod length", positive=True),
        Parameter("g", 9.81, "m/s^2", "gravity", nonnegative=True),
    )
    m, L, g = (p.symbol for p in params)
    x, y = symbols("x y")
    xd, yd = symbols("x_dot y_dot")
    q, u = (x, y), (xd, yd)
    r = vec(x, y, 0)
    return Model(
        name="iftomm_a01_pendulum",
        source="IFToMM multibody benchmark A01 (simple pendulum)",
        title="Simple pendulum, 1 m, 1 kg, released horizontal (IFToMM A01)",
        parameters=params,
        coordinates=q,
        speeds=u,
        kinematics=u,
        bodies=(Body("mass", m, v_G=rate(r, q, u, T), r_G=r),),
        gravity=vec(0, -g, 0),
        configuration_constraints=((x**2 + y**2 - L**2) / 2,),
        constraint_names=("rod",),
        multiplier_meaning="lambda * L is the rod's force on the mass along -r/L (tension "
        "positive): lambda = -T / L",
        formulations=("lagrange", "dalembert", "kane"),
        initial_q=(1.0, 0.0),
        initial_u=(0.0, 0.0),
        energy_conserved=True,
    )


def models():
    return [a01_pendulum()]
