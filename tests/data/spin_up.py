"""Written for multibody-crosscheck: a mechanism that spins up. A pendulum driven by a torque
growing as t**6 reaches about 2e4 rad/s in 5 s; over that horizon the reference's own run
cannot vouch for its work-energy balance, over 2 s it can. The loader calls models()."""

import sympy as sp

from reference.forces import applied_torque
from reference.system import Body, Model, Parameter, rate, symbols, vec

T = sp.Symbol("t", real=True)


def spin_up() -> Model:
    params = (
        Parameter("m", 1.0, "kg", "bob mass", positive=True),
        Parameter("L", 1.0, "m", "rod length", positive=True),
        Parameter("g", 9.81, "m/s^2", "gravity", nonnegative=True),
        Parameter("A", 40.0, "N m/s^6", "torque growth"),
    )
    m, L, g, A = (p.symbol for p in params)
    (th,), (thd,) = symbols("theta"), symbols("theta_dot")
    r = vec(L * sp.sin(th), -L * sp.cos(th), 0)
    motor = applied_torque(
        "motor",
        vec(0, 0, thd),
        lambda t, q, u: (0, 0, A * t**6),
        coordinates=(th,),
        speeds=(thd,),
    )
    return Model(
        name="spin_up",
        source="tests/data/spin_up.py",
        title="Pendulum spun up by a growing torque",
        parameters=params,
        coordinates=(th,),
        speeds=(thd,),
        kinematics=(thd,),
        bodies=(Body("bob", m, v_G=rate(r, (th,), (thd,), T), r_G=r),),
        gravity=vec(0, -g, 0),
        formulations=("lagrange",),
        initial_q=(0.4,),
        initial_u=(0.0,),
        loads=motor.loads,
    )


def models():
    return [spin_up()]
