"""The suite's speed targets, as ratios of figures measured in one `crosscheck bench` run: the
reference's work-precision against the soft fixed-step engine's (MuJoCo), and its forward
dynamics against the exact engine's native call (Pinocchio), single-state and batched."""

from __future__ import annotations

import cProfile
import io
import pstats
import statistics

import numpy as np

from crosscheck.bench.workprecision import QUICK_MODELS, adapter_or_reason, horizon
from crosscheck.engines.registry import available_engines, get_engine
from reference import NumericModel, models
from reference.integrate.driver import simulate

TARGET_ERROR, TARGET_RESIDUAL, TARGET_MUJOCO_ERROR = 1e-8, 1e-10, 1e-4
TARGET_BATCH_SPEEDUP = 10.0
# the bar for target 1: the reference in at most a quarter of MuJoCo's time (ratio >= 4)
TARGET_WP_SPEEDUP = 4.0


def _best(records, **cond):
    """The fastest record satisfying cond (callables on the record) or None."""
    ok = [r for r in records if r.get("wall_s") is not None and all(c(r) for c in cond.values())]
    return min(ok, key=lambda r: r["wall_s"]) if ok else None


def _brief(r):
    if r is None:
        return None
    return {
        k: r.get(k)
        for k in (
            "engine",
            "method",
            "integrator",
            "setting",
            "wall_s",
            "error",
            "residual",
            "nfev",
            "solref",
            "stepper",
        )
    }


def _profile_run(fn, top=8) -> list[str]:
    """cProfile of fn(): the top functions by internal time (for a missed target)."""
    pr = cProfile.Profile()
    pr.enable()
    fn()
    pr.disable()
    s = io.StringIO()
    pstats.Stats(pr, stream=s).sort_stats("tottime").print_stats(top)
    return [ln.rstrip() for ln in s.getvalue().splitlines() if ln.strip()][-top - 1 :]


def targets(
    forward: list[dict], wp: list[dict], model: str = "slider_crank", quick: bool = False
) -> dict:
    """The three targets, as ratios of figures measured in this run. The forward targets
    time the reference and Pinocchio back to back (forward_pair) on every model with a
    Pinocchio forward record (quick: QUICK_MODELS only)."""
    out = {}
    # 1. reference to 1e-8 with residual 1e-10 vs MuJoCo to 1e-4 (or at its most accurate)
    out["slider_crank_work_precision"] = work_precision_target(
        [r for r in wp if r.get("model") == model], model
    )

    # 2./3. forward dynamics: single state vs Pinocchio, batched vs Pinocchio
    e = _target_engine(exact=True)  # the exact engine of targets 2 and 3 (Pinocchio)
    constrained = sorted(
        {
            r["model"]
            for r in forward
            if r.get("engine") == e
            and r.get("us_per_state") is not None
            and (not quick or r["model"] in QUICK_MODELS)
        }
    )
    single, batched = {}, {}
    for name in constrained:
        row_single, row_batched = _forward_rows(forward, name, e)
        if row_single:
            single[name] = row_single
        if row_batched:
            batched[name] = row_batched
    out[f"forward_single_vs_{e}"] = {
        "statement": "single-state reference forward dynamics no slower than Pinocchio's "
        "constrained call on the same model: ratio = pin / ref >= 1 for the checked "
        "call NumericModel.forward (met), ratio_raw for the fast forward_fast "
        "the integrators use (met_raw); pinocchio_call_us is the native call alone "
        "(for 'kkt' models J and gamma are evaluated outside it); reference and "
        "Pinocchio are timed back to back in interleaved rounds",
        "models": single,
        "met": _all_met(single),
        "met_raw": _all_met({k: {**v, "met": v["met_raw"]} for k, v in single.items()}),
    }
    out[f"forward_batched_vs_{e}"] = {
        "statement": f"batched reference forward over 10^4 states at least "
        f"{TARGET_BATCH_SPEEDUP:g}x faster per state than Pinocchio's call",
        "models": batched,
        "met": _all_met(batched),
    }
    return out


def _us(forward: list[dict], name: str, engine, path: str):
    """The forward record's median microseconds per state, or None."""
    for r in forward:
        if (
            r.get("model") == name
            and r.get("engine") == engine
            and r.get("path") == path
            and r.get("us_per_state") is not None
        ):
            return r["us_per_state"]
    return None


def _forward_rows(forward: list[dict], name: str, e: str) -> tuple[dict | None, dict | None]:
    """One model's single-state and batched rows against engine e's call."""
    # the forward records time the adapter's forward() (engine call + mapping + the
    # adapter's own residual checks); the fair figure is the engine call alone
    adapter_us = _us(forward, name, e, f"engine:{e}")
    pair = forward_pair(name, e)
    solver = pair.get(f"{e}_solver")
    pin_us = pair.get(f"{e}_call_us") or adapter_us
    ref_us = pair.get("reference_us") or _us(forward, name, "reference", "single")
    raw_us = pair.get("reference_raw_us") or _us(forward, name, "reference", "single-raw")
    bat_us = _us(forward, name, "reference", "batched")
    # the target is about Pinocchio's *constrained* call; where Pinocchio models the system
    # as a minimal tree (solver aba) the row is informative and not counted
    counted = bool(pair.get("constrained_solve"))
    single = batched = None
    if pin_us and ref_us:
        single = {
            f"{e}_call_us": pin_us,
            f"{e}_solver": solver,
            f"{e}_timing": pair.get(f"{e}_timing"),
            f"{e}_adapter_forward_us": adapter_us,
            "reference_us": ref_us,
            "reference_raw_us": raw_us,
            "ratio": pin_us / ref_us,
            "ratio_raw": pin_us / raw_us if raw_us else None,
            "counted": counted,
            "met": pin_us / ref_us >= 1.0,
            "met_raw": bool(raw_us) and pin_us / raw_us >= 1.0,
        }
        if counted and pin_us < ref_us:
            single["what_bounds_it"] = pair.get("bound")
    if pin_us and bat_us:
        batched = {
            f"{e}_call_us": pin_us,
            f"{e}_solver": solver,
            "reference_batched_us": bat_us,
            "ratio": pin_us / bat_us,
            "counted": counted,
            "met": pin_us / bat_us >= TARGET_BATCH_SPEEDUP,
        }
    return single, batched


def work_precision_target(recs: list[dict], model: str) -> dict:
    """Target 1: the reference's fastest run with error <= TARGET_ERROR (above the reference's
    own accuracy) and residual <= TARGET_RESIDUAL against the soft engine's fastest run with
    error <= TARGET_MUJOCO_ERROR, over every setting it was run at (its default constraint
    stiffness and the stiffer ones). Where no soft run reaches that error, the comparison is
    against its most accurate run: met when the reference is faster than that run too (it is
    then faster and more accurate), ratio = that run's wall / the reference's."""
    soft = _target_engine(exact=False) or "soft_engine"  # target 1's engine (MuJoCo)
    ref_best = _best(
        [r for r in recs if r["engine"] == "reference"],
        e=lambda r: r.get("error") is not None and r["error"] <= TARGET_ERROR,
        c=lambda r: r.get("residual") is not None and r["residual"] <= TARGET_RESIDUAL,
    )
    mj = [
        r
        for r in recs
        if r["engine"] == soft
        and r.get("wall_s") is not None
        and r.get("error") is not None
        and not r.get("flagged")
    ]
    mj_best = _best(mj, e=lambda r: r["error"] <= TARGET_MUJOCO_ERROR)
    t1 = {
        "model": model,
        "t_end": horizon(model),
        "statement": f"reference reaches error <= {TARGET_ERROR:g} with residual <= "
        f"{TARGET_RESIDUAL:g} in less wall time than MuJoCo needs for error <= "
        f"{TARGET_MUJOCO_ERROR:g} (at any of its settings, the stiffer soft "
        f"constraints included), or than its most accurate run where none gets "
        f"there",
        "reference": _brief(ref_best),
        soft: _brief(mj_best),
        f"{soft}_settings": sorted({str(r.get("method")) for r in mj}),
    }
    if ref_best is None:
        t1.update(
            met=False,
            ratio=None,
            reason="no reference run on the ladder met both the error and the residual",
        )
        return t1
    if (
        ref_best.get("reference_accuracy") is not None
        and ref_best["reference_accuracy"] > TARGET_ERROR
    ):
        t1.update(
            met=None,
            ratio=None,
            reason=f"the reference solution's accuracy "
            f"{ref_best['reference_accuracy']:.1e} does not resolve {TARGET_ERROR:g}",
        )
        return t1
    if not mj:
        t1.update(met=None, ratio=None, reason="no MuJoCo records in this run")
        return t1
    if mj_best is not None:
        ratio = mj_best["wall_s"] / ref_best["wall_s"]
        t1.update(
            met=ratio > 1.0,
            ratio=ratio,
            compared_with=f"{soft}'s fastest run with error <= {TARGET_MUJOCO_ERROR:g}",
            **_speedup(ratio),
        )
        return t1
    closest = min(mj, key=lambda r: r["error"])
    ratio = closest["wall_s"] / ref_best["wall_s"]
    t1.update(
        met=ratio > 1.0,
        ratio=ratio,
        **{f"{soft}_closest": _brief(closest)},
        compared_with=f"{soft}'s most accurate run (error {closest['error']:.1e}: no run "
        f"reached {TARGET_MUJOCO_ERROR:g})",
        **_speedup(ratio),
    )
    return t1


def _speedup(ratio: float) -> dict:
    """The stricter bar on the same ratio: at most a quarter of the engine's time."""
    return {
        "speedup_target": TARGET_WP_SPEEDUP,
        "met_speedup": ratio >= TARGET_WP_SPEEDUP,
    }


def _all_met(rows: dict):
    counted = [v["met"] for v in rows.values() if v.get("counted")]
    return all(counted) if counted else None


def _target_engine(exact: bool) -> str | None:
    """The first available engine (registry order) whose answers are exact (or soft)."""
    for e in available_engines():
        if get_engine(e).capabilities.exact == exact:
            return e
    return None


# Where the reference's single-state forward call spends its time, per backend (the record's
# explanation; measured in benchmarks/reference_speed.md)
FORWARD_COST = {
    "c": "the generated KKT solve compiled to C: one METH_FASTCALL-style call per state "
    "(argument checks in C, about 0.1-0.2 us) plus the straight-line arithmetic; the checked "
    "call adds the output arrays and the Forward record, built in the same C call "
    "(benchmarks/reference_speed.md)",
    "python": "the generated forward is straight-line Python on floats: its cost is the "
    "interpreter's ~20-40 ns per arithmetic operation times the operation count of the "
    "generated KKT solve; the checked call adds state validation and numpy conversion of the "
    "outputs",
}


def forward_pair(name: str, engine: str | None = None, rounds: int = 3) -> dict:
    """Reference forward (checked and raw) and Pinocchio's engine call timed back to back, in
    interleaved rounds (medians), at the model's initial state: a ratio from the same moment of
    this noisy machine. Also what bounds the reference: the straight-line Python it runs."""
    from crosscheck.bench.timing import per_call_seconds

    engine = engine or _target_engine(exact=True)
    a, _why = adapter_or_reason(engine) if engine else (None, "no exact engine")
    out: dict = {}
    try:
        model = models.get(name)
        nm = NumericModel(model)
        q = np.asarray(model.initial_q, float)
        u = np.asarray(model.initial_u, float)
        # each backend's native inputs (as bench's single-raw): float64 vectors for the
        # kernels, lists for the generated Python
        ql, ul = (q, u) if nm.backend != "python" else (q.tolist(), u.tolist())
        em = a.build(name, None) if a is not None else None
        # Pinocchio's native call (the adapter's timing hook: aba / forwardDynamics(J, gamma) /
        # constraintDynamics with tau and, for 'kkt', the rows J, gamma evaluated beforehand),
        # else the adapter's _solve (the call plus building its inputs and copying outputs)
        call, how = None, None
        if em is not None:
            call, how = em.timed_forward(q, u), "native call (adapter.timed_forward)"
        ref, raw, pin = [], [], []
        for _ in range(rounds):
            ref.append(per_call_seconds(lambda: nm.forward(q, u), repeats=3)["median"])
            raw.append(per_call_seconds(lambda: nm.forward_fast(ql, ul, 0.0), repeats=3)["median"])
            if call is not None:
                pin.append(per_call_seconds(call, repeats=3)["median"])
        out.update(
            reference_us=statistics.median(ref) * 1e6,
            reference_raw_us=statistics.median(raw) * 1e6,
            constrained_solve=em is not None and em.constrained_solve,
        )
        out.update(
            {
                f"{engine}_call_us": statistics.median(pin) * 1e6 if pin else None,
                f"{engine}_timing": how,
                f"{engine}_solver": em.solver if em else None,
            }
        )
        src = nm.source
        body = src[src.index("def forward") : src.index("def matrices")]
        lines = [ln for ln in body.splitlines()[1:] if ln.strip()]
        ops = sum(
            ln.count("*")
            + ln.count("+")
            + ln.count("-")
            + ln.count("/")
            + ln.count("sqrt")
            + ln.count("sin")
            + ln.count("cos")
            for ln in lines
        )
        out["bound"] = {
            "generated_forward_lines": len(lines),
            "generated_forward_operations": ops,
            "ns_per_operation": out["reference_raw_us"] * 1e3 / max(ops, 1),
            "validation_overhead_us": out["reference_us"] - out["reference_raw_us"],
            "backend": nm.backend,
            "explanation": FORWARD_COST[nm.backend]
            + ". Pinocchio's call is C++ whose cost grows with the tree, not with the "
            "expression size.",
        }
    except Exception as exc:
        out["error"] = f"{type(exc).__name__}: {exc}"
    return out


def profile_for_missed(tg: dict, model: str = "slider_crank") -> None:
    """Attach a cProfile of the winning reference run where target 1 was missed."""
    t1 = tg.get("slider_crank_work_precision", {})
    if t1.get("met") is False and t1.get("reference"):
        r = t1["reference"]
        nm = NumericModel(models.get(model))
        m = nm.model
        t1["profile"] = _profile_run(
            lambda: simulate(
                nm,
                m.initial_q,
                m.initial_u,
                horizon(model),
                r["method"],
                rtol=r["setting"],
                atol=r["setting"],
            )
        )
