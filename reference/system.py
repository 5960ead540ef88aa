"""One declaration per model: parameters, coordinates, speeds, bodies, loads, constraints.

A `Model` is frozen data. Formulations (reference.formulations) are functions over it and never
rebuild its geometry. All expressions use plain sympy Symbols (no dynamicsymbols): coordinates q,
speeds u and time t are symbols, and time derivatives are taken with `Model.time_derivative`, which
substitutes the kinematic differential equations q' = N(q, u, t).

Vector conventions. Every vector is a 3x1 sympy Matrix of components in a named frame:
``"inertial"`` or ``"body"`` (the body's own fixed frame). Dot products are taken between
components in the same frame, so a body's mass-center velocity, the loads acting on it and the
gravity vector must be expressed consistently (gravity is rotated into the body frame with the
body's rotation matrix ``R`` when its velocity is in body components).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import sympy as sp

from reference.dag import digest, free_symbols
from reference.errors import ModelDefinitionError

Frame = Literal["inertial", "body"]
FORMULATIONS = ("lagrange", "dalembert", "kane")


@dataclass(frozen=True)
class Parameter:
    """A physical parameter: the textbook's symbol in ASCII, a value with SI unit, and its role.

    Parameters
    ----------
    name : str
        The textbook's symbol in ASCII (``m``, ``L``, ``I_zz``); also the sympy symbol's name.
    default : float
        The value a model is evaluated at unless overridden (``--set``, NumericModel's params).
    unit : str
        Its SI unit.
    description : str
        What it is, in a few words.
    positive, nonnegative : bool
        Its admissible range: masses, lengths and inertias > 0; damping, stiffness, gravity
        >= 0. NumericModel refuses a value outside it.
    """

    name: str
    default: float
    unit: str
    description: str
    positive: bool = False  # masses, lengths, inertias: must be > 0
    nonnegative: bool = False  # damping, stiffness, gravity: must be >= 0

    @property
    def symbol(self) -> sp.Symbol:
        return sp.Symbol(self.name, real=True)


@dataclass(frozen=True)
class Body:
    """A rigid body (or, with zero inertia and omega, a particle).

    Parameters
    ----------
    name : str
    mass : sympy expression
    v_G : sympy Matrix (3x1)
        Mass-center velocity, components in `v_frame`.
    v_frame : {"inertial", "body"}
    inertia : sympy Matrix (3x3)
        Central inertia matrix in body-fixed components (zero for a particle).
    omega : sympy Matrix (3x1)
        Angular velocity, body-fixed components (zero for a particle).
    r_G : sympy Matrix (3x1), optional
        Inertial position of the mass center (the gravity potential, the engines' models).
    R : sympy Matrix (3x3), optional
        Rotation body -> inertial: its columns are the body axes in inertial components.
    """

    name: str
    mass: sp.Expr
    v_G: sp.Matrix
    v_frame: Frame = "inertial"
    inertia: sp.Matrix = field(default_factory=lambda: sp.zeros(3, 3))
    omega: sp.Matrix = field(default_factory=lambda: sp.zeros(3, 1))
    r_G: sp.Matrix | None = None
    R: sp.Matrix | None = None


@dataclass(frozen=True)
class Force:
    """An applied force at a point.

    Parameters
    ----------
    name : str
    velocity : sympy Matrix (3x1)
        The velocity of the point it acts at.
    force : sympy Matrix (3x1)
        The force, in the same frame's components as `velocity`.
    """

    name: str
    velocity: sp.Matrix
    force: sp.Matrix


@dataclass(frozen=True)
class Torque:
    """An applied torque on a body.

    For a torque between two bodies (a motor, a torsional spring-damper) give the relative
    angular velocity: the generalized force is torque . d(omega)/d(speed), Eqs. 5-9.

    Parameters
    ----------
    name : str
    omega : sympy Matrix (3x1)
        The angular velocity of the body it acts on (or the relative one, above).
    torque : sympy Matrix (3x1)
        The torque, in the same frame's components as `omega`.
    """

    name: str
    omega: sp.Matrix
    torque: sp.Matrix


@dataclass(frozen=True)
class Model:
    """A constrained mechanical system as the unit declares it: frozen data, validated by
    `validate` (every problem collected and raised once).

    Parameters
    ----------
    name : str
        The registry name (``crosscheck models``).
    source : str
        Where it comes from ("Example 2(b)", "MJCF file F").
    title : str
    parameters : tuple of Parameter
    coordinates, speeds : tuple of sympy Symbol
        q and u.
    kinematics : tuple of sympy expressions
        q' = N(q, u, t), one per coordinate; Lagrange's and d'Alembert's models need u = q'.
    bodies : tuple of Body
    formulations : tuple of str
        Which of "lagrange", "dalembert", "kane" apply.
    initial_q, initial_u : tuple of float
        A consistent initial state.
    gravity : sympy Matrix (3x1)
        Inertial components.
    loads : tuple of Force or Torque
    potential : sympy expression
        Springs' potential energy (gravity's is derived from the bodies).
    configuration_constraints : tuple of sympy expressions
        f_j(q, t) = 0 (Eq. 1), written so that df_j/dt gives the textbook's velocity row
        exactly (Eqs. 2-4): each multiplier's sign and scale follow its row.
    motion_constraints : tuple of sympy expressions
        A u + a0, linear in the speeds (Eq. 8).
    constraint_names : tuple of str
        One per row, configuration rows first.
    geometry_note : str
        Assumptions made where the textbook's figure was lost.
    multiplier_meaning : str
        What the multipliers are physically (Addendum).
    energy_conserved : bool
        No non-conservative loads and scleronomic constraints: K + V is conserved.
    formulation_dependent_rows : tuple of (str, str)
        Rows whose multiplier depends on the formulation, with the reason (the motion does
        not): the Euler-parameter normalization row of the top (Exercise 6.6).
    state_sampler : callable, optional
        ``(rng, params) -> (q, u)``, a consistent state.
    redundant_constraints : bool
        Dependent rows are allowed (a planar loop closed by a 3-D MJCF connect): the numeric
        model then gives the unique u' and A^T lambda and the minimum-norm lambda with the
        rank (reference.numeric.redundant). False keeps the unit's rule rank(A) = m (Eq. 4).
    t : sympy Symbol
        Time.
    """

    name: str
    source: str
    title: str
    parameters: tuple[Parameter, ...]
    coordinates: tuple[sp.Symbol, ...]
    speeds: tuple[sp.Symbol, ...]
    kinematics: tuple[sp.Expr, ...]
    bodies: tuple[Body, ...]
    formulations: tuple[str, ...]
    initial_q: tuple[float, ...]
    initial_u: tuple[float, ...]
    gravity: sp.Matrix = field(default_factory=lambda: sp.zeros(3, 1))
    loads: tuple[Force | Torque, ...] = ()
    # sympy's zero is an immutable singleton, so one default shared by every Model is safe
    potential: sp.Expr = sp.Integer(0)  # noqa: RUF009
    configuration_constraints: tuple[sp.Expr, ...] = ()
    motion_constraints: tuple[sp.Expr, ...] = ()
    constraint_names: tuple[str, ...] = ()
    geometry_note: str = ""  # assumptions where the textbook's figure was lost
    multiplier_meaning: str = ""  # what lambda is physically (Addendum)
    energy_conserved: bool = False  # no non-conservative loads, scleronomic constraints
    formulation_dependent_rows: tuple[tuple[str, str], ...] = ()
    state_sampler: Callable | None = None  # rng, params -> (q, u) consistent (optional)
    redundant_constraints: bool = False
    t: sp.Symbol = field(default_factory=lambda: sp.Symbol("t", real=True))

    # ---- derived helpers -------------------------------------------------------------------
    @property
    def n_constraints(self) -> int:
        return len(self.configuration_constraints) + len(self.motion_constraints)

    @property
    def parameter_symbols(self) -> tuple[sp.Symbol, ...]:
        return tuple(p.symbol for p in self.parameters)

    @property
    def speeds_are_coordinate_rates(self) -> bool:
        """True when u_k = q'_k, which Lagrange's equations and d'Alembert's principle need."""
        return len(self.speeds) == len(self.coordinates) and all(
            sp.simplify(k - u) == 0 for k, u in zip(self.kinematics, self.speeds, strict=True)
        )

    def time_derivative(self, expr: Any, accelerations: Any = None) -> Any:
        """Total time derivative of an expression of (q, u, t).

        Parameters
        ----------
        expr : sympy expression or Matrix
        accelerations : sequence of sympy Symbol, optional
            The symbols standing for u'. None drops the u' terms (bias terms).

        Returns
        -------
        sympy expression or Matrix
            d(expr)/dt with q' = N(q, u, t) substituted.
        """
        if isinstance(expr, sp.MatrixBase):
            return expr.applyfunc(lambda e: self.time_derivative(e, accelerations))
        out = rate(expr, self.coordinates, self.kinematics, self.t)
        if accelerations is not None:
            for u, ud in zip(self.speeds, accelerations, strict=True):
                out += sp.diff(expr, u) * ud
        return out

    def load_power(self) -> sp.Expr:
        """Power of the applied loads.

        Returns
        -------
        sympy expression
            Sum of force . velocity and torque . omega (gravity and springs excluded: they are
            in the potential).
        """
        P = sp.Integer(0)
        for ld in self.loads:
            if isinstance(ld, Force):
                P += (ld.force.T * ld.velocity)[0]
            else:
                P += (ld.torque.T * ld.omega)[0]
        return P

    def content_hash(self) -> str:
        """A hash of everything that defines the equations (the derivation cache's key).

        The name is left out: it is the cache entry's readable prefix, not physics. Kept on the
        instance after the first call: the model is frozen, and printing its expressions costs
        about 9 ms on every NumericModel built from it.

        Returns
        -------
        str
            20 hexadecimal digits.
        """
        if "_content_hash" not in self.__dict__:
            object.__setattr__(self, "_content_hash", self._hash_content())
        return self.__dict__["_content_hash"]

    def _hash_content(self) -> str:
        # reference.dag.digest writes each distinct subexpression once: a robot's expressions
        # share their parents' (srepr wrote Cassie's out as trees, 70 s)
        parts: list = [repr(self.formulations)]
        parts += [*self.coordinates, *self.speeds, *self.kinematics]
        for b in self.bodies:
            parts += [b.name, b.v_frame, b.mass, b.v_G, b.inertia, b.omega, b.r_G, b.R]
        for ld in self.loads:
            parts += [type(ld).__name__, ld.name]
            parts += [x for x in vars(ld).values() if not isinstance(x, str)]
        parts += [self.gravity, self.potential]
        parts += [*self.configuration_constraints, *self.motion_constraints]
        parts += [p.name for p in self.parameters]
        parts.append(f"redundant={self.redundant_constraints}")  # the code differs (codegen)
        return digest(parts)[:20]

    def validate(self) -> None:
        """Check the declaration.

        Raises
        ------
        reference.errors.ModelDefinitionError
            Every inconsistency at once (sizes, unknown formulations, undeclared symbols,
            asymmetric inertia, a motion constraint not linear in the speeds...).
        """
        problems: list[str] = []
        n, nu = len(self.coordinates), len(self.speeds)
        if len(self.kinematics) != n:
            problems.append(f"{len(self.kinematics)} kinematic equations for {n} coordinates")
        if len(self.initial_q) != n or len(self.initial_u) != nu:
            problems.append(
                f"initial state has {len(self.initial_q)} q and {len(self.initial_u)} u, "
                f"expected {n} and {nu}"
            )
        if self.constraint_names and len(self.constraint_names) != self.n_constraints:
            problems.append(
                f"{len(self.constraint_names)} constraint names for "
                f"{self.n_constraints} constraints"
            )
        bad = [f for f in self.formulations if f not in FORMULATIONS]
        if bad:
            problems.append(f"unknown formulations {bad}; valid: {list(FORMULATIONS)}")
        if {"lagrange", "dalembert"} & set(
            self.formulations
        ) and not self.speeds_are_coordinate_rates:
            problems.append("Lagrange/d'Alembert need speeds equal to the coordinate rates")
        known = set(self.parameter_symbols) | set(self.coordinates) | set(self.speeds) | {self.t}
        exprs = (
            list(self.kinematics)
            + list(self.configuration_constraints)
            + list(self.motion_constraints)
            + [self.potential]
            + list(self.gravity)
        )
        for b in self.bodies:
            exprs += [b.mass, *b.v_G, *b.inertia, *b.omega]
            exprs += list(b.r_G) if b.r_G is not None else []
            exprs += list(b.R) if b.R is not None else []
            if b.v_frame == "body" and b.R is None and any(g != 0 for g in self.gravity):
                problems.append(f"body {b.name}: v_G in body components with gravity needs R")
            if b.inertia != b.inertia.T:
                problems.append(f"body {b.name}: inertia matrix is not symmetric")
        for ld in self.loads:
            exprs += [*(ld.velocity if isinstance(ld, Force) else ld.omega)]
            exprs += [*(ld.force if isinstance(ld, Force) else ld.torque)]
        unknown = free_symbols(sp.sympify(e) for e in exprs) - known
        if unknown:
            problems.append(
                f"undeclared symbols {sorted(map(str, unknown))}: add them as parameters"
            )
        for g in self.motion_constraints:
            for u in self.speeds:
                if sp.simplify(sp.diff(g, u, 2)) != 0:
                    problems.append(f"motion constraint {g} is not linear in the speeds (Eq. 8)")
                    break
        for p in self.parameters:
            if not math.isfinite(p.default):
                problems.append(f"parameter {p.name} default is not finite")
        if problems:
            raise ModelDefinitionError(self.name, problems)


def vec(*components: Any) -> sp.Matrix:
    """A 3x1 component column."""
    return sp.Matrix(components)


def symbols(names: str) -> tuple[sp.Symbol, ...]:
    """Real symbols for coordinates and speeds."""
    out = sp.symbols(names, real=True)
    return out if isinstance(out, tuple) else (out,)


def rot_z(a: Any) -> sp.Matrix:
    """Rotation body -> inertial about the z axis by angle a."""
    c, s = sp.cos(a), sp.sin(a)
    return sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def rot_x(a: Any) -> sp.Matrix:
    c, s = sp.cos(a), sp.sin(a)
    return sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]])


def skew(w: sp.Matrix) -> sp.Matrix:
    return sp.Matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def unskew(S: sp.Matrix) -> sp.Matrix:
    return sp.Matrix([S[2, 1], S[0, 2], S[1, 0]])


def rate(expr: Any, coordinates: Any, kinematics: Any, t: Any = None) -> Any:
    """Time derivative of an expression of (q, t) given q' = kinematics (before a Model exists)."""
    if isinstance(expr, sp.MatrixBase):
        return expr.applyfunc(lambda e: rate(e, coordinates, kinematics, t))
    out = sp.diff(expr, t) if t is not None else sp.Integer(0)
    for q, qdot in zip(coordinates, kinematics, strict=True):
        out += sp.diff(expr, q) * qdot
    return out
