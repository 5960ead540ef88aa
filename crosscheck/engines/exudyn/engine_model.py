"""Shared machinery of the Exudyn models: the system container, one state's answer, energy and
trajectories through Exudyn's own implicit solvers.

One state's answer. Exudyn has no "forward dynamics at a state" call; its implicit solver
computes consistent initial accelerations when it is initialized
(timeIntegration.generalizedAlpha.computeInitialAccelerations, the default): it writes the
state as the initial configuration, then ``MainSolverImplicitSecondOrder.InitializeSolver``
solves the KKT system

    [ M    C_q^T ] [ q'' ]   [ f                      ]
    [ C_q  0     ] [ lam ] = [ -(C_q q')_q q'         ]

and ``GetODE2Coordinates_tt`` / ``GetAECoordinates`` return q'' and lam (the multipliers are
kept because generalizedAlpha.storeInitialAlgebraicCoordinates is on). Exudyn's sign: the
constraint force on the ODE2 coordinates is -C_q^T lam (the per-model docstrings give what
that means for each connector; verified against the reference in tests/test_engine_exudyn.py).

The finite-difference floor and its removal. The quadratic-velocity term (C_q q')_q q' is a
forward difference of the connectors' analytic Jacobians, step h_j = relativeEpsilon *
max(minimumCoordinateSize, |q_j|) per coordinate: its error is c1 h + c2 h^2 + ... plus round-off
~eps_machine / h. The KKT solve is linear in that right-hand side, so the engine's answers at
steps h, h/2, h/4 (three calls) combine by Richardson extrapolation,
(8 a(h/4) - 6 a(h/2) + a(h)) / 3, into the answer with an O(h^3) difference term.
RICHARDSON_EPSILON is the h of the first call. ``forward`` returns the extrapolated answer;
raw["plain_accelerations"] / raw["plain_multipliers"] keep Exudyn's answer at its default
relativeEpsilon 1e-7 (the figures of both are in docs/engines/exudyn.md).

Coordinates. Engine states q_e are total coordinates (Exudyn stores them relative to the
nodes' reference coordinates, which are zero except the Euler parameters' (1, 0, 0, 0)); the
engine world is the reference model's own frame (gravity as the reference writes it, e.g. +g Y
for the Y-down pendulum), so no axis is flipped in any map.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence

import exudyn as exu
import numpy as np

from crosscheck.engines.base import EngineForward, EngineModel, EngineTrajectory, EngineUnsupported
from crosscheck.engines.building import check_state

__all__ = ["DEFAULT_EPSILON", "INTEGRATORS", "RICHARDSON_EPSILON", "ExudynModel"]

# relativeEpsilon of the first of the three extrapolated calls, with minimumCoordinateSize 1
# (Exudyn's default 0.01 shrinks the step of coordinates near 0 to 1e-2 h, whose round-off
# eps_machine / h_j the extrapolation's weights (8, -6, 1)/3 amplify). Scanned over h = 1e-3,
# 3e-4, 1e-4 on the pendulums and slider-cranks (15 sampled states each, scaled error of q''
# and lam against the reference): worst 5.4e-11, 1.8e-11, 9.1e-11; with minimumCoordinateSize
# 0.01 the same scan gave up to 1.4e-9. The plain answer at the defaults: 1.3e-8..1.5e-7.
RICHARDSON_EPSILON = 3e-4
MINIMUM_COORDINATE_SIZE = 1.0
DEFAULT_EPSILON = 1e-7
VELOCITY_STEP = 1e-6  # Exudyn's default relativeEpsilon (the "plain" answer in raw)

# Exudyn's implicit solvers accepted by simulate() (fixed step: pass ``timestep``):
# generalized-alpha on the index-3 constraints (spectral radius 0.9, Exudyn's default) and the
# trapezoidal rule on index-2 (velocity-level) constraints.
from crosscheck.engines.exudyn.trajectory import INTEGRATORS  # noqa: E402 - its own module, imported by both


def _settings() -> exu.SimulationSettings:
    ss = exu.SimulationSettings()
    ss.solution.file.write = False
    ss.solution.sensors.active = True
    ss.timeIntegration.verboseMode = 0
    ss.show.statistics = False
    ss.show.computationTime = False
    # the velocity term of the initial accelerations exists only in dense mode (Exudyn warns)
    ss.linearSolver.solverType = exu.LinearSolverType.EXUdense
    ss.timeIntegration.newton.numericalDifferentiation.minimumCoordinateSize = (
        MINIMUM_COORDINATE_SIZE
    )
    return ss


class ExudynModel(EngineModel):
    """An Exudyn system of one reference model; subclasses build it and write the maps."""

    engine = "exudyn"
    nq_ref: int
    n_ref: int
    gravity = (0.0, 0.0, 0.0)  # subclasses set the reference's gravity vector in _build
    rheonomic = False
    mass_matrix_note = (
        "Exudyn's coordinates are every body's absolute position and angle or "
        "Euler parameters, not the reference's; its mass matrix is not mapped "
        "onto the reference's speeds (Capabilities.mass_matrix is False)"
    )
    energy_dofs: tuple[int, ...] | None = None  # engine speeds in K (None: all)
    # reference coordinates that from_engine_state reads with atan2 (made continuous along a
    # trajectory, trajectory._continuous_angles)
    angle_indices: tuple[int, ...] = ()

    def __init__(self, model_name: str, params: dict[str, float], simulation: bool = False):
        self.model_name = model_name
        self.params = dict(params)
        # simulation: the system simulate() steps (a fresh one, so forward's is undisturbed);
        # a model may build it differently (the knife edge's row, see special.py)
        self.simulation = simulation
        self.time = 0.0  # the time of the state being mapped (rheonomic models use it)
        self.sc = exu.SystemContainer()
        self.mbs = self.sc.AddSystem()
        self.masses: list[tuple[int, int, float]] = []  # (node, object, mass) for V
        self._build()
        self.mbs.Assemble()
        self.settings = _settings()
        self.solver = exu.MainSolverImplicitSecondOrder()
        self.n_engine = self.mbs.systemData.ODE2Size()
        # engine states hold total coordinates; Exudyn stores them relative to the nodes'
        # reference coordinates (zero except Euler parameters: (1, 0, 0, 0))
        self.q_reference = np.array(
            self.mbs.systemData.GetODE2Coordinates(configuration=exu.ConfigurationType.Reference)
        )

    # ---- hooks ---------------------------------------------------------------------------
    def _build(self) -> None:
        raise NotImplementedError

    def _acc_to_reference(self, qe, ve, ae) -> np.ndarray:
        raise NotImplementedError

    def _multipliers(self, qe, ve, ae, lam_e) -> np.ndarray | None:
        return np.zeros(0)

    def _extra_raw(self, qe, ve, ae, lam_e, raw) -> None:
        pass

    def _spring_potential(self, qe) -> float:
        return 0.0

    def _position_rows(self, qe, t: float) -> np.ndarray:
        """The engine's position-level constraint residuals C(q_e, t), written from the
        joints' definitions (empty without position-level constraints)."""
        return np.zeros(0)

    def constraint_violation(self, qe, t: float = 0.0) -> float:
        """Largest |C(q_e, t)| (0 without position-level constraints)."""
        rows = self._position_rows(np.asarray(qe, float), t)
        return float(np.max(np.abs(rows))) if rows.size else 0.0

    def velocity_violation(self, qe, ve, t: float = 0.0) -> float:
        """Largest |dC/dt| along (v_e, 1): a central difference of _position_rows, step
        VELOCITY_STEP (truncation ~1e-12 of the rows' second derivatives)."""
        qe, ve = np.asarray(qe, float), np.asarray(ve, float)
        h = VELOCITY_STEP
        d = self._position_rows(qe + h * ve, t + h) - self._position_rows(qe - h * ve, t - h)
        return float(np.max(np.abs(d))) / (2 * h) if d.size else 0.0

    # ---- engine calls --------------------------------------------------------------------
    def _set_state(self, qe, ve, t: float) -> None:
        sd = self.mbs.systemData
        init = exu.ConfigurationType.Initial
        sd.SetODE2Coordinates(
            (np.asarray(qe, float) - self.q_reference).tolist(), configuration=init
        )
        sd.SetODE2Coordinates_t(np.asarray(ve, float).tolist(), configuration=init)
        ti = self.settings.timeIntegration
        ti.startTime = float(t)
        ti.endTime = float(t) + 1.0

    def _engine_answer(self, qe, ve, t: float, epsilon: float):
        """Exudyn's initial accelerations and multipliers at (qe, ve, t) with one
        relativeEpsilon: the engine's native call (see the module docstring)."""
        self.settings.timeIntegration.newton.numericalDifferentiation.relativeEpsilon = epsilon
        self._set_state(qe, ve, t)
        # Exudyn's type stub omits InitializeSolver's arguments (the call is as documented)
        self.solver.InitializeSolver(self.mbs, self.settings)  # type: ignore[call-arg,misc]
        sd = self.mbs.systemData
        return np.array(sd.GetODE2Coordinates_tt()), np.array(sd.GetAECoordinates())

    def _plain_answer(self, qe, ve, t: float):
        """Exudyn's answer with its default differentiation settings (relativeEpsilon 1e-7,
        minimumCoordinateSize 0.01): what a user of Exudyn gets."""
        nd = self.settings.timeIntegration.newton.numericalDifferentiation
        nd.minimumCoordinateSize = 0.01
        try:
            return self._engine_answer(qe, ve, t, DEFAULT_EPSILON)
        finally:
            nd.minimumCoordinateSize = MINIMUM_COORDINATE_SIZE

    def _solve(self, qe, ve, t: float = 0.0):
        """Richardson extrapolation of three engine answers (steps h, h/2, h/4)."""
        h = RICHARDSON_EPSILON
        (a1, l1), (a2, l2), (a4, l4) = (self._engine_answer(qe, ve, t, h / k) for k in (1, 2, 4))
        return (8 * a4 - 6 * a2 + a1) / 3, (8 * l4 - 6 * l2 + l1) / 3

    def timed_forward(self, q, u, t: float = 0.0):
        """Timing hook for `crosscheck bench`: the state mapped once; the callable makes the
        three native InitializeSolver calls of forward() (no mapping, no residuals)."""
        q, u = self._check(q, u, t)
        self.time = float(t)
        qe, ve = self.to_engine_state(q, u)
        return lambda: self._solve(qe, ve, t)

    # ---- EngineModel ---------------------------------------------------------------------
    def _check(self, q, u=None, t: float = 0.0):
        """Sizes and finiteness of a reference state, as the reference checks them."""
        return check_state(f"{self.model_name} ({self.engine})", self.nq_ref, self.n_ref, q, u, t)

    def forward(self, q, u, t: float = 0.0) -> EngineForward:
        q, u = self._check(q, u, t)
        self.time = float(t)
        qe, ve = self.to_engine_state(q, u)
        ae, lam_e = self._solve(qe, ve, t)
        a_plain, l_plain = self._plain_answer(qe, ve, t)
        raw = {
            "engine_q": qe,
            "engine_v": ve,
            "engine_accelerations": ae,
            "engine_multipliers": lam_e,
            "richardson_epsilon": RICHARDSON_EPSILON,
            "plain_accelerations": self._acc_to_reference(qe, ve, a_plain),
            "plain_multipliers": self._multipliers(qe, ve, a_plain, l_plain),
            "constraint_violation": self.constraint_violation(qe, t),
        }
        self._extra_raw(qe, ve, ae, lam_e, raw)
        lam = self._multipliers(qe, ve, ae, lam_e)
        return EngineForward(self._acc_to_reference(qe, ve, ae), lam, raw, iterations=1)

    def _positions(self, qe):
        """World positions of the mass-carrying nodes (for the potential)."""
        self._set_state(qe, np.zeros(self.n_engine), 0.0)
        init = exu.ConfigurationType.Initial
        return [
            np.asarray(
                self.mbs.GetNodeOutput(n, exu.OutputVariableType.Position, configuration=init)
            )
            for n, _, _ in self.masses
        ]

    def _energy_engine(self, qe, ve) -> tuple[float, float]:
        """K = v^T M v / 2 with Exudyn's mass matrix; V = -sum m g . p over the bodies' mass
        centres (nodes at the mass centres), datum the world origin = the reference's, plus
        the reference's springs."""
        self._set_state(qe, ve, 0.0)
        self.solver.InitializeSolver(self.mbs, self.settings)  # type: ignore[call-arg,misc]
        self.solver.ComputeMassMatrix(self.mbs)
        M = np.asarray(self.solver.GetSystemMassMatrix())  # type: ignore[misc]
        v = np.asarray(ve, float).copy()
        if self.energy_dofs is not None:
            keep = np.zeros(v.size, bool)
            keep[list(self.energy_dofs)] = True
            v[~keep] = 0.0
        K = 0.5 * float(v @ M @ v)
        gvec = np.asarray(self.gravity, float)
        V = self._spring_potential(qe)
        for (_, _, mass), p in zip(self.masses, self._positions(qe), strict=True):
            V -= mass * float(gvec[: len(p)] @ p[:3])
        return K, V

    def energy(self, q, u) -> tuple[float, float]:
        q, u = self._check(q, u)
        qe, ve = self.to_engine_state(q, u)
        return self._energy_engine(qe, ve)

    def simulate(
        self,
        q0,
        u0,
        t_eval: Sequence[float],
        *,
        integrator: str = "generalized-alpha",
        rtol: float | None = None,
        timestep: float | None = None,
    ) -> EngineTrajectory:
        from crosscheck.engines.exudyn.trajectory import simulate

        if integrator not in INTEGRATORS:
            raise EngineUnsupported(
                f"exudyn: unknown integrator {integrator!r}; valid: {', '.join(INTEGRATORS)}"
            )
        if timestep is None or not timestep > 0:
            raise EngineUnsupported(
                f"exudyn's {integrator} is a fixed-step method: pass "
                "timestep > 0 (rtol is not used)"
            )
        q0, u0 = self._check(q0, u0)
        return simulate(self, q0, u0, np.asarray(t_eval, float), integrator, float(timestep))

    def fingerprint(self) -> str:
        """Digest of the built system as Exudyn reports it back (mbs.GetNode / GetObject /
        GetMarker / GetLoad: masses, inertias, positions, stiffnesses, load vectors) and of
        the Python user functions it holds, by name and the numbers they close over (the
        knife edge's a, the support's a and Omega). The parameter dict is not in it: a
        parameter the built system does not contain leaves the digest unchanged."""
        sd = self.mbs.systemData
        items = {
            kind: [_plain(get(i)) for i in range(count())]
            for kind, get, count in (
                ("nodes", self.mbs.GetNode, sd.NumberOfNodes),
                ("objects", self.mbs.GetObject, sd.NumberOfObjects),
                ("markers", self.mbs.GetMarker, sd.NumberOfMarkers),
                ("loads", self.mbs.GetLoad, sd.NumberOfLoads),
            )
        }
        blob = {"model": type(self).__name__, "gravity": list(self.gravity), **items}
        return hashlib.sha256(json.dumps(blob, sort_keys=True).encode()).hexdigest()[:16]


def _plain(v):
    """An Exudyn item dictionary as JSON-able data: arrays (and Exudyn's lists of 3-vectors and
    3x3 matrices) as lists, visualization left out, a user function as its name and the
    numbers it closes over (its parameters)."""
    if callable(v):
        cells = [c.cell_contents for c in getattr(v, "__closure__", None) or ()]
        return {
            "function": getattr(v, "__qualname__", type(v).__name__),
            "closes_over": [_plain(c) for c in cells if isinstance(c, (int, float, np.ndarray))],
        }
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (exu.Matrix3DList, exu.Vector3DList)):  # str() rounds to 8 digits
        return [np.asarray(v[i]).tolist() for i in range(len(v))]
    if isinstance(v, dict):
        return {
            k: _plain(x) for k, x in v.items() if k != "visualization" and not k.startswith("V")
        }
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v if isinstance(v, (int, float, str, bool, type(None))) else str(v)
