"""The engine contract: what an adapter and a built engine model provide, and what they declare.

An adapter (one per engine, registered under the entry-point group ``crosscheck.engines``)
builds the engine's model of a reference model with one parameter set. A built model maps a
consistent reference state to the engine's state and returns the engine's answers mapped back to
the reference's speeds and multipliers (same order, same sign and scale as the textbook rows).

Callers never probe for methods: they read the adapter's ``capabilities`` (what the engine can
do at all) and, per built model, the optional answers (``mass_matrix`` returns None with
``mass_matrix_note`` saying why). Everything a capability promises is checked for every
registered engine on every model it claims by tests/test_engine_contract.py.

What every adapter would otherwise write again is here once: TableAdapter (models, variants
and build from a table of engine models, through lookup_builder and resolve_params) and
check_state (a reference state's sizes and finiteness, as the reference checks them).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from crosscheck.checks.tolerances import EXACT_KKT, Tolerance

__all__ = [
    "Capabilities",
    "EngineAdapter",
    "EngineForward",
    "EngineModel",
    "EngineTrajectory",
    "EngineUnsupported",
    "ModelTable",
    "TableAdapter",
    "check_state",
    "is_user_model",
    "lookup_builder",
    "resolve_params",
    "table_variants",
]


class EngineUnsupported(Exception):
    """The engine cannot represent this model; the message is the reason shown in results."""


@dataclass(frozen=True)
class Capabilities:
    """What an engine can answer, declared once by its adapter.

    multipliers: forward() maps constraint forces onto the reference's multipliers (a model
        may still return None with ``multipliers_note``, e.g. a minimal-coordinate tree).
    exact: the answers solve the rigid KKT system (False: regularized, soft constraints).
    rigid_recovery: a soft engine's forward() also returns the rigid answer recovered from
        its own soft output (``EngineForward.rigid_accelerations`` / ``rigid_multipliers``).
    mass_matrix: built models give the mass matrix (and forcing) in reference speeds where
        the coordinates map linearly (else None with ``mass_matrix_note``).
    nonholonomic: velocity-level (non-integrable) constraint rows can be expressed.
    integrators: the engine's own integrators accepted by ``simulate``; () means the engine
        has no trajectories in this suite. The first is the one `crosscheck run` uses.
    adaptive_integrators: the subset of ``integrators`` that control their error (they take
        ``rtol``); the others take a fixed ``timestep``.
    reference_integrators: the subset of ``adaptive_integrators`` that are the reference's
        own stepper (reference.integrate.rk.LeanDOP853, driven by solve_ivp): their error per
        rtol is the reference's, which the trajectory check measures in the run, so it does
        not integrate the engine a second time to estimate it.
    variants: some models have several engine models (``EngineAdapter.variants``).
    soft_prediction: built models predict their raw soft answer from the reference's rigid
        answer and the engine's documented regularization alone (``EngineModel.predict_soft``),
        without reading the engine's constraint solution: the ``*_soft_vs_predicted`` records.
    soft_limit: built models with soft rows give the same model with a stiffer regularization
        (``EngineModel.stiffened``): the trajectories' rigid-limit record extrapolates to it.
    """

    multipliers: bool
    exact: bool
    rigid_recovery: bool = False
    mass_matrix: bool = False
    nonholonomic: bool = False
    integrators: tuple[str, ...] = ()
    variants: bool = False
    adaptive_integrators: tuple[str, ...] = ()
    soft_prediction: bool = False
    soft_limit: bool = False
    reference_integrators: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        extra = set(self.adaptive_integrators) - set(self.integrators)
        if extra:
            raise ValueError(f"adaptive_integrators {sorted(extra)} are not in integrators")
        extra = set(self.reference_integrators) - set(self.adaptive_integrators)
        if extra:
            raise ValueError(
                f"reference_integrators {sorted(extra)} are not in adaptive_integrators"
            )

    def as_dict(self) -> dict[str, Any]:
        return {
            "multipliers": self.multipliers,
            "exact": self.exact,
            "rigid_recovery": self.rigid_recovery,
            "mass_matrix": self.mass_matrix,
            "nonholonomic": self.nonholonomic,
            "integrators": list(self.integrators),
            "variants": self.variants,
            "adaptive_integrators": list(self.adaptive_integrators),
            "soft_prediction": self.soft_prediction,
            "soft_limit": self.soft_limit,
            "reference_integrators": list(self.reference_integrators),
        }


@dataclass
class EngineForward:
    """Engine answer at one state, in reference coordinates.

    accelerations: u' in the reference model's speed order.
    multipliers: lambda in the reference model's constraint order, or None when the engine
        model has no constraint forces that map to them (``multipliers_note`` says why).
    rigid_accelerations / rigid_multipliers: soft engines only (Capabilities.rigid_recovery):
        the rigid answer recovered from the engine's own soft output.
    predicted_acceleration_error / predicted_multiplier_error: soft engines, at a state where
        the answer is regularized: (raw - rigid) as the regularization predicts it; None where
        the engine model has no soft rows (its answer is then exact).
    iterations: solver iterations (0: no solve, 1: a direct solve), None if not reported.
    raw: engine-native quantities worth reporting (residuals, impedance, ...), floats or arrays.
    """

    accelerations: np.ndarray
    multipliers: np.ndarray | None
    raw: dict = field(default_factory=dict)
    multipliers_note: str | None = None
    rigid_accelerations: np.ndarray | None = None
    rigid_multipliers: np.ndarray | None = None
    iterations: int | None = None
    predicted_acceleration_error: np.ndarray | None = None
    predicted_multiplier_error: np.ndarray | None = None

    @property
    def soft(self) -> bool:
        """The answer is regularized here: compare its rigid recovery, predict the raw one."""
        return (
            self.rigid_accelerations is not None and self.predicted_acceleration_error is not None
        )


@dataclass
class EngineTrajectory:
    """A trajectory computed by the engine, mapped to reference (q, u) at the requested times.

    violation / velocity_violation: the engine-side constraint residuals per output time (zeros
    for a model without constraints); energy: the engine's K + V per output time; wall_s: time
    spent in the engine's stepping (mapping excluded where the engine allows); steps: number of
    engine steps or right-hand-side evaluations; setting: the integrator setting used;
    failure: None when the integration reached the last time, else why it stopped; warnings:
    engine warnings that fired (name -> count; a run with any is not a trajectory of the model).
    """

    t: np.ndarray
    q: np.ndarray
    u: np.ndarray
    violation: np.ndarray
    velocity_violation: np.ndarray
    energy: np.ndarray
    integrator: str
    setting: dict = field(default_factory=dict)
    wall_s: float | None = None
    steps: int | None = None
    raw: dict = field(default_factory=dict)
    failure: str | None = None
    warnings: dict = field(default_factory=dict)


class EngineModel(ABC):
    """An engine's model of one reference model with one parameter set."""

    engine: str
    model_name: str
    variant: str | None = None
    mass_matrix_note: str | None = None
    # the engine's own constraint rows are regularized (soft): trajectories follow slightly
    # different dynamics, so they are characterized, not held to the rigid bounds
    soft_constraints: bool = False
    # the engine's native solver for this model (reported with timings), and whether it solves
    # constraint rows (False: a minimal-coordinate tree or an unconstrained model)
    solver: str | None = None
    constrained_solve: bool = False

    @abstractmethod
    def to_engine_state(self, q: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Reference (q, u) -> engine state (qpos/q, qvel/v)."""

    @abstractmethod
    def from_engine_state(self, qe: np.ndarray, ve: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Engine state -> reference (q, u) (the inverse map, tested both ways)."""

    @abstractmethod
    def forward(self, q: np.ndarray, u: np.ndarray, t: float = 0.0) -> EngineForward:
        """Accelerations and constraint forces at a consistent reference state."""

    @abstractmethod
    def energy(self, q: np.ndarray, u: np.ndarray) -> tuple[float, float]:
        """(kinetic, potential) in the engine, same datum as the reference."""

    def mass_matrix(self, q: np.ndarray) -> np.ndarray | None:
        """Engine mass matrix in reference speeds, or None (``mass_matrix_note`` says why)."""
        return None

    def forcing(self, q: np.ndarray, u: np.ndarray, t: float = 0.0) -> np.ndarray | None:
        """The reference's f (applied forces minus velocity products) from the engine, or None."""
        return None

    def simulate(
        self,
        q0: np.ndarray,
        u0: np.ndarray,
        t_eval: Sequence[float],
        *,
        integrator: str,
        rtol: float | None = None,
        timestep: float | None = None,
    ) -> EngineTrajectory:
        """Integrate from a consistent reference state with one of the adapter's integrators:
        adaptive ones take ``rtol``, fixed-step ones ``timestep``."""
        raise EngineUnsupported(f"{self.engine} has no trajectories in this suite")

    def predict_soft(
        self, q: np.ndarray, u: np.ndarray, reference_accelerations: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """The raw soft (accelerations, multipliers) this model should return at a consistent
        reference state, predicted from the reference's accelerations and the engine's
        documented regularization, never from its constraint solution
        (Capabilities.soft_prediction); raises EngineUnsupported where it cannot."""
        raise EngineUnsupported(f"{self.engine} does not predict its soft answer")

    def stiffened(self, factor: float) -> EngineModel:
        """The same model (same parameters) with its soft rows' time constant divided by
        ``factor`` (Capabilities.soft_limit)."""
        raise EngineUnsupported(f"{self.engine} has no stiffer soft model")

    def timed_forward(self, q: np.ndarray, u: np.ndarray) -> Callable[[], Any]:
        """A callable making only the engine's native forward call at a state already mapped
        (what `crosscheck bench` times); the default times the whole forward()."""
        return lambda: self.forward(q, u)

    # the parameter values the adapter's maps (state, acceleration and multiplier maps, raw
    # figures) read: the nominal (unperturbed) set, given by crosscheck.checks.instantaneous.build,
    # so that a perturbation (crosscheck.checks.perturb) changes only the engine's physics; None:
    # the build's own values
    nominal: dict[str, float] | None = None

    @property
    def map_params(self) -> dict[str, float]:
        """The values the maps use: ``nominal`` when given, else the build's own."""
        return self.nominal if self.nominal is not None else self.params  # type: ignore

    def fingerprint(self) -> str:
        """A digest of the built engine model's physics (masses, inertias, geometry, gravity,
        loads): two builds differ in it exactly when their dynamics can differ, so a parameter
        perturbation that leaves it unchanged is refused as doing nothing."""
        raise NotImplementedError(f"{type(self).__name__} has no fingerprint")


class EngineAdapter(ABC):
    """One engine: its name, the package it comes from, what it can do, and its models."""

    name: str
    distribution: str  # the installed package whose version results record (e.g. "pin")
    capabilities: Capabilities
    label: str = ""  # the engine's name in prose (tables, plot legends); default: name
    # position in every default order (engine lists, tables, plot colours, the timing anchor):
    # lower first, ties alphabetical; engines that do not set it come after the built-ins
    rank: int = 100

    @property
    def display_name(self) -> str:
        return self.label or self.name

    @abstractmethod
    def models(self) -> tuple[str, ...]:
        """The reference models this engine expresses (built-in names)."""

    def unsupported(self) -> dict[str, str]:
        """Reference models the engine cannot express, each with the reason (shown as a skip)."""
        return {}

    def variants(self, model_name: str) -> tuple[str | None, ...]:
        """The engine models of one reference model; the first is build's default."""
        return (None,)

    @abstractmethod
    def build(
        self, model_name: str, params: dict[str, float] | None = None, variant: str | None = None
    ) -> EngineModel:
        """Engine model for a reference model; raises EngineUnsupported with the reason."""

    def exact_tolerance(self, model_name: str) -> Tolerance:
        """The tolerance of this engine's exact (rigid or recovered rigid) answer on a model,
        with the reason it is that size; the default is the round-off bound of a KKT solve."""
        return EXACT_KKT

    def annotate_records(self, model_name: str, records: list[dict]) -> list[dict]:
        """An engine's own notes on its instantaneous records of a model (e.g. which engine
        model answered a user's file, and what the engine's own file parser lost); the default
        adds nothing."""
        return records


# An adapter's models: reference model -> the engine model's builder, or {variant: builder}
# for several engine models of one reference model (the first variant is build's default).
ModelTable = dict[str, Any]


def resolve_params(model_name: str, params: dict | None) -> dict[str, float]:
    """The reference model's parameter values (defaults filled in, names and signs checked)."""
    from reference.models import get
    from reference.numeric.model import resolve_parameters

    return resolve_parameters(get(model_name), params)


def is_user_model(table: ModelTable, model_name: str) -> bool:
    """A model loaded from a user's file (reference.models.user_names), not in the table."""
    from reference.models import user_names

    return model_name not in table and model_name in user_names()


def table_variants(table: ModelTable, model_name: str) -> tuple[str | None, ...]:
    """The variants of a model in an adapter's table; (None,) for a single engine model."""
    entry = table.get(model_name)
    return tuple(entry) if isinstance(entry, dict) else (None,)


def single_variant(engine: str, model_name: str, variant: str | None, what: str = "") -> None:
    """Refuse a variant for a model with one engine model (``what`` names it, e.g. a user's
    file; default the engine)."""
    if variant is not None:
        raise EngineUnsupported(f"{model_name}: {what or engine} has a single variant here")


def lookup_builder(
    engine: str,
    table: ModelTable,
    model_name: str,
    variant: str | None,
    unsupported: dict[str, str] | None = None,
) -> Any:
    """The builder of one variant of a model in an adapter's table (the default variant when
    ``variant`` is None); EngineUnsupported with the reason, or with the valid names."""
    if unsupported and model_name in unsupported:
        raise EngineUnsupported(unsupported[model_name])
    if model_name not in table:
        raise EngineUnsupported(
            f"{engine} adapter has no model {model_name!r} (mapped: {', '.join(table)})"
        )
    entry = table[model_name]
    if not isinstance(entry, dict):
        single_variant(engine, model_name, variant)
        return entry
    key = variant or next(iter(entry))
    if key not in entry:
        raise EngineUnsupported(
            f"{model_name}: unknown {engine} variant {key!r}; valid: {', '.join(entry)}"
        )
    return entry[key]


def check_state(
    where: str, nq: int, n: int, q: Any, u: Any = None, t: float = 0.0
) -> tuple[np.ndarray, np.ndarray | None]:
    """A reference state's sizes and finiteness, checked as the reference checks them;
    ``where`` names the model and engine in the error. Returns (q, u) as flat float arrays."""
    from reference.errors import ModelInputError

    q = np.asarray(q, dtype=float).reshape(-1)
    if q.size != nq:
        raise ModelInputError(f"{where}: expected {nq} coordinates, got {q.size}")
    if u is not None:
        u = np.asarray(u, dtype=float).reshape(-1)
        if u.size != n:
            raise ModelInputError(f"{where}: expected {n} speeds, got {u.size}")
    if not (np.all(np.isfinite(q)) and (u is None or np.all(np.isfinite(u))) and math.isfinite(t)):
        raise ModelInputError(f"{where}: state contains NaN or infinite values")
    return q, u


class TableAdapter(EngineAdapter):
    """An adapter whose engine models are one ModelTable: ``model_table`` (reference model ->
    builder(model_name, params), or {variant: builder}), ``refused`` (reference model -> why
    the engine cannot express it) and ``user_files`` (it also builds the models loaded from
    users' files; its build() then handles them before the table)."""

    model_table: ClassVar[ModelTable] = {}
    refused: ClassVar[dict[str, str]] = {}
    user_files: ClassVar[bool] = False

    def models(self) -> tuple[str, ...]:
        from reference.models import user_names

        return (*self.model_table, *(user_names() if self.user_files else ()))

    def unsupported(self) -> dict[str, str]:
        return dict(self.refused)

    def variants(self, model_name: str) -> tuple[str | None, ...]:
        return table_variants(self.model_table, model_name)

    def build(
        self, model_name: str, params: dict[str, float] | None = None, variant: str | None = None
    ) -> EngineModel:
        builder = lookup_builder(self.name, self.model_table, model_name, variant, self.refused)
        model: EngineModel = builder(model_name, resolve_params(model_name, params))
        return model
