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

import hashlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import sympy as sp

from reference.errors import ModelDefinitionError

Frame = Literal["inertial", "body"]
FORMULATIONS = ("lagrange", "dalembert", "kane")


@dataclass(frozen=True)
class Parameter:
    """A physical parameter: the textbook's symbol in ASCII, a value with SI unit, and its role."""

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

    mass: its mass; inertia: central inertia matrix in body-fixed components; omega: angular
    velocity, body-fixed components; v_G: mass-center velocity, components in `v_frame`;
    r_G: inertial position of the mass center (for the gravity potential and the engines);
    R: rotation matrix body -> inertial (columns are the body axes in inertial components).
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
    """An applied force F at a point moving with velocity v (same frame components)."""

    name: str
    velocity: sp.Matrix
    force: sp.Matrix


@dataclass(frozen=True)
class Torque:
    """An applied torque acting on a body with angular velocity omega (same frame components).

    For a torque between two bodies (a motor, a torsional spring-damper) give the relative
    angular velocity: the generalized force is torque . d(omega)/d(speed), Eqs. 5-9.
    """

    name: str
    omega: sp.Matrix
    torque: sp.Matrix


@dataclass(frozen=True)
class Model:
    """A constrained mechanical system as the unit declares it.

    coordinates q, speeds u, kinematics q' = N(q, u, t) (one expression per coordinate; for
    Lagrange's and d'Alembert's models u_k = q'_k). Configuration constraints f_j(q, t) = 0
    (Eq. 1) are written so that df_j/dt gives the textbook's velocity row exactly (Eqs. 2-4),
    because sign and scale of each multiplier follow its row. Motion constraints are written as
    expressions linear in the speeds, A u + a0 (Eq. 8).
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
    # springs; gravity's potential is derived from the bodies (sympy's zero is an immutable
    # singleton, so one default object shared by every Model is safe)
    potential: sp.Expr = sp.Integer(0)  # noqa: RUF009
    configuration_constraints: tuple[sp.Expr, ...] = ()
    motion_constraints: tuple[sp.Expr, ...] = ()
    constraint_names: tuple[str, ...] = ()
    geometry_note: str = ""  # assumptions where the textbook's figure was lost
    multiplier_meaning: str = ""  # what lambda is physically (Addendum)
    energy_conserved: bool = False  # no non-conservative loads, scleronomic constraints
    # constraint rows whose multiplier depends on the formulation, with the reason (the motion
    # does not): e.g. the Euler-parameter normalization row of the top (Exercise 6.6)
    formulation_dependent_rows: tuple[tuple[str, str], ...] = ()
    state_sampler: Callable | None = None  # rng, params -> (q, u) consistent (optional)
    # Dependent constraint rows are allowed (user models: a planar loop closed by a 3-D MJCF
    # `connect` has a row that repeats the others). NumericModel then solves on the independent
    # rows, gives the unique u' and A^T lambda and the minimum-norm lambda with the rank
    # (reference.numeric.redundant); False keeps the unit's rule that rank(A) = m (Eq. 4
    # discussion).
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
        """Total time derivative, substituting q' = N(q, u, t) and u' = `accelerations` symbols.

        With accelerations None the u' terms are dropped (useful for bias terms).
        """
        if isinstance(expr, sp.MatrixBase):
            return expr.applyfunc(lambda e: self.time_derivative(e, accelerations))
        out = rate(expr, self.coordinates, self.kinematics, self.t)
        if accelerations is not None:
            for u, ud in zip(self.speeds, accelerations, strict=True):
                out += sp.diff(expr, u) * ud
        return out

    def load_power(self) -> sp.Expr:
        """Power of the applied loads (forces and torques; gravity and springs excluded)."""
        P = sp.Integer(0)
        for ld in self.loads:
            if isinstance(ld, Force):
                P += (ld.force.T * ld.velocity)[0]
            else:
                P += (ld.torque.T * ld.omega)[0]
        return P

    def content_hash(self) -> str:
        """A hash of everything that defines the equations (for the derivation cache). The name
        is left out: it is the cache entry's readable prefix, not part of the physics. Kept on
        the instance after the first call: the model is frozen, and printing its expressions
        costs about 9 ms, on every NumericModel built from it."""
        if "_content_hash" not in self.__dict__:
            object.__setattr__(self, "_content_hash", self._hash_content())
        return self.__dict__["_content_hash"]

    def _hash_content(self) -> str:
        parts = [repr(self.formulations)]
        parts += [sp.srepr(x) for x in self.coordinates + self.speeds + self.kinematics]
        for b in self.bodies:
            parts += [b.name, b.v_frame] + [
                sp.srepr(x) for x in (b.mass, b.v_G, b.inertia, b.omega, b.r_G, b.R)
            ]
        for ld in self.loads:
            parts += [type(ld).__name__, ld.name] + [
                sp.srepr(x) for x in vars(ld).values() if not isinstance(x, str)
            ]
        parts += [sp.srepr(self.gravity), sp.srepr(self.potential)]
        parts += [sp.srepr(x) for x in self.configuration_constraints + self.motion_constraints]
        parts += [p.name for p in self.parameters]
        parts.append(f"redundant={self.redundant_constraints}")  # the code differs (codegen)
        return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:20]

    def validate(self) -> None:
        """Collect every inconsistency in the declaration and raise once."""
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
        unknown = set().union(*(sp.sympify(e).free_symbols for e in exprs)) - known
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
