"""Work-precision benchmark: wall time against final-state error and constraint residual.

One record per model x engine x method x setting:
- reference: every method of reference.integrate.driver over a tolerance ladder (rtol = atol),
DOP853;
- every engine, through its simulate() and Capabilities.integrators: each error-controlled
  integrator (adaptive_integrators; quick: the first) over the same rtol ladder (method "index1":
  e.g. Pinocchio's forward dynamics under scipy's DOP853, OpenSim's Simbody integrators), each
  fixed-step one over a time-step ladder (MuJoCo's mj_step per integrator, FIXED_STEPS_*; any
  other, e.g. Exudyn's implicit solvers, FIXED_STEPS_OTHER), every step adjusted to divide the
  horizon; a soft engine whose adapter takes `solref` also at stiffer constraint settings (time
  constant SOFT_TIMECONST_STEPS steps: method "<integrator> solref=<k>h", field solref).
Fields: model, engine, method, integrator, setting (rtol = atol, or the time step),
setting_kind, wall_s (median of `repeats`), wall_s_min, error (max over q and u of |final state
- reference|, the model's own coordinates), residual (max over the outputs of |f(q, t)| and |A u
+ a0|, evaluated by the reference on the engine's mapped states), residual_position/_velocity,
energy_drift (max |E - E0 - W| / |E| scale, None where not checked), timed_energy (the
reference's: what its timed runs integrate besides the motion), stepper (the reference's: "c",
the whole run in the model's C module, or "python (why)"; reference.integrate.compiled), nfev,
t_end, and the reference's kind and estimated accuracy; error_resolved (False: the error is at
or below the reference's own accuracy, error_note says so: the figure bounds the run's error, it
does not measure it); reference_same_method (True: the reference solution is a tighter run of
this row's own method, models without an independent reference: the error shows convergence
only); setting_requested (the ladder's step where it was adjusted to divide the horizon),
solref, engine_steps. A run that fails keeps its row with "failed": reason; an engine's refusal
of a model (EngineUnsupported) is a row with "skipped", "refusal" and the reason, any other
build error a failed row.

Timings are medians over repeats and meaningful only as ratios within one run (crosscheck/timing).
What is inside each wall_s: reference: simulate() from the projected initial state to t_end
(outputs = every accepted step), the motion only (timed_energy "none": the work integral, where
the energy check needs it, comes from an untimed run, as the engines' timed runs carry none);
an engine: the wall time its simulate() reports (Pinocchio: the whole call, including the
mapping of its 21 output states; MuJoCo: its own loop timer, mj_step calls plus two recorded
states), else the call.
"""

from __future__ import annotations

import inspect
import math
import statistics
import time

import numpy as np

from crosscheck.checks.instantaneous import constraint_residual, energy_drift
from crosscheck.engines.base import EngineAdapter, EngineUnsupported
from crosscheck.engines.registry import available_engines, engine_label, get_engine
from reference import NumericModel, models
from reference.errors import ModelInputError
from reference.integrate.driver import METHODS, simulate
from reference.minimal import reference_final_state

# benchmark horizons [s]: the pendulum over ~6 periods (the exploratory study's 10 s), the
# slider-crank over ~2.5 crank revolutions, the 3-D models over 1-2 s
HORIZON = {
    "pendulum_angle": 10.0,
    "pendulum_xy": 10.0,
    "slider_crank": 2.0,
    "slider_crank_split": 2.0,
    "slider_crank_free": 2.0,
    "top_euler": 1.0,
    "top_cartesian": 1.0,
}
DEFAULT_HORIZON = 2.0

LADDER_FULL = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
LADDER_QUICK = (1e-6, 1e-8, 1e-10, 1e-12)
ENGINE_LADDER_FULL = (1e-6, 1e-8, 1e-10, 1e-12)
ENGINE_LADDER_QUICK = (1e-6, 1e-8, 1e-10)
# fixed-step engine integrators (MuJoCo's): a time-step ladder per integrator
FIXED_STEPS_FULL = {
    "Euler": (1e-2, 1e-3, 1e-4, 1e-5),
    "implicitfast": (1e-2, 1e-3, 1e-4, 1e-5),
    "RK4": (1e-2, 3e-3, 1e-3, 3e-4, 1e-4),
}
FIXED_STEPS_QUICK = {"Euler": (1e-3, 1e-4), "implicitfast": (1e-3, 1e-4), "RK4": (1e-2, 1e-3, 1e-4)}
# every other fixed-step integrator (Exudyn's implicit solvers, OpenSim's ExplicitEuler,
# MuJoCo's implicit): one ladder for all (quick: ~0.2-0.7 s per slider-crank run at 1e-3 on this
# machine). No 1e-2: Exudyn's generalized-alpha stops there on slider_crank_free, top_cartesian
# and top_euler (its Newton iteration does not converge); 1e-3 runs on every model of every
# engine (measured by running each engine's fixed-step integrators on each of its models)
FIXED_STEPS_OTHER = {True: (1e-3,), False: (1e-3, 1e-4)}
# a soft engine at its stiffest: its constraint time constant (MuJoCo's solref[0], damping
# ratio 1) set to this many time steps per run, beside the adapter's default; 2 steps is
# MuJoCo's documented floor (a smaller one is clamped to it); quick leaves out the steps below
# STIFF_MIN_STEP (the 1e-4 runs cost ~2 s each)
SOFT_TIMECONST_STEPS = (2, 5)
STIFF_MIN_STEP = {True: 1e-3, False: 0.0}
# fixed-step runs longer than this many steps are left out (quick: ~0.3 s per MuJoCo run on
# this machine)
FIXED_MAX_STEPS = {True: 25_000, False: 1_000_000}
QUICK_MODELS = ("pendulum_xy", "slider_crank")
REPEATS_FULL, REPEATS_QUICK = 5, 3
# an engine's error-controlled run longer than this leaves out the tighter settings of its
# ladder (engines take no wall bound): OpenSim's second-order Verlet had not finished its full
# ladder on the slider-crank after 5 minutes, where its other integrators take 4-33 s per ladder
ENGINE_RUN_BUDGET_S = {True: 10.0, False: 30.0}
# a single run longer than this is not repeated (its timing noise is small against its length)
REPEAT_BUDGET_S = 1.0
RUN_BOUND_S = {True: 10.0, False: 60.0}  # max_wall_s of one reference run (quick, full)
# the reference's timed runs integrate the motion only, as the engines' do (no engine integrates
# the work of its loads): the work integral W, where the model needs it for its energy check,
# comes from an untimed run (reference_records). Carrying W made the slider-crank's projection
# run at rtol 1e-10 1.32x slower at least (bench.json skips.energy_bookkeeping,
# ratio_wall_work_over_none; benchmarks/reference_speed.md "`crosscheck bench`")
TIMED_ENERGY = "none"


def horizon(name: str) -> float:
    return HORIZON.get(name, DEFAULT_HORIZON)


def _timed(fn, repeats: int):
    """(last result, median wall, min wall, runs): fn() returns (result, seconds)."""
    walls, out = [], None
    for _k in range(repeats):
        out, w = fn()
        walls.append(w)
        if w > REPEAT_BUDGET_S:
            break
    return out, statistics.median(walls), min(walls), len(walls)


def _finite(x) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _judge_error(rec: dict, err, ref) -> None:
    """rec["error"], and whether it is above the reference's own estimated accuracy: an error at
    or below it is not resolved (the figure is the reference's error as much as the run's)."""
    rec["error"] = _finite(err)
    if rec["engine"] == "reference" and ref.kind.startswith(f"tight run ({rec['method']},"):
        # the reference is a tighter run of this very method: convergence, not independence
        rec["reference_same_method"] = True
    if rec["error"] is None:
        return
    rec["error_resolved"] = rec["error"] > ref.accuracy
    if not rec["error_resolved"]:
        rec["error_note"] = (
            f"at or below the reference's accuracy ({ref.accuracy:.1e}, "
            f"{ref.kind}): the run's error is not resolved"
        )


def _state_metrics(nm: NumericModel, T, Q, U, ref_state, energy_conserved: bool):
    """error vs the reference, max residuals and energy drift of mapped states."""
    rp = rv = 0.0
    E = []
    for t, q, u in zip(T, Q, U, strict=True):
        pos, vel = constraint_residual(nm, q, u, t)
        rp, rv = max(rp, pos), max(rv, vel)
        if energy_conserved:
            E.append(sum(nm.energy(q, u, t)))
    err = float(np.max(np.abs(np.concatenate([Q[-1], U[-1]]) - ref_state)))
    drift = energy_drift(E) if energy_conserved and E else None
    return err, rp, rv, drift


def _base(name, engine, method, integrator, setting, kind, T, ref):
    return {
        "model": name,
        "engine": engine,
        "method": method,
        "integrator": integrator,
        "setting": setting,
        "setting_kind": kind,
        "t_end": T,
        "reference_kind": ref.kind,
        "reference_accuracy": ref.accuracy,
    }


def _reference_run(nm, name, method, tol, quick, energy):
    """One reference run over the horizon from the model's initial state."""
    m = nm.model
    return simulate(
        nm,
        m.initial_q,
        m.initial_u,
        horizon(name),
        method,
        rtol=tol,
        atol=tol,
        energy=energy,
        max_wall_s=RUN_BOUND_S[quick],
    )


def reference_records(name, quick, ref, nm, methods=METHODS, ladder=None):
    """Every reference method over the rtol = atol ladder. The timed runs integrate the motion
    only (energy="none"), as the engines' timed runs do; where the model does not conserve
    energy, the work integral W is carried in one more, untimed run of the same setting
    (energy="auto": W never changes the steps, reference.integrate.driver), which gives energy_drift
    (and the work-energy balance) without its cost in wall_s (TIMED_ENERGY)."""
    T = horizon(name)
    out = []
    ladder = ladder or (LADDER_QUICK if quick else LADDER_FULL)
    repeats = REPEATS_QUICK if quick else REPEATS_FULL
    for method in methods:
        for tol in ladder:
            rec = _base(name, "reference", method, "DOP853", tol, "rtol=atol", T, ref)
            try:

                def run(method=method, tol=tol):
                    tr = _reference_run(nm, name, method, tol, quick, TIMED_ENERGY)
                    return tr, tr.wall_s

                tr, wall, wmin, n = _timed(run, repeats)
                r = tr.max_residual()
                _judge_error(rec, np.max(np.abs(tr.final_state - ref.state)), ref)
                trw = tr  # the run whose energy drift is recorded
                if not nm.model.energy_conserved:
                    trw = _reference_run(nm, name, method, tol, quick, "auto")
                rec.update(
                    wall_s=wall,
                    wall_s_min=wmin,
                    repeats=n,
                    residual=max(r["position"], r["velocity"]),
                    residual_position=r["position"],
                    residual_velocity=r["velocity"],
                    energy_drift=_finite(trw.energy_drift()),
                    nfev=tr.nfev,
                    nsteps=tr.nsteps,
                    bookkeeping=trw.settings["bookkeeping"],
                    timed_energy=TIMED_ENERGY,
                    stepper=tr.stats.get("stepper"),
                )
                if method == "nullspace":
                    rec["partitions"] = tr.stats.get("partitions")
                if tr.warnings:
                    rec["warnings"] = list(tr.warnings)
            except Exception as exc:  # recorded, never hidden: the row stays, marked failed
                rec.update(
                    wall_s=None, error=None, residual=None, failed=f"{type(exc).__name__}: {exc}"
                )
            out.append(rec)
    return out


def _engine_model(adapter, name, nm, row):
    """(engine model, None), or (None, [row]): skipped with the reason where the engine has no
    trajectories or refuses the model (EngineUnsupported), failed where the build breaks."""
    if not adapter.capabilities.integrators:
        return None, [
            {
                **row,
                "skipped": True,
                "reason": f"the {adapter.name} engine has no trajectories in this suite",
            }
        ]
    try:
        em = adapter.build(name, nm.params)
    except EngineUnsupported as exc:  # the one expected refusal: the engine says why
        return None, [
            {
                **row,
                "skipped": True,
                "refusal": "EngineUnsupported",
                "reason": f"EngineUnsupported: {exc}",
            }
        ]
    except Exception as exc:  # anything else is a broken build: a failure, never a skip
        return None, [
            {
                **row,
                "wall_s": None,
                "error": None,
                "residual": None,
                "failed": f"engine build: {type(exc).__name__}: {exc}",
            }
        ]
    return em, None


def _simulate_timed(em, q0, u0, t_eval, **setting):
    """(trajectory, seconds): the engine's own wall_s where it reports one, else the call."""
    t0 = time.perf_counter()
    tr = em.simulate(q0, u0, t_eval, **setting)
    return tr, tr.wall_s if tr.wall_s is not None else time.perf_counter() - t0


def adaptive_records(name, quick, ref, nm, em, engine, integrator):
    """An engine's error-controlled integrator over the rtol = atol ladder (method "index1":
    the engine's equations integrated as an index-1 ODE, no stabilization)."""
    T = horizon(name)
    m = nm.model
    out = []
    t_eval = np.linspace(0.0, T, 21)
    slow = None  # the wall of a run over ENGINE_RUN_BUDGET_S: tighter settings are left out
    for tol in ENGINE_LADDER_QUICK if quick else ENGINE_LADDER_FULL:
        rec = _base(name, engine, "index1", integrator, tol, "rtol=atol", T, ref)
        if slow is not None:
            out.append(
                {
                    **rec,
                    "skipped": True,
                    "reason": f"left out: the looser setting took "
                    f"{slow:.0f} s > {ENGINE_RUN_BUDGET_S[quick]:g} s (a tighter one costs "
                    f"more; an engine run cannot be bounded from outside)",
                }
            )
            continue
        try:
            tr, wall, wmin, n = _timed(
                lambda tol=tol: _simulate_timed(
                    em, m.initial_q, m.initial_u, t_eval, integrator=integrator, rtol=tol
                ),
                REPEATS_QUICK if quick else REPEATS_FULL,
            )
            if tr.failure:
                raise RuntimeError(tr.failure)
            err, rp, rv, drift = _state_metrics(nm, tr.t, tr.q, tr.u, ref.state, m.energy_conserved)
            _judge_error(rec, err, ref)
            rec.update(
                wall_s=wall,
                wall_s_min=wmin,
                repeats=n,
                residual=max(rp, rv),
                residual_position=rp,
                residual_velocity=rv,
                energy_drift=_finite(drift),
                nfev=int(tr.steps),
                note="residual and energy drift over 21 output states",
            )
            if wall > ENGINE_RUN_BUDGET_S[quick]:
                slow = wall
        except Exception as exc:
            rec.update(
                wall_s=None, error=None, residual=None, failed=f"{type(exc).__name__}: {exc}"
            )
        out.append(rec)
    return out


STAGES = {"Euler": 1, "implicitfast": 1, "implicit": 1, "RK4": 4}


def _fixed_step_run(rec, quick, ref, nm, em, integ, h, n):
    """Fill one fixed-step record: the timed run to n * h, then an untimed recorded run."""
    m = nm.model
    engine = rec["engine"]
    try:
        tr, wall, wmin, nrep = _timed(
            lambda: _simulate_timed(
                em, m.initial_q, m.initial_u, [0.0, n * h], integrator=integ, timestep=h
            ),
            REPEATS_QUICK if quick else REPEATS_FULL,
        )
        # an untimed run that records ~100 states for the residual and the energy
        every = max(1, n // 100)
        marks = sorted(set(range(0, n + 1, every)) | {n})
        trr = em.simulate(
            m.initial_q, m.initial_u, np.array(marks) * h, integrator=integ, timestep=h
        )
        err, rp, rv, drift = _state_metrics(nm, trr.t, trr.q, trr.u, ref.state, m.energy_conserved)
        err_timed = float(np.max(np.abs(np.concatenate([tr.q[-1], tr.u[-1]]) - ref.state)))
        _judge_error(rec, err_timed, ref)
        stages = STAGES.get(integ)  # None: an implicit solver's calls are not counted here
        rec.update(
            wall_s=wall,
            wall_s_min=wmin,
            repeats=nrep,
            residual=max(rp, rv),
            residual_position=rp,
            residual_velocity=rv,
            energy_drift=_finite(drift),
            nfev=n * stages if stages else None,
            nsteps=n,
            engine_steps=tr.steps,
            engine_violation=_finite(np.max(trr.violation)),
            note="residual and energy drift over ~100 recorded states; nfev = "
            "steps x stages (None: stages unknown)",
        )
        if err != err_timed:
            rec["error_recorded_run"] = _finite(err)
        warnings = {**tr.warnings, **trr.warnings}
        if warnings:  # the engine reset an unstable state and went on: not a trajectory
            rec.update(
                warnings=warnings,
                flagged=f"{engine_label(engine)} reported an "
                f"unstable simulation ({', '.join(warnings)}) and reset its state",
            )
    except Exception as exc:
        rec.update(wall_s=None, error=None, residual=None, failed=f"{type(exc).__name__}: {exc}")
    return rec


def fixed_step_ladder(integ: str, quick: bool) -> tuple:
    """The time steps an engine's fixed-step integrator is run at (FIXED_STEPS_*, else
    FIXED_STEPS_OTHER)."""
    named = FIXED_STEPS_QUICK if quick else FIXED_STEPS_FULL
    return named.get(integ, FIXED_STEPS_OTHER[quick])


def fixed_step_records(name, quick, ref, nm, em, engine, integ, stiff=None):
    """An engine's fixed-step integrator over its time-step ladder. Each step is adjusted to
    divide the horizon (T / round(T / h)), so the final state is compared at T itself.
    `stiff` = (adapter, k): a soft engine rebuilt per step with its constraint time constant
    at k steps (SOFT_TIMECONST_STEPS), recorded as method "<integrator> solref=<k>h"."""
    T = horizon(name)
    out = []
    for h0 in fixed_step_ladder(integ, quick):
        n = round(T / h0)
        h = T / n
        if n > FIXED_MAX_STEPS[quick] or (stiff and h < STIFF_MIN_STEP[quick]):
            continue
        rec = _base(name, engine, integ, integ, h, "timestep", T, ref)
        if h != h0:
            rec["setting_requested"] = h0
        model = em
        if stiff:
            adapter, k = stiff
            rec.update(method=f"{integ} solref={k}h", solref=[k * h, 1.0])
            try:
                model = type(adapter)(solref=(k * h, 1.0)).build(name, nm.params)
            except Exception as exc:  # the default build worked: this one must too
                out.append(
                    {
                        **rec,
                        "wall_s": None,
                        "error": None,
                        "residual": None,
                        "failed": f"engine build: {type(exc).__name__}: {exc}",
                    }
                )
                continue
        out.append(_fixed_step_run(rec, quick, ref, nm, model, integ, h, n))
    return out


def _stiffer(adapter) -> list:
    """(adapter, k) for every stiffer setting of a soft engine whose adapter takes a `solref`
    option (its constraint time constant and damping ratio); [] for every other engine."""
    if adapter.capabilities.exact:
        return []
    try:
        takes = "solref" in inspect.signature(type(adapter)).parameters
    except (TypeError, ValueError):
        takes = False
    return [(adapter, k) for k in SOFT_TIMECONST_STEPS] if takes else []


def engine_records(name, quick, ref, nm, adapter):
    """Every integrator of one engine (Capabilities.integrators) on one model; a soft engine
    also at its stiffer settings (_stiffer)."""
    T = horizon(name)
    caps = adapter.capabilities
    first = caps.integrators[0] if caps.integrators else None
    row = (
        _base(name, adapter.name, "index1", first, None, "rtol=atol", T, ref)
        if first in caps.adaptive_integrators
        else _base(name, adapter.name, None, None, None, "timestep", T, ref)
    )
    em, skip = _engine_model(adapter, name, nm, row)
    if skip:
        return skip
    adaptive = [i for i in caps.integrators if i in caps.adaptive_integrators]
    if quick:  # the first error-controlled integrator only (OpenSim declares six)
        adaptive = adaptive[:1]
    out = []
    for integ in adaptive:
        out += adaptive_records(name, quick, ref, nm, em, adapter.name, integ)
    named = list(FIXED_STEPS_QUICK if quick else FIXED_STEPS_FULL)
    fixed = [i for i in caps.integrators if i not in caps.adaptive_integrators]
    # the named ladders' order first (cheap integrators first), then the engine's own order
    fixed.sort(key=lambda i: named.index(i) if i in named else len(named))
    for integ in fixed:
        out += fixed_step_records(name, quick, ref, nm, em, adapter.name, integ)
        for stiff in _stiffer(adapter):
            out += fixed_step_records(name, quick, ref, nm, em, adapter.name, integ, stiff)
    return out


def adapter_or_reason(engine):
    """The engine adapter object, or the reason it is unavailable."""
    if isinstance(engine, EngineAdapter):
        return engine, None
    try:
        return get_engine(engine), None
    except ModelInputError as exc:  # unknown, or registered but not importable here
        return None, str(exc)


def work_precision_records(model_names, quick: bool = False, engines=None, log=None) -> list[dict]:
    """Records for every model x method over the ladder (see the module docstring).

    `engines`: names or adapter objects (default: every available engine). With `quick`, only
    QUICK_MODELS among `model_names` (the slider-crank always, for every engine) on the short
    ladders."""
    names = list(model_names)
    if quick:
        if set(QUICK_MODELS) <= set(names):  # the default (all models): the quick subset
            names = list(QUICK_MODELS)
        if "slider_crank" not in names:  # quick still covers the slider-crank for every engine
            names.append("slider_crank")
    adapters = []
    for e in available_engines() if engines is None else engines:
        a, why = adapter_or_reason(e)
        adapters.append((a.name if a is not None else e, a, why))
    out = []
    for name in names:
        T = horizon(name)
        try:
            nm = NumericModel(models.get(name))
            ref = reference_final_state(name, T)
        except Exception as exc:
            out.append(
                {
                    "model": name,
                    "engine": "reference",
                    "t_end": T,
                    "skipped": True,
                    "reason": f"{type(exc).__name__}: {exc}",
                }
            )
            continue
        t0 = time.perf_counter()
        out += reference_records(name, quick, ref, nm)
        for ename, a, why in adapters:
            if a is None:
                out.append(
                    {
                        "model": name,
                        "engine": ename,
                        "t_end": T,
                        "skipped": True,
                        "reason": f"engine adapter unavailable: {why}",
                    }
                )
            else:
                t_e = time.perf_counter()
                out += engine_records(name, quick, ref, nm, a)
                if log:  # a full ladder runs for minutes per engine: show where it is
                    log(f"work-precision {name} {ename}: {time.perf_counter() - t_e:.1f} s")
        if log:
            log(f"work-precision {name}: {time.perf_counter() - t0:.1f} s")
    return out
