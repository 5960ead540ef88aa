"""Force elements for Model declarations: springs, dampers and applied loads by name.

A Model carries forces in two places (reference.system): `potential` (conservative springs;
gravity comes from the bodies) and `loads` (Force and Torque objects: a force at a point with
the point's velocity, a torque with the angular velocity it acts through). The elements here
write both for the common cases, so a published mechanism needs no hand-written potential:

    springs = spring_damper("AB", r_A, r_B, stiffness=k, damping=c, free_length=L0,
                            coordinates=q, kinematics=N)
    motor = applied_torque("motor", omega=vec(0, 0, th1_dot), torque=lambda t, q, u: ...,
                           coordinates=q, speeds=u)
    fe = combine(springs, joint_damper("hinge", th1_dot, 0.1), motor)
    Model(..., potential=fe.potential, loads=fe.loads, energy_conserved=False)

Every quantity is a sympy expression of the coordinates q, speeds u, time t and the model's
parameters; a callable given for a force or torque is called once with those symbols
(f(t, q, u)) and must return sympy-compatible expressions (sympy functions such as sp.sin,
not numpy or math ones). A spring's potential keeps energy bookkeeping exact; a damper or an
applied load enters the work-energy balance through Model.load_power.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import sympy as sp

from reference.errors import ModelInputError
from reference.system import Force, Torque, rate, vec

T_SYM = sp.Symbol("t", real=True)  # the Model's default time symbol

VectorSpec = sp.Matrix | Sequence | Callable


@dataclass(frozen=True)
class ForceElements:
    """A potential and loads to give a Model (potential=..., loads=...)."""

    potential: sp.Expr = sp.S.Zero
    loads: tuple = ()

    def __add__(self, other: ForceElements) -> ForceElements:
        return ForceElements(self.potential + other.potential, self.loads + other.loads)


def combine(*elements: ForceElements) -> ForceElements:
    """All elements together (their potentials add, their loads are concatenated)."""
    out = ForceElements()
    for e in elements:
        out = out + e
    return out


def _column(value, name: str) -> sp.Matrix:
    M = sp.Matrix(value) if not isinstance(value, sp.MatrixBase) else value
    if M.shape != (3, 1):
        M = M.reshape(M.shape[0] * M.shape[1], 1) if len(M) == 3 else M
    if M.shape != (3, 1):
        raise ModelInputError(f"force element {name!r}: expected 3 components, got {M.shape}")
    return M.applyfunc(sp.sympify)


def _evaluate(spec: VectorSpec, name: str, t, coordinates, speeds) -> sp.Matrix:
    """A 3-vector given directly or as f(t, q, u) called with the model's symbols."""
    if callable(spec) and not isinstance(spec, sp.MatrixBase):
        try:
            spec = spec(t, tuple(coordinates), tuple(speeds))
        except TypeError as exc:  # numpy/math functions reject sympy symbols
            raise ModelInputError(
                f"force element {name!r}: its function must accept sympy symbols "
                f"(t, q, u) and use sympy functions (sp.sin, not math.sin): {exc}"
            ) from exc
    return _column(spec, name)


def spring_damper(
    name: str, r_A, r_B, *, stiffness, free_length, damping=0, coordinates, kinematics, t=T_SYM
) -> ForceElements:
    """A linear spring-damper between points A and B (inertial positions r_A, r_B as functions
    of q and t): tension k (L - L0) + c L' along the line, L = |r_B - r_A|.

    The spring is the potential k (L - L0)^2 / 2; the damper is one Force, -c L' e acting through
    the relative velocity v_B - v_A (its generalized force is the sum of the two point forces).
    L must stay positive (the line of action is undefined at L = 0).
    """
    r_A, r_B = _column(r_A, name), _column(r_B, name)
    d = r_B - r_A
    L = sp.sqrt((d.T * d)[0])
    V = sp.Rational(1, 2) * sp.sympify(stiffness) * (L - sp.sympify(free_length)) ** 2
    loads: tuple = ()
    if sp.sympify(damping) != 0:
        v_rel = rate(d, coordinates, kinematics, t)
        e = d / L
        L_dot = (e.T * v_rel)[0]
        loads = (Force(f"{name}:damper", velocity=v_rel, force=-sp.sympify(damping) * L_dot * e),)
    return ForceElements(V, loads)


def joint_spring(name: str, coordinate, stiffness, reference=0) -> ForceElements:
    """A linear spring on one coordinate: potential k (q - q_ref)^2 / 2."""
    return ForceElements(
        sp.Rational(1, 2) * sp.sympify(stiffness) * (coordinate - sp.sympify(reference)) ** 2
    )


def joint_damper(name: str, rate_expr, damping) -> ForceElements:
    """A linear damper on a joint rate w (a speed, or any expression linear in the speeds):
    generalized force -c w dw/du. It is written as a Force along a one-component 'velocity' w,
    so its power is -c w^2 (Model.load_power)."""
    w = sp.sympify(rate_expr)
    return ForceElements(
        loads=(
            Force(
                f"{name}:damper", velocity=vec(w, 0, 0), force=vec(-sp.sympify(damping) * w, 0, 0)
            ),
        )
    )


def applied_force(
    name: str, point, force: VectorSpec, *, coordinates, speeds, kinematics, t=T_SYM
) -> ForceElements:
    """A force at a point (inertial position `point` as a function of q, t): the force is a
    3-vector in inertial components, or f(t, q, u) returning one (a function of time and
    state)."""
    r = _column(point, name)
    F = _evaluate(force, name, t, coordinates, speeds)
    return ForceElements(
        loads=(Force(name, velocity=rate(r, coordinates, kinematics, t), force=F),)
    )


def applied_torque(
    name: str, omega, torque: VectorSpec, *, coordinates, speeds, t=T_SYM
) -> ForceElements:
    """A torque acting through the angular velocity `omega` (components in the same frame as
    the torque; the relative angular velocity for a torque between two bodies, a motor): a
    3-vector or f(t, q, u) returning one."""
    return ForceElements(
        loads=(
            Torque(
                name,
                omega=_column(omega, name),
                torque=_evaluate(torque, name, t, coordinates, speeds),
            ),
        )
    )
