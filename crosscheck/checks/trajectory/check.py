"""Trajectories: the same initial state run T seconds in the reference and in each engine.

- reference: DOP853 with coordinate projection at rtol = atol = 1e-12 (reference.integrate.driver),
  its own accuracy measured in the same run against rtol = atol = 1e-13;
- each engine with the first of its integrators (Capabilities.integrators): an error-controlled
  one at rtol = atol = 1e-10 in the engine's own coordinates, no stabilization (index-1 drift
  is part of what is measured), and again at 10x that rtol for its own error unless it is the
  reference's stepper (Pinocchio: the reference's DOP853 on its forward dynamics), a fixed-step
  one on a time-step ladder h and h/2 (MuJoCo: its own RK4; h = 1 ms, or for a horizon that
  is not a whole number of ms the largest step below 1 ms that divides it, see step_ladder),
  every run recorded on the reference's output times (output_grid).
Each run yields records (state error against the reference, constraint drift, velocity drift
|A u + a0|, energy drift) and a series for the report's plots; an engine model with soft
constraint rows (Capabilities.soft_limit) is also run with its regularization's time constant
halved, and the two runs extrapolated to the rigid limit are judged against the reference
(``state_error_rigid_limit``, trajectory_soft.py), which sizes its other tolerances too; a run
that does not finish is a failed record with its reason, and the other runs go on. What a run is
judged by (the scaled state error, residuals, energy) is in trajectory_measures.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from crosscheck.checks import tolerances as C
from crosscheck.checks.instantaneous import build, energy_drift, work_energy_balance
from crosscheck.checks.records import record
from crosscheck.checks.sampling import monitor_of
from crosscheck.checks.trajectory.grid import (  # noqa: F401 (re-exported: the check's grid)
    FIXED_STEPS,
    GRID_SLACK,
    N_OUT,
    output_grid,
    step_ladder,
)
from crosscheck.checks.trajectory.horizon import (
    NoHorizon,
    activation_reason,
    crossed,
    first_activation,
    horizon_before,
    horizon_reason,
    name_the_horizon,
    nothing_to_compare,
    singular_time,
)
from crosscheck.checks.trajectory.measures import (
    energy_measure,
    energy_series,
    residual_series,
    state_error,
)
from crosscheck.checks.trajectory.soft import (
    SOFT_DRIFT,
    SOFT_ENERGY,
    SOFT_STATE,
    SOFT_VELOCITY_DRIFT,
    soft_limit,
)
from crosscheck.checks.trajectory.tolerances import (
    EXACT_ROWS_DRIFT,
    INDEX1_DRIFT,
    INDEX1_VELOCITY_DRIFT,
    REFERENCE_ACCURACY,
    projected_drift,
    projected_velocity_drift,
    ref_energy,
)
from crosscheck.engines.base import EngineUnsupported
from crosscheck.engines.registry import engine_label
from crosscheck.runtime import interrupts
from reference import NumericModel
from reference.integrate.driver import simulate

T_END = 5.0
REF_RTOL, REF_CHECK_RTOL = 1e-12, 1e-13
ENGINE_RTOL = 1e-10  # engines' error-controlled integrators (rtol = atol)


def _failed(rec, engine, what: str, exc: Exception, **details) -> dict:
    """A failed record for a run that did not finish (step underflow, a projection that does
    not converge, a singular system): the run goes on with the next one."""
    message = (str(exc).splitlines() or [""])[0]
    return rec(
        engine,
        "state_error",
        math.inf,
        C.Tolerance(0.0, "the run must finish"),
        f"{what} failed: {type(exc).__name__}: {message}",
        failure=True,
        **details,
    )


def _series(model, engine, formulation, label, t, err, res, E, work=None, variant=None):
    """One line of the report's trajectory plots; `work` (the reference's W(t)) where energy is
    not conserved, so the plots show the work-energy balance that the records check."""
    s = {
        "model": model,
        "engine": engine,
        "formulation": formulation,
        "label": label,
        "t": np.asarray(t).tolist(),
        "state_error": np.asarray(err).tolist(),
        "residual": np.asarray(res).tolist(),
        "energy": np.asarray(E).tolist(),
        "energy_kind": "total energy K + V (reference datum)",
        "state_error_kind": "max |x - x_ref| / max(max |x_ref|, 1), x = (q, u)",
        "reference_label": f"reference DOP853+projection rtol={REF_RTOL:g}",
    }
    if work is not None:
        s["work"] = np.asarray(work).tolist()
        s["energy_kind"] += (
            "; not conserved: the work-energy balance E(t) - E(0) - W(t) is "
            "checked, W the work of loads and moving constraints"
        )
    if variant:
        s["variant"] = variant
    return s


class _Tolerances(NamedTuple):
    """What an engine run's first-rung records are held to."""

    state: C.Tolerance
    drift: C.Tolerance  # constraint drift |f(q, t)|
    energy: C.Tolerance  # energy drift, or work-energy balance
    velocity: C.Tolerance  # velocity drift |A u + a0|


def _adaptive_runs(em, integrator, q0, u0, grid, loose_err, loose_E, reference_stepper: bool):
    """An error-controlled engine integrator at ENGINE_RTOL, held to 10x the reference's own
    global error (and energy error) at that rtol, measured in this run. Returns the runs, their
    _Tolerances and the extra records (none)."""
    tr = em.simulate(q0, u0, grid, integrator=integrator, rtol=ENGINE_RTOL)
    why = (
        f"{integrator} at rtol {ENGINE_RTOL:g}: 10x the global error of the reference's "
        f"DOP853 at that rtol, measured in this run ({loose_err:.1e}; another choice of "
        f"coordinates)"
    )
    if reference_stepper:  # the reference's own DOP853 stepper: loose_err is its error per rtol
        state_tol = C.Tolerance(
            10 * loose_err + 1e-10, f"{why}; the engine is integrated by that same stepper"
        )
    else:
        # the engine's own integrator need not share DOP853's error per rtol (Simbody's
        # accuracy is a different norm): its own error, estimated against a run at 10x the
        # rtol, is added
        loose = em.simulate(q0, u0, grid, integrator=integrator, rtol=10 * ENGINE_RTOL)
        own = float(np.max(state_error(loose.q, loose.u, tr.q, tr.u)))
        state_tol = C.Tolerance(
            10 * loose_err + own + 1e-10,
            f"{why}, plus the engine's own error estimated against its run at rtol "
            f"{10 * ENGINE_RTOL:g} ({own:.1e})",
        )
    label = f"{integrator} rtol={ENGINE_RTOL:g} (no stabilization)"
    energy_tol = C.Tolerance(
        10 * loose_E + 1e-10,
        f"10x the reference's energy drift at rtol "
        f"{ENGINE_RTOL:g} without stabilization ({loose_E:.1e}; "
        f"the work-energy balance where energy is not conserved)",
    )
    return (
        [(label, tr.t, tr.q, tr.u, {"nfev": tr.steps})],
        _Tolerances(state_tol, INDEX1_DRIFT, energy_tol, INDEX1_VELOCITY_DRIFT),
        [],
    )


def _fixed_step_runs(ctx, em, integrator, has_soft_limit: bool):
    """A fixed-step engine integrator on the step ladder FIXED_STEPS: the tolerances come from
    halving the step, and for soft constraint rows from the rigid limit (trajectory_soft) where
    the engine has a stiffer model (else characterized, SOFT_*). Returns the runs, their
    _Tolerances and the extra records."""
    nm, q0, u0 = ctx.nm, ctx.q0, ctx.u0
    grid = output_grid(ctx.t_end)
    ladder = step_ladder(ctx.t_end)
    runs, trs = [], {}
    for h in ladder:  # both rungs record on the same output times
        trs[h] = em.simulate(q0, u0, grid, integrator=integrator, timestep=h)
        info = {"steps": trs[h].steps}
        if trs[h].warnings:  # an unstable step reset the engine's state
            info["engine_warnings"] = trs[h].warnings
        runs.append((f"{integrator} h={h:g}", trs[h].t, trs[h].q, trs[h].u, info))
    h0, h1 = ladder
    halving = float(np.max(state_error(trs[h0].q, trs[h0].u, trs[h1].q, trs[h1].u)))
    if em.soft_constraints:
        if not has_soft_limit:
            return runs, _Tolerances(SOFT_STATE, SOFT_DRIFT, SOFT_ENERGY, SOFT_VELOCITY_DRIFT), []
        limit, state_tol, energy_tol = soft_limit(ctx, em, integrator, runs, h0, halving)
        return runs, _Tolerances(state_tol, SOFT_DRIFT, energy_tol, SOFT_VELOCITY_DRIFT), [limit]
    state_tol = C.Tolerance(
        10 * halving + 1e-10,
        f"{engine_label(em.engine)}'s constraint rows, if any, are rigid (no soft "
        f"regularization to extrapolate away): {integrator}'s global error, estimated in this "
        f"run by halving the step ({halving:.1e}), times 10, plus the reference's own accuracy",
    )
    E0, E1 = (energy_measure(ctx, trs[h].t, trs[h].q, trs[h].u) for h in (h0, h1))
    energy_tol = C.Tolerance(
        10 * abs(E0 - E1) + 1e-10,
        f"{integrator}'s energy error estimated by halving the step ({abs(E0 - E1):.1e}), times 10",
    )
    # a fixed-step (index-3) solver holds the position rows; its velocity residual is a
    # discretization error, estimated like the state error by halving the step
    V0, V1 = (
        float(np.max(residual_series(nm, trs[h].t, trs[h].q, trs[h].u)[1])) if nm.m else 0.0
        for h in (h0, h1)
    )
    velocity_tol = C.Tolerance(
        10 * abs(V0 - V1) + 1e-10,
        f"{integrator}'s velocity-row residual estimated by halving the "
        f"step ({abs(V0 - V1):.1e}), times 10",
    )
    return runs, _Tolerances(state_tol, EXACT_ROWS_DRIFT, energy_tol, velocity_tol), []


@dataclass(frozen=True)
class _Reference:
    """The reference's run of one model, and what the engines' tolerances take from it."""

    name: str
    nm: NumericModel
    t_end: float
    grid: np.ndarray
    q0: np.ndarray
    u0: np.ndarray
    ref: object  # the reference trajectory at rtol REF_RTOL
    work: np.ndarray  # work of loads and moving constraints along it
    conserved: bool
    loose_err: float  # the reference's own global error at ENGINE_RTOL (index-1)
    loose_E: float  # and its energy drift (or work-energy balance) there

    def rec(self, engine, qty, err, tol, reason="", **k):
        return record(
            self.name,
            self.nm.formulation,
            engine,
            "trajectory",
            qty,
            err,
            tol,
            reason,
            t_end=self.t_end,
            **k,
        )


def _reference_runs(nm: NumericModel, q0, u0, t_end: float, grid):
    """The reference at REF_RTOL, at REF_CHECK_RTOL, and index-1 at the engines' rtol; raises
    RuntimeError naming the run that failed."""
    what = f"the reference run (DOP853+projection rtol {REF_RTOL:g})"
    try:
        ref = simulate(nm, q0, u0, t_end, "projection", rtol=REF_RTOL, atol=REF_RTOL, t_eval=grid)
        crossed(ref)
        what = f"the tighter reference run (rtol {REF_CHECK_RTOL:g})"
        tight = simulate(
            nm, q0, u0, t_end, "projection", rtol=REF_CHECK_RTOL, atol=REF_CHECK_RTOL, t_eval=grid
        )
        crossed(tight)
        what = f"the reference's index-1 run at the engines' rtol {ENGINE_RTOL:g}"
        # the reference's own global error at the engines' tolerance, for the adaptive bound
        loose = simulate(
            nm, q0, u0, t_end, "index1", rtol=ENGINE_RTOL, atol=ENGINE_RTOL, t_eval=grid
        )
        crossed(loose)
    except Exception as exc:
        interrupts.check()
        raise _RunFailed(what, exc) from exc
    return ref, tight, loose


class _RunFailed(RuntimeError):
    """A run that did not finish: what it was, and the exception."""

    def __init__(self, what: str, exc: Exception):
        super().__init__(what)
        self.what, self.exc = what, exc


def _is_conserved(nm: NumericModel, ref) -> bool:
    """Energy is conserved at these parameters: declared so, or no load does work along the
    reference run (a driving torque or damper whose parameter is 0) and no constraint moves."""
    from reference.constraints import is_rheonomic

    return nm.model.energy_conserved or (
        not is_rheonomic(nm.model)
        and all(
            nm.power_balance(qi, ui, ti)["load_power"] == 0.0
            for ti, qi, ui in zip(ref.t[::10], ref.q[::10], ref.u[::10], strict=True)
        )
    )


def _reference_run(name: str, nm: NumericModel, t_end: float, start=None):
    """The reference's run from the model's initial state (or ``start``), its records and
    series, and the context the engines need; raises _RunFailed when one of its runs does not
    finish."""
    model = nm.model
    grid = output_grid(t_end)
    q0, u0 = nm.project(*(start if start is not None else (model.initial_q, model.initial_u)))
    ref, tight, loose = _reference_runs(nm, q0, u0, t_end, grid)
    conserved = _is_conserved(nm, ref)
    # where energy is not conserved, the work-energy balance: E(t) - E(0) = W(t), the work of
    # the applied loads and moving constraints, integrated exactly alongside the reference run
    work = ref.work if ref.work is not None else np.zeros(len(ref.t))
    loose_err = float(np.max(state_error(loose.q, loose.u, ref.q, ref.u)))
    E_loose = energy_series(nm, loose.t, loose.q, loose.u)
    loose_E = energy_drift(E_loose) if conserved else work_energy_balance(E_loose, work)
    ctx = _Reference(name, nm, t_end, grid, q0, u0, ref, work, conserved, loose_err, loose_E)
    records, series = _reference_records(ctx, tight)
    return ctx, records, series


def _reference_horizon_run(name: str, nm: NumericModel, t_end: float, start=None):
    """_reference_run over t_end or, for a file with contacts or limits, over the horizon
    before the first one acts, and where a reference run reaches a singular pose first, over
    the horizon before the earliest such pose (trajectory_horizon), with a skipped record
    saying so. Each retry stops strictly earlier, so this ends."""
    t_try, reason = t_end, None
    monitor = monitor_of(nm.model)
    if monitor is not None:  # first, so that the reference runs only over what is compared
        q0, u0 = nm.project(*(start if start is not None else _initial(nm)))
        try:
            hit = first_activation(nm, q0, u0, t_end, monitor.active, REF_RTOL)
        except Exception as exc:
            interrupts.check()
            raise _RunFailed("the reference's run checked for contacts and limits", exc) from exc
        if hit is not None:
            t_cut = horizon_before(hit[0], t_end)
            reason = activation_reason(t_cut, t_end, *hit)
            if t_cut is None:
                raise NoHorizon(reason)
            t_try = t_cut
    while True:
        try:
            ctx, records, series = _reference_run(name, nm, t_try, start)
            break
        except _RunFailed as exc:
            t_sing = singular_time(exc.exc)
            t_cut = None if t_sing is None else horizon_before(t_sing, t_try)
            if t_sing is None or t_cut is None or t_cut >= t_try:
                raise
            message = (str(exc.exc).splitlines() or [""])[0]
            reason = horizon_reason(t_cut, t_end, t_sing, f"{exc.what}: {message}")
            t_try = t_cut
    if reason is not None:  # the last cut: each one ends before the one before
        records.append(ctx.rec("reference", "horizon", None, None, reason, t_requested=t_end))
    return ctx, records, series


def _initial(nm: NumericModel):
    return nm.model.initial_q, nm.model.initial_u


def _reference_records(ctx: _Reference, tight):
    """The reference's records (its accuracy against the tighter run, its drifts within the
    projection's guarantees, its energy) and its plot series."""
    nm, ref, rec = ctx.nm, ctx.ref, ctx.rec
    ref_acc = float(np.max(state_error(ref.q, ref.u, tight.q, tight.u)))
    E_ref = energy_series(nm, ref.t, ref.q, ref.u)
    res_ref, vel_ref = residual_series(nm, ref.t, ref.q, ref.u)
    label = "DOP853+projection"
    records = [
        rec(
            "reference",
            "state_error",
            ref_acc,
            REFERENCE_ACCURACY,
            label=f"{label} rtol={REF_RTOL:g} vs {REF_CHECK_RTOL:g}",
            nfev=ref.nfev,
        )
    ]
    if nm.m:
        records.append(
            rec(
                "reference",
                "constraint_drift",
                float(res_ref.max()),
                projected_drift(ref.q),
                label=label,
            )
        )
        records.append(
            rec(
                "reference",
                "velocity_drift",
                float(vel_ref.max()),
                projected_velocity_drift(ref.u),
                label=label,
            )
        )
    if ctx.conserved:
        records.append(rec("reference", "energy_drift", energy_drift(E_ref), ref_energy(ctx.t_end)))
    else:
        records.append(
            rec(
                "reference",
                "work_energy_balance",
                work_energy_balance(E_ref, ctx.work),
                ref_energy(ctx.t_end),
                label="E(t) - E(0) - W(t), W integrated with the run",
            )
        )
    series = _series(
        ctx.name,
        "reference",
        nm.formulation,
        f"{label} rtol={REF_RTOL:g}",
        ref.t,
        state_error(ref.q, ref.u, tight.q, tight.u),
        res_ref,
        E_ref,
        None if ctx.conserved else ctx.work,
    )
    return name_the_horizon(records, ctx.t_end), [series]


def _check_on_grid(ctx: _Reference, engine: str, label: str, t) -> None:
    """An engine run must land on the reference's output times (a bug here, not a finding)."""
    ref_t = ctx.ref.t
    if len(t) != len(ref_t) or np.max(np.abs(np.asarray(t) - ref_t)) > GRID_SLACK * max(
        ctx.t_end, 1.0
    ):
        raise RuntimeError(
            f"{engine} trajectory of {ctx.name} ({label}, {len(t)} times) "
            f"is not on the reference's output grid ({len(ref_t)} times over "
            f"{ctx.t_end:g} s): a bug in output_grid / step_ladder"
        )


def _engine_run(ctx: _Reference, adapter, em, variant):
    """Records (the first rung) and series (every rung) of one engine model's trajectories."""
    nm, ref = ctx.nm, ctx.ref
    integrator = adapter.capabilities.integrators[0]
    extra = {"variant": variant} if variant else {}
    try:
        if integrator in adapter.capabilities.adaptive_integrators:
            runs, tols, more = _adaptive_runs(
                em,
                integrator,
                ctx.q0,
                ctx.u0,
                ctx.grid,
                ctx.loose_err,
                ctx.loose_E,
                integrator in adapter.capabilities.reference_integrators,
            )
        else:
            runs, tols, more = _fixed_step_runs(
                ctx, em, integrator, adapter.capabilities.soft_limit
            )
    except Exception as exc:
        interrupts.check()  # unless Ctrl-C stopped it (the engine may report that as a failure)
        return [
            _failed(ctx.rec, adapter.name, f"{adapter.name}'s {integrator} run", exc, **extra)
        ], []
    records, series = [], []
    for k, (label, t, q, u, info) in enumerate(runs):
        _check_on_grid(ctx, adapter.name, label, t)
        err = state_error(q, u, ref.q, ref.u)
        res, vel = residual_series(nm, t, q, u)
        E = energy_series(nm, t, q, u)
        work = None if ctx.conserved else ctx.work
        series.append(
            _series(ctx.name, adapter.name, nm.formulation, label, t, err, res, E, work, variant)
        )
        if not k:  # records for the first rung; the others feed the estimate and plots
            measured = (float(err.max()), float(res.max()), float(vel.max()), E)
            records += _engine_records(ctx, adapter.name, em, tols, label, measured, info, extra)
    for qty, err, tol, label in more:  # e.g. the soft model's rigid limit
        records.append(ctx.rec(adapter.name, qty, err, tol, label=label, **extra))
    return records, series


def _engine_records(
    ctx: _Reference, engine: str, em, tols: _Tolerances, label, measured, info, extra
):
    """The records of an engine run's first rung: its state error, drifts and energy against
    their tolerances; measured = (max state error, max |f|, max |A u + a0|, energy series)."""
    err, drift, vel, E = measured
    records = [ctx.rec(engine, "state_error", err, tols.state, label=label, **info, **extra)]
    if ctx.nm.m:
        records.append(ctx.rec(engine, "constraint_drift", drift, tols.drift, label=label, **extra))
        records.append(ctx.rec(engine, "velocity_drift", vel, tols.velocity, label=label, **extra))
    if ctx.conserved:
        records.append(
            ctx.rec(engine, "energy_drift", energy_drift(E), tols.energy, label=label, **extra)
        )
        return records
    # a soft model's energy tolerance already judges its work-energy balance
    balance_tol = (
        tols.energy
        if em.soft_constraints
        else C.Tolerance(
            tols.energy.value + 10 * tols.state.value,
            "the engine's energy change against the work done along the "
            "reference's run: they differ by the engine's energy error plus the "
            "work along the trajectory difference, bounded by the state tolerance "
            "(x10 for the size of grad E)",
        )
    )
    records.append(
        ctx.rec(
            engine,
            "work_energy_balance",
            work_energy_balance(E, ctx.work),
            balance_tol,
            label=label,
            **extra,
        )
    )
    return records


def trajectory_records(
    name: str,
    nm: NumericModel,
    adapters,
    t_end: float = T_END,
    engine_params: dict | None = None,
    start=None,
):
    """Records and plot series for one model: the reference, then every engine variant, from
    the model's initial state or ``start`` (a consistent (q, u): a user's file whose initial
    state has a contact or limit acting). A run that does not finish is a failed record with
    its reason; the other runs go on."""
    try:
        ctx, records, series = _reference_horizon_run(name, nm, t_end, start)
    except NoHorizon as none:
        return nothing_to_compare(name, nm.formulation, adapters, t_end, str(none)), []
    except _RunFailed as failed:
        rec = lambda engine, qty, err, tol, reason="", **k: record(
            name, nm.formulation, engine, "trajectory", qty, err, tol, reason, t_end=t_end, **k
        )
        return [_failed(rec, "reference", failed.what, failed.exc)] + [
            rec(
                a.name,
                "state_error",
                None,
                None,
                "no reference trajectory to compare with "
                "(its run failed, see the reference's trajectory record)",
            )
            for a in adapters
        ], []
    for adapter in adapters:
        params = (engine_params or {}).get(adapter.name, nm.params)
        if not adapter.capabilities.integrators:
            records.append(
                ctx.rec(
                    adapter.name,
                    "state_error",
                    None,
                    None,
                    f"{adapter.name} has no trajectories in this suite",
                )
            )
            continue
        for variant in adapter.variants(name):
            try:
                em = build(adapter, name, params, variant, nominal=nm.params)
            except EngineUnsupported as exc:
                records.append(
                    ctx.rec(
                        adapter.name,
                        "state_error",
                        None,
                        None,
                        f"engine cannot represent the model: {exc}",
                    )
                )
                continue
            recs, ser = _engine_run(ctx, adapter, em, variant)
            records += recs
            series += ser
    return records, series
