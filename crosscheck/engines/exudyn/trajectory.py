"""Trajectories through Exudyn's own implicit solvers (mbs.SolveDynamic), fixed step.

A fresh system of the same model (``simulation=True``: the knife edge gets its honest
velocity-level row) starts from the mapped state; SensorNode sensors (stored internally)
record every node's coordinates and velocities at every step, and the output times are picked
from that record (they must lie on the step grid: t0 + k * timestep). Newton's tolerances are
tightened from Exudyn's defaults (relative 1e-8) to NEWTON_RTOL so the integrator's own error,
not the iteration's, is what a work-precision plot shows; the step is never changed
(adaptiveStep off: a failed Newton iteration is an error, not a silently smaller step).
"""

from __future__ import annotations

import time
from contextlib import contextmanager

import exudyn as exu
import numpy as np
from exudyn.itemInterface import SensorNode

from crosscheck.engines.base import EngineTrajectory, EngineUnsupported

# Exudyn's own integrators for simulate() (the first is the one `crosscheck run` uses)
INTEGRATORS = {
    "generalized-alpha": exu.DynamicSolverType.GeneralizedAlpha,
    "trapezoidal-index2": exu.DynamicSolverType.TrapezoidalIndex2,
}

__all__ = ["ExudynIntegrationError", "simulate"]

NEWTON_RTOL = 1e-10  # relative; absolute NEWTON_ATOL (Exudyn's defaults 1e-8 / 1e-10)
NEWTON_ATOL = 1e-12
GRID_TOL = 1e-9  # an output time within GRID_TOL * timestep of a step counts as on the grid


class ExudynIntegrationError(RuntimeError):
    """Exudyn's solver stopped (its Newton iteration failed at the fixed step)."""


@contextmanager
def quiet():
    """Exudyn's console writing (exudyn.Print, config.printToConsole) off for one engine call:
    SolveDynamic prints a "DYNAMIC SOLVER FAILED" banner before it raises, and a note on
    "memory allocations in every time step" on models with Python user functions (the knife
    edge, the moving support: a performance note, not a result). A failure still raises; its
    reason is read from the solver (``failure_reason``)."""
    before = exu.config.printToConsole
    exu.config.printToConsole = False
    try:
        yield
    finally:
        exu.config.printToConsole = before


def failure_reason(solver) -> str:
    """Why Exudyn's implicit solver stopped, from its convergence flags (what its banner says,
    without the generic hints)."""
    conv, it = solver.conv, solver.it
    why = [
        text
        for flag, text in (
            (conv.newtonSolutionDiverged, "Newton iteration diverged"),
            (conv.stepReductionFailed, "Newton iteration did not converge at the fixed step"),
            (conv.linearSolverFailed, f"linear solver failed (row {conv.linearSolverCausingRow})"),
            (conv.massMatrixNotInvertible, "mass matrix not invertible"),
        )
        if flag
    ]
    return (
        f"{'; '.join(why) or 'stopped'} at t = {it.currentTime:.6g} (residual {conv.residual:.3g})"
    )


def _sensors(mbs) -> list[tuple[int, int, int]]:
    """(node, coordinate sensor, velocity sensor) for every node with ODE2 coordinates."""
    out = []
    for n in range(mbs.systemData.NumberOfNodes()):
        if not len(mbs.systemData.GetNodeLTGODE2(n)):
            continue
        s_q = mbs.AddSensor(
            SensorNode(
                nodeNumber=n,
                storeInternal=True,
                writeToFile=False,
                outputVariableType=exu.OutputVariableType.Coordinates,
            )
        )
        s_v = mbs.AddSensor(
            SensorNode(
                nodeNumber=n,
                storeInternal=True,
                writeToFile=False,
                outputVariableType=exu.OutputVariableType.Coordinates_t,
            )
        )
        out.append((n, s_q, s_v))
    return out


def _grid_indices(t_eval: np.ndarray, t0: float, timestep: float) -> np.ndarray:
    k = np.rint((t_eval - t0) / timestep)
    if np.any(np.abs(t_eval - t0 - k * timestep) > GRID_TOL * timestep) or np.any(k < 0):
        raise EngineUnsupported(
            f"exudyn: output times must lie on the step grid t0 + k * {timestep:g} (fixed-step "
            "integrator); choose t_eval as multiples of the timestep"
        )
    return k.astype(int)


def _continuous_angles(Q: np.ndarray, q0: np.ndarray, indices) -> np.ndarray:
    """Angles read back with atan2 jump by 2 pi at +-pi; along a trajectory they are made
    continuous (np.unwrap) on the branch of the initial state's angle."""
    for i in indices:
        if len(Q):
            Q[:, i] = np.unwrap(Q[:, i])
            Q[:, i] += 2 * np.pi * np.round((q0[i] - Q[0, i]) / (2 * np.pi))
    return Q


def simulate(
    model, q0, u0, t_eval: np.ndarray, integrator: str, timestep: float
) -> EngineTrajectory:
    t0 = float(t_eval[0]) if t_eval.size else 0.0
    steps = _grid_indices(t_eval, t0, timestep)
    sim = type(model)(model.model_name, model.params, simulation=True)
    sim.nominal = model.nominal  # the same maps as the model's (nominal values)
    sim.time = t0
    qe0, ve0 = sim.to_engine_state(q0, u0)
    mbs = sim.mbs
    sensors = _sensors(mbs)
    mbs.Assemble()
    sim._set_state(qe0, ve0, t0)
    ss = sim.settings
    ti = ss.timeIntegration
    n_steps = int(steps.max()) if steps.size else 0
    ti.startTime, ti.endTime = t0, t0 + n_steps * timestep
    ti.numberOfSteps = max(n_steps, 1)
    ti.adaptiveStep = False
    ti.newton.relativeTolerance, ti.newton.absoluteTolerance = NEWTON_RTOL, NEWTON_ATOL
    ss.solution.sensors.writePeriod = timestep
    start = time.perf_counter()
    try:
        with quiet():
            mbs.SolveDynamic(ss, solverType=INTEGRATORS[integrator], storeSolver=True)
    except Exception as exc:  # Exudyn raises exudyn.SolverError("SolveDynamic terminated")
        reason = failure_reason(mbs.sys["dynamicSolver"]) if "dynamicSolver" in mbs.sys else exc
        raise ExudynIntegrationError(
            f"{model.model_name}: Exudyn's {integrator} stopped with timestep {timestep:g} "
            f"({reason}): use a smaller timestep"
        ) from exc
    wall = time.perf_counter() - start
    # every node's record: rows (time, coordinates...), one row per step from t0
    rec_q = [np.asarray(mbs.GetSensorStoredData(s_q)) for _, s_q, _ in sensors]
    rec_v = [np.asarray(mbs.GetSensorStoredData(s_v)) for _, _, s_v in sensors]
    order = np.concatenate([np.asarray(mbs.systemData.GetNodeLTGODE2(n)) for n, _, _ in sensors])
    Q, U, viol, vviol, E = [], [], [], [], []
    for t, k in zip(t_eval, steps, strict=True):
        qe, ve = np.empty(order.size), np.empty(order.size)
        qe[order] = np.concatenate([r[k, 1:] for r in rec_q])
        qe += sim.q_reference
        ve[order] = np.concatenate([r[k, 1:] for r in rec_v])
        model.time = float(t)
        q, u = model.from_engine_state(qe, ve)
        Q.append(q)
        U.append(u)
        viol.append(model.constraint_violation(qe, float(t)))
        vviol.append(model.velocity_violation(qe, ve, float(t)))
        E.append(sum(model._energy_engine(qe, ve)))
    q_out = _continuous_angles(np.array(Q), np.asarray(q0, float), model.angle_indices)
    return EngineTrajectory(
        t=np.asarray(t_eval, float),
        q=q_out,
        u=np.array(U),
        violation=np.array(viol),
        velocity_violation=np.array(vviol),
        energy=np.array(E),
        integrator=integrator,
        setting={
            "timestep": timestep,
            "newton_rtol": NEWTON_RTOL,
            "newton_atol": NEWTON_ATOL,
            "spectral_radius": ti.generalizedAlpha.spectralRadius,
        },
        wall_s=wall,
        steps=n_steps,
    )
