"""What skipping saves: each figure compares like with like, measured in this run.

- no_kkt_without_constraints: one model's compiled forward with its constraint rows (the KKT
  solve: Cholesky of M, Schur complement A M^-1 A^T, back-substitution) against the same model
  with the rows removed (the generator then emits the Cholesky solve of M alone), called on the
  same states (the constrained model's own trajectory): the same coordinates, M and f, so the
  difference is the skipped solve alone. The per-run figure scales it by the RHS calls of the
  constrained run.
- energy_bookkeeping: the same run with the work integral carried as a state, or not.
- derivation_cache: NumericModel construction with an empty cache (derive, simplify, generate,
  compile) in a fresh process, against a fresh process that finds the cache, and against
  repeated constructions in this process.
- projection_fsal_refresh: the same projection run refreshing the FSAL derivative or not.
- time_split: where the time of one reference run goes.
Timings alternate between the compared callables (A B A B ...), so load changes on this shared
machine hit both alike; ratios of medians and of minima (the minimum is the least disturbed).
"""

from __future__ import annotations

import cProfile
import dataclasses
import json
import os
import pstats
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

from crosscheck.bench.workprecision import horizon
from reference import NumericModel, models
from reference.integrate.driver import simulate
from reference.minimal import reference_final_state

# the models of no_kkt_without_constraints: one and two constraint rows
KKT_MODELS = ("pendulum_xy", "slider_crank")
# states of the constrained trajectory the forward calls are timed on, and the passes over
# them per timed sample (~5000 calls, ~10-20 ms: a per-call difference of ~0.2 us against a
# ~2-4 us call was lost in the noise of a single 200-call pass, even in the minimum)
KKT_STATES = 200
KKT_PASSES = 25
# a cold construction derives, simplifies, generates and compiles: bounded per model
COLD_BOUND_S = 600.0


def _interleaved(fns: dict, rounds: int) -> dict:
    """Time several callables in alternating rounds (A B C A B C ...), so a load change on this
    shared machine hits all of them alike. Returns label -> {median_s, min_s, result}."""
    walls: dict = {k: [] for k in fns}
    last = {}
    for _ in range(rounds):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            last[k] = fn()
            walls[k].append(time.perf_counter() - t0)
    return {
        k: {"median_s": statistics.median(w), "min_s": min(w), "result": last[k]}
        for k, w in walls.items()
    }


def _ratio(a: dict, b: dict) -> dict:
    return {"median": a["median_s"] / b["median_s"], "min": a["min_s"] / b["min_s"]}


def unconstrained(model):
    """The same model without its constraint rows (same coordinates, speeds, M and f)."""
    return dataclasses.replace(
        model,
        name=f"{model.name}_rows_removed",
        configuration_constraints=(),
        motion_constraints=(),
        constraint_names=(),
        formulation_dependent_rows=(),
        state_sampler=None,
        energy_conserved=False,
    )


def _forward_loop(nm: NumericModel, Q, U):
    """A callable making the compiled forward call at every state (the backend's inputs)."""
    raw = nm.forward_fast
    if nm.backend == "python":
        Q, U = Q.tolist(), U.tolist()

    def loop():
        for _ in range(KKT_PASSES):
            for q, u in zip(Q, U, strict=True):
                raw(q, u, 0.0)

    return loop


def kkt_saving(name: str, rounds: int) -> dict:
    """One model with its rows vs without them, on the constrained run's states (see above)."""
    model = models.get(name)
    with_rows, without = NumericModel(model), NumericModel(unconstrained(model))
    T = horizon(name)
    tr = simulate(
        with_rows,
        model.initial_q,
        model.initial_u,
        T,
        "projection",
        rtol=1e-10,
        atol=1e-10,
        t_eval=np.linspace(0.0, T, KKT_STATES),
        energy="none",
    )
    Q, U = np.asarray(tr.q, float), np.asarray(tr.u, float)
    timed = _interleaved(
        {"kkt": _forward_loop(with_rows, Q, U), "rows_removed": _forward_loop(without, Q, U)},
        rounds,
    )
    k, r = timed["kkt"], timed["rows_removed"]
    calls = len(Q) * KKT_PASSES
    saved_us = (k["min_s"] - r["min_s"]) / calls * 1e6
    run = _interleaved(
        {
            "run": lambda: simulate(
                with_rows,
                model.initial_q,
                model.initial_u,
                T,
                "projection",
                rtol=1e-10,
                atol=1e-10,
                energy="none",
            )
        },
        max(3, rounds // 3),
    )["run"]
    return {
        "constraint_rows": with_rows.m,
        "coordinates": with_rows.nq,
        "states": len(Q),
        "calls_per_sample": calls,
        "forward_us": {
            "kkt": k["median_s"] / calls * 1e6,
            "rows_removed": r["median_s"] / calls * 1e6,
            "kkt_min": k["min_s"] / calls * 1e6,
            "rows_removed_min": r["min_s"] / calls * 1e6,
        },
        "ratio_kkt_over_rows_removed": _ratio(k, r),
        "saved_us_per_call_min": saved_us,
        "projection_run": {
            "nfev": run["result"].nfev,
            "wall_s": run["median_s"],
            "wall_s_min": run["min_s"],
            "saved_share_min": saved_us * 1e-6 * run["result"].nfev / run["min_s"],
        },
    }


def no_kkt_without_constraints(rounds: int) -> dict:
    return {
        "what": "one model's compiled forward with its constraint rows (KKT solve: Schur "
        "complement A M^-1 A^T and back-substitution) vs the same model with the rows "
        f"removed (Cholesky of M alone), both called on the same {KKT_STATES} states "
        f"({KKT_PASSES} passes per sample) "
        "of the constrained model's projection run (rtol 1e-10): same coordinates, M "
        "and f, so the difference is the skipped solve; saved_share_min = the saving "
        "per call x the RHS calls of that run / its wall time",
        "models": {name: kkt_saving(name, rounds) for name in KKT_MODELS},
        "note": "a model without constraint rows gets the Cholesky solve of M alone from the "
        "generator: this is what it saves against carrying the KKT solve",
    }


def energy_bookkeeping(rounds: int) -> dict:
    sc = NumericModel(models.get("slider_crank"))
    T = horizon("slider_crank")
    q0, u0 = sc.model.initial_q, sc.model.initial_u
    timed = _interleaved(
        {
            mode: (
                lambda mode=mode: simulate(
                    sc, q0, u0, T, "projection", rtol=1e-10, atol=1e-10, energy=mode
                )
            )
            for mode in ("work", "none")
        },
        rounds,
    )
    tw, tn = timed["work"]["result"], timed["none"]["result"]
    return {
        "what": "slider_crank, projection, rtol 1e-10: work integral W carried as an ODE state "
        "(energy='work') vs none; W is excluded from error control, so the steps are "
        "the same up to the rounding of the error norm",
        "work": {
            "wall_s": timed["work"]["median_s"],
            "wall_s_min": timed["work"]["min_s"],
            "nfev": tw.nfev,
            "nsteps": tw.nsteps,
        },
        "none": {
            "wall_s": timed["none"]["median_s"],
            "wall_s_min": timed["none"]["min_s"],
            "nfev": tn.nfev,
            "nsteps": tn.nsteps,
        },
        "max_final_state_difference": float(np.max(np.abs(tw.final_state - tn.final_state))),
        "same_step_count": tw.nsteps == tn.nsteps,
        "ratio_wall_work_over_none": _ratio(timed["work"], timed["none"]),
        "note": "the power comes from the compiled energy function, which also returns dE/dq "
        "and dE/du for NumericModel.power_balance: a power-only function would cut "
        "most of the cost",
    }


_CONSTRUCT = """
import json, sys, time
from reference import NumericModel, models
model = models.get(sys.argv[1])
t0 = time.perf_counter()
NumericModel(model)
print(json.dumps(time.perf_counter() - t0))
"""


def _fresh_process_construction(name: str, cache: str) -> float:
    """Seconds of NumericModel(model) in a new interpreter using the cache directory `cache`
    (the Model object is built before the clock starts, as in this process)."""
    # the Python backend: the derivation cache's saving alone (the C build and its own cache
    # are a separate saving, timed in the bench's "compiled" section)
    env = {**os.environ, "CROSSCHECK_CACHE_DIR": cache, "CROSSCHECK_BACKEND": "python"}
    r = subprocess.run(
        [sys.executable, "-c", _CONSTRUCT, name],
        env=env,
        capture_output=True,
        text=True,
        timeout=COLD_BOUND_S,
        check=True,
    )
    return float(json.loads(r.stdout.strip().splitlines()[-1]))


def derivation_cache(quick: bool, rounds: int) -> dict:
    # quick: one model (two fresh processes cost ~3 s of imports each, and the slider-crank's
    # cold derivation ~5 s)
    names = ("pendulum_xy",) if quick else ("pendulum_xy", "slider_crank", "slider_crank_split")
    out = {}
    old = {k: os.environ.get(k) for k in ("CROSSCHECK_CACHE_DIR", "CROSSCHECK_BACKEND")}
    try:
        with tempfile.TemporaryDirectory(prefix="crosscheck-cache-") as tmp:
            for name in names:
                cold = _fresh_process_construction(name, tmp)
                warm_fresh = _fresh_process_construction(name, tmp)
                os.environ.update(CROSSCHECK_CACHE_DIR=tmp, CROSSCHECK_BACKEND="python")
                model = models.get(name)
                w = _interleaved({"warm": lambda model=model: NumericModel(model)}, rounds)["warm"]
                out[name] = {
                    "cold_s": cold,
                    "warm_fresh_process_s": warm_fresh,
                    "warm_s": w["median_s"],
                    "warm_s_min": w["min_s"],
                    "ratio_cold_over_warm_fresh_process": cold / warm_fresh,
                    "ratio_cold_over_warm": cold / w["median_s"],
                }
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return {
        "what": "NumericModel construction on the Python backend with an empty "
        "CROSSCHECK_CACHE_DIR (derive, simplify, generate code) in a fresh process "
        "(cold_s), in a second "
        "fresh process that finds the cache (warm_fresh_process_s: the like-for-like "
        "figure), and repeated in this process (warm_s: also skips the imports and "
        "sympy's first-use costs); the Model object is built before the clock starts",
        "backend": "python",
        "models": out,
    }


def projection_fsal_refresh(rounds: int) -> dict:
    sc = NumericModel(models.get("slider_crank"))
    T = horizon("slider_crank")
    q0, u0 = sc.model.initial_q, sc.model.initial_u
    ref = reference_final_state("slider_crank", T)
    timed = _interleaved(
        {
            key: (
                lambda refresh=refresh: simulate(
                    sc,
                    q0,
                    u0,
                    T,
                    "projection",
                    rtol=1e-10,
                    atol=1e-10,
                    energy="none",
                    refresh=refresh,
                )
            )
            for key, refresh in (("refresh", True), ("reuse", False))
        },
        rounds,
    )
    pr = {}
    for key, v in timed.items():
        tr = v["result"]
        pr[key] = {
            "wall_s": v["median_s"],
            "wall_s_min": v["min_s"],
            "nfev": tr.nfev,
            "nsteps": tr.nsteps,
            "error": float(np.max(np.abs(tr.final_state - ref.state))),
        }
    return {
        "what": "slider_crank, DOP853 + projection, rtol 1e-10: solver.f recomputed at the "
        "projected point (one RHS call per step) vs kept from the unprojected point",
        **pr,
        "ratio_wall_refresh_over_reuse": _ratio(timed["refresh"], timed["reuse"]),
    }


def skip_savings(quick: bool = False) -> dict:
    """Measured savings of what a scene does not need (see the module docstring)."""
    rounds = 5 if quick else 9
    sc = NumericModel(models.get("slider_crank"))
    return {
        "no_kkt_without_constraints": no_kkt_without_constraints(rounds),
        "energy_bookkeeping": energy_bookkeeping(rounds),
        "derivation_cache": derivation_cache(quick, rounds),
        "projection_fsal_refresh": projection_fsal_refresh(rounds),
        "time_split": time_split(sc, horizon("slider_crank")),
    }


def time_split(nm: NumericModel, T: float, method: str = "projection", tol: float = 1e-10):
    """cProfile of one run: the share of the model's compiled code vs scipy's step machinery."""
    pr = cProfile.Profile()
    m = nm.model
    pr.enable()
    tr = simulate(nm, m.initial_q, m.initial_u, T, method, rtol=tol, atol=tol, energy="none")
    pr.disable()
    st = pstats.Stats(pr)
    total = st.total_tt  # type: ignore[attr-defined]
    from reference.backends.codegen import cache_dir

    gen_dir = os.path.realpath(str(cache_dir()))
    compiled = sum(
        v[2]
        for k, v in st.stats.items()  # type: ignore[attr-defined]
        if os.path.dirname(os.path.realpath(k[0])) == gen_dir
    )
    top = sorted(st.stats.items(), key=lambda kv: -kv[1][2])[:8]  # type: ignore[attr-defined]
    return {
        "what": f"cProfile of {nm.model.name} {method} rtol {tol:g} over {T:g} s "
        f"({tr.nfev} RHS calls, {tr.nsteps} steps; profiling inflates absolute "
        f"times, the split is what matters)",
        "profiled_total_s": total,
        "compiled_model_code_s": compiled,
        "compiled_share": compiled / total if total else None,
        "top_tottime": [
            f"{v[2] * 1e3:8.2f} ms {k[2]} ({os.path.basename(k[0])}:{k[1]})" for k, v in top
        ],
    }
