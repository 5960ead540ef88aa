"""The engine contract: what an adapter and a built engine model provide, and what they declare.

An adapter (one per engine, registered under the entry-point group ``crosscheck.engines``)
builds the engine's model of a reference model with one parameter set. A built model maps a
consistent reference state to the engine's state and returns the engine's answers mapped back to
the reference's speeds and multipliers (same order, same sign and scale as the textbook rows).

Callers never probe for methods: they read the adapter's ``capabilities`` (what the engine can
do at all) and, per built model, the optional answers (``mass_matrix`` returns None with
``mass_matrix_note`` saying why). Everything a capability promises is checked for every
registered engine on every model it claims by tests/test_engine_contract.py.

What a built model answers (EngineForward at a state, EngineTrajectory over time) is in
crosscheck.engines.answers, re-exported here; what every adapter would otherwise write again is
in crosscheck.engines.building.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from crosscheck.checks.tolerances import EXACT_KKT, Tolerance
from crosscheck.engines.answers import EngineForward, EngineTrajectory

__all__ = [
    "Capabilities",
    "EngineAdapter",
    "EngineForward",
    "EngineModel",
    "EngineTrajectory",
    "EngineUnsupported",
]


class EngineUnsupported(Exception):
    """The engine cannot represent this model; the message is the reason shown in results."""


DERIVATIVE_KINDS = ("numerical", "analytic", "engine_differences")


@dataclass(frozen=True)
class Capabilities:
    """What an engine can answer, declared once by its adapter.

    Parameters
    ----------
    multipliers : bool
        forward() maps constraint forces onto the reference's multipliers (a model may still
        return None with ``multipliers_note``, e.g. a minimal-coordinate tree).
    exact : bool
        The answers solve the rigid KKT system (False: regularized, soft constraints).
    rigid_recovery : bool
        A soft engine's forward() also returns the rigid answer recovered from its own soft
        output (``EngineForward.rigid_accelerations`` / ``rigid_multipliers``).
    mass_matrix : bool
        Built models give the mass matrix (and forcing) in reference speeds where the
        coordinates map linearly (else None with ``mass_matrix_note``).
    nonholonomic : bool
        Velocity-level (non-integrable) constraint rows can be expressed.
    integrators : tuple of str
        The engine's own integrators accepted by ``simulate``; () means no trajectories in
        this suite. The first is the one `crosscheck run` uses.
    variants : bool
        Some models have several engine models (``EngineAdapter.variants``).
    adaptive_integrators : tuple of str
        The subset of ``integrators`` that control their error (they take ``rtol``); the others
        take a fixed ``timestep``.
    soft_prediction : bool
        Built models predict their raw soft answer from the reference's rigid answer and the
        engine's documented regularization alone (``EngineModel.predict_soft``), without
        reading the engine's constraint solution: the ``*_soft_vs_predicted`` records.
    soft_limit : bool
        Built models with soft rows give the same model with a stiffer regularization
        (``EngineModel.stiffened``): the trajectories' rigid-limit record extrapolates to it.
    reference_integrators : tuple of str
        The subset of ``adaptive_integrators`` that are the reference's own stepper
        (reference.integrate.rk.LeanDOP853): their error per rtol is the reference's, which the
        trajectory check measures in the run, so the engine is not integrated a second time to
        estimate it.
    derivatives : {"numerical", "analytic", "engine_differences"}
        Where the ``derivatives`` records' engine side comes from: central differences of
        forward() (every engine), plus the engine's own derivative routines where a built
        model has them (``EngineModel.derivatives``): "analytic" ones, or the engine's own
        finite differences of its soft answer (MuJoCo's mjd_transitionFD).

    Raises
    ------
    ValueError
        An adaptive integrator not among ``integrators``, or a reference integrator not among
        ``adaptive_integrators``.
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
    derivatives: str = "numerical"

    def __post_init__(self) -> None:
        extra = set(self.adaptive_integrators) - set(self.integrators)
        if extra:
            raise ValueError(f"adaptive_integrators {sorted(extra)} are not in integrators")
        extra = set(self.reference_integrators) - set(self.adaptive_integrators)
        if extra:
            raise ValueError(
                f"reference_integrators {sorted(extra)} are not in adaptive_integrators"
            )
        if self.derivatives not in DERIVATIVE_KINDS:
            raise ValueError(
                f"derivatives {self.derivatives!r}: one of {', '.join(DERIVATIVE_KINDS)}"
            )

    def as_dict(self) -> dict[str, Any]:
        """The capabilities as JSON data (``crosscheck engines --json``, results' meta)."""
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
            "derivatives": self.derivatives,
        }


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
        """Map a reference state to the engine's.

        Parameters
        ----------
        q, u : ndarray
            A consistent reference state.

        Returns
        -------
        tuple of ndarray
            The engine's positions and velocities (qpos/q, qvel/v).
        """

    @abstractmethod
    def from_engine_state(self, qe: np.ndarray, ve: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Map an engine state back to the reference's (the inverse of `to_engine_state`,
        tested both ways).

        Parameters
        ----------
        qe, ve : ndarray
            The engine's positions and velocities.

        Returns
        -------
        tuple of ndarray
            The reference's (q, u).
        """

    @abstractmethod
    def forward(self, q: np.ndarray, u: np.ndarray, t: float = 0.0) -> EngineForward:
        """The engine's accelerations and constraint forces at a state.

        Parameters
        ----------
        q, u : ndarray
            A consistent reference state.
        t : float
            Time (rheonomic constraints).

        Returns
        -------
        EngineForward
            In the reference's speeds and constraint rows.

        Raises
        ------
        EngineUnsupported
            The engine model cannot answer at this state, with the reason.
        """

    @abstractmethod
    def energy(self, q: np.ndarray, u: np.ndarray) -> tuple[float, float]:
        """The engine's kinetic and potential energy at a state, on the reference's datum.

        Parameters
        ----------
        q, u : ndarray
            A reference state.

        Returns
        -------
        tuple of float
            (kinetic, potential).
        """

    def mass_matrix(self, q: np.ndarray) -> np.ndarray | None:
        """The engine's mass matrix in the reference's speeds.

        Parameters
        ----------
        q : ndarray
            Reference coordinates.

        Returns
        -------
        ndarray or None
            None where the speeds do not map linearly (``mass_matrix_note`` says why).
        """
        return None

    def mass_matrix_in_engine_speeds(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """(M_e, H): the engine's mass matrix in its own speeds v and u = H v at q, where the
        speeds do not map one to one (quaternions); compared with H^T M H. None: not given."""
        return None

    def forcing(self, q: np.ndarray, u: np.ndarray, t: float = 0.0) -> np.ndarray | None:
        """The reference's f (applied forces minus velocity products) from the engine.

        Parameters
        ----------
        q, u : ndarray
            A reference state.
        t : float
            Time.

        Returns
        -------
        ndarray or None
            None where the engine does not give it.
        """
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
        """Integrate from a consistent reference state with one of the engine's integrators.

        Parameters
        ----------
        q0, u0 : ndarray
            A consistent reference state.
        t_eval : sequence of float
            Output times, the first the initial time.
        integrator : str
            One of ``Capabilities.integrators``.
        rtol : float, optional
            For adaptive integrators.
        timestep : float, optional
            For fixed-step integrators.

        Returns
        -------
        EngineTrajectory

        Raises
        ------
        EngineUnsupported
            The engine has no trajectories in this suite, or not with this integrator.
        """
        raise EngineUnsupported(f"{self.engine} has no trajectories in this suite")

    def predict_soft(
        self, q: np.ndarray, u: np.ndarray, reference_accelerations: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """The raw soft answer this model should give, predicted from the reference's
        accelerations and the engine's documented regularization, never from its constraint
        solution (Capabilities.soft_prediction).

        Parameters
        ----------
        q, u : ndarray
            A consistent reference state.
        reference_accelerations : ndarray
            The reference's u' there.

        Returns
        -------
        tuple
            (accelerations, multipliers or None) as the engine should return them.

        Raises
        ------
        EngineUnsupported
            Where the engine cannot predict it.
        """
        raise EngineUnsupported(f"{self.engine} does not predict its soft answer")

    def stiffened(self, factor: float) -> EngineModel:
        """The same model with its soft rows' time constant divided by `factor`
        (Capabilities.soft_limit).

        Parameters
        ----------
        factor : float
            > 1: stiffer.

        Returns
        -------
        EngineModel

        Raises
        ------
        EngineUnsupported
            The engine has no stiffer soft model.
        """
        raise EngineUnsupported(f"{self.engine} has no stiffer soft model")

    def timed_forward(self, q: np.ndarray, u: np.ndarray) -> Callable[[], Any]:
        """What `crosscheck bench` times: the engine's native forward call alone.

        Parameters
        ----------
        q, u : ndarray
            A consistent reference state, mapped once before the callable is returned.

        Returns
        -------
        callable
            No arguments; the default times the whole forward().
        """
        return lambda: self.forward(q, u)

    def derivatives(self, q: np.ndarray, u: np.ndarray, t: float, directions: Any) -> Any:
        """The engine's own derivatives of its answer along consistent directions
        (Capabilities.derivatives "analytic" or "engine_differences").

        Parameters
        ----------
        q, u : ndarray
            A consistent reference state.
        t : float
            Time.
        directions : reference.derivatives.directions.Directions
            The q- and u-directions at the state (the generalized forces are the unit vectors
            on the reference's speeds).

        Returns
        -------
        crosscheck.engines.linearization.EngineDerivatives

        Raises
        ------
        EngineUnsupported
            This model has no derivative routine of the engine's own (the check then
            differences forward()).
        """
        raise EngineUnsupported(f"{self.engine} gives no derivatives of its own")

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
        loads).

        Two builds differ in it exactly when their dynamics can differ, so a parameter
        perturbation that leaves it unchanged is refused as doing nothing.

        Returns
        -------
        str
        """
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
        """The engine's name in prose: ``label``, else ``name``."""
        return self.label or self.name

    @abstractmethod
    def models(self) -> tuple[str, ...]:
        """The reference models this engine expresses.

        Returns
        -------
        tuple of str
            Registry names.
        """

    def unsupported(self) -> dict[str, str]:
        """The reference models the engine cannot express.

        Returns
        -------
        dict of str to str
            Model name -> the reason, shown in its skip records.
        """
        return {}

    def variants(self, model_name: str) -> tuple[str | None, ...]:
        """The engine models of one reference model.

        Parameters
        ----------
        model_name : str

        Returns
        -------
        tuple of (str or None)
            Variant names; the first is `build`'s default.
        """
        return (None,)

    @abstractmethod
    def build(
        self, model_name: str, params: dict[str, float] | None = None, variant: str | None = None
    ) -> EngineModel:
        """The engine's model of a reference model.

        Parameters
        ----------
        model_name : str
        params : dict of str to float, optional
            Parameter values (defaults filled in); None: the model's defaults.
        variant : str, optional
            One of `variants`; None: the first.

        Returns
        -------
        EngineModel

        Raises
        ------
        EngineUnsupported
            The engine cannot express the model, with the reason.
        reference.errors.ModelInputError
            An unknown model, parameter or variant.
        """

    def exact_tolerance(self, model_name: str) -> Tolerance:
        """The tolerance of this engine's exact (rigid or recovered rigid) answer on a model.

        Parameters
        ----------
        model_name : str

        Returns
        -------
        Tolerance
            With the reason for its size; the default is the round-off bound of a KKT solve.
        """
        return EXACT_KKT

    def annotate_records(self, model_name: str, records: list[dict]) -> list[dict]:
        """The engine's own notes on its instantaneous records of a model (which engine model
        answered a user's file, what the engine's own file parser lost).

        Parameters
        ----------
        model_name : str
        records : list of dict

        Returns
        -------
        list of dict
            The records, annotated; the default returns them unchanged.
        """
        return records
