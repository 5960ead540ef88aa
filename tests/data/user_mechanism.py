"""Written for multibody-crosscheck: a Python model file as a user writes one.

A point mass on a horizontal plane (x, y) tied to the origin by a spring-damper, and a
pendulum (one angle) with a joint damper and a time-dependent driving torque, both with the
public API (reference.system, reference.forces). The loader calls models().
"""

import sympy as sp

from reference.forces import applied_torque, combine, joint_damper, spring_damper
from reference.system import Body, Model, Parameter, rate, symbols, vec

T = sp.Symbol("t", real=True)


def tethered_mass() -> Model:
    params = (
        Parameter("m", 0.7, "kg", "mass", positive=True),
        Parameter("k", 40.0, "N/m", "spring stiffness", nonnegative=True),
        Parameter("c", 0.9, "N s/m", "damping", nonnegative=True),
        Parameter("L0", 0.5, "m", "free length", positive=True),
    )
    m, k, c, L0 = (p.symbol for p in params)
    x, y = symbols("x y")
    xd, yd = symbols("x_dot y_dot")
    q, u = (x, y), (xd, yd)
    r = vec(x, y, 0)
    fe = spring_damper(
        "tether",
        vec(0, 0, 0),
        r,
        stiffness=k,
        damping=c,
        free_length=L0,
        coordinates=q,
        kinematics=u,
    )
    return Model(
        name="tethered_mass",
        source="tests/data/user_mechanism.py",
        title="Point mass on a spring-damper tether",
        parameters=params,
        coordinates=q,
        speeds=u,
        kinematics=u,
        bodies=(Body("mass", m, v_G=rate(r, q, u, T), r_G=r),),
        formulations=("lagrange", "kane"),
        initial_q=(0.8, 0.1),
        initial_u=(0.0, 1.5),
        potential=fe.potential,
        loads=fe.loads,
    )


def driven_pendulum() -> Model:
    params = (
        Parameter("m", 1.2, "kg", "bob mass", positive=True),
        Parameter("L", 0.9, "m", "rod length", positive=True),
        Parameter("g", 9.81, "m/s^2", "gravity", nonnegative=True),
        Parameter("d", 0.15, "N m s", "joint damping", nonnegative=True),
        Parameter("A", 0.8, "N m", "torque amplitude"),
        Parameter("w", 3.0, "rad/s", "torque frequency"),
    )
    m, L, g, d, A, w = (p.symbol for p in params)
    (th,), (thd,) = symbols("theta"), symbols("theta_dot")
    r = vec(L * sp.sin(th), -L * sp.cos(th), 0)
    fe = combine(
        joint_damper("pivot", thd, d),
        applied_torque(
            "motor",
            vec(0, 0, thd),
            lambda t, q, u: (0, 0, A * sp.sin(w * t)),
            coordinates=(th,),
            speeds=(thd,),
        ),
    )
    return Model(
        name="driven_pendulum",
        source="tests/data/user_mechanism.py",
        title="Pendulum with a joint damper and a sinusoidal motor torque",
        parameters=params,
        coordinates=(th,),
        speeds=(thd,),
        kinematics=(thd,),
        bodies=(Body("bob", m, v_G=rate(r, (th,), (thd,), T), r_G=r),),
        gravity=vec(0, -g, 0),
        formulations=("lagrange", "kane", "dalembert"),
        initial_q=(0.4,),
        initial_u=(0.0,),
        loads=fe.loads,
    )


def models():
    return [tethered_mass(), driven_pendulum()]
