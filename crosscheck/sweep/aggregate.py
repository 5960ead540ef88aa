"""The parent's side of a sweep: merging chunk results per model, then the summary (quantiles,
histograms, worst cases with the commands that reproduce them, faults, timing)."""

from __future__ import annotations

import shlex
from dataclasses import dataclass, field

import numpy as np

from crosscheck.checks import tolerances as C
from crosscheck.checks.instantaneous import rigid_answer, tolerance
from crosscheck.checks.perturb import perturbed
from crosscheck.checks.sampling import draw_sample
from crosscheck.sweep.config import (
    FAULTS_KEPT,
    HIST_HI,
    HIST_LO,
    HIST_STEP,
    QUANTILE_METHOD,
    QUANTILES,
    QUANTITY_ORDER,
    REFERENCE,
    SOFT_ERROR_REASON,
    Campaign,
)
from crosscheck.sweep.worker import base_model, cached_adapter

# the derivatives quantities (--derivatives) are stored as error over the tolerance derived at
# each sample (crosscheck.checks.derivatives.tolerances): judged against 1
DERIVATIVE_QUANTITIES = frozenset(q for q in QUANTITY_ORDER if q.startswith("d"))
DERIVED = C.Tolerance(
    1.0,
    "derivatives: each sample's error over the tolerance derived at that sample from what "
    "limits the comparison (crosscheck.checks.derivatives.tolerances, docs/tolerances.md)",
)


# ---- the campaign (runs in the parent) ------------------------------------------------------
@dataclass
class ModelAggregate:
    name: str
    formulation: str
    start: int
    n: int
    series: list  # [(engine, variant)] evaluated
    unsupported: dict  # {(engine, variant): reason}
    values: dict = field(default_factory=dict)
    soft: dict = field(default_factory=dict)
    skips: dict = field(default_factory=dict)
    faults: list = field(default_factory=list)
    chunk_faults: list = field(default_factory=list)
    completed: np.ndarray = None
    timing: dict = field(
        default_factory=lambda: {
            "draw_s": 0.0,
            "reference_s": 0.0,
            "reference_aux_s": 0.0,
            "samples": 0,
            "series": {},
        }
    )

    def __post_init__(self):
        self.completed = np.zeros(self.n, bool)

    def merge(self, res: dict) -> None:
        off, done = res["start"] - self.start, res["completed"]
        self.completed[off : off + done] = True
        for key, arr in res["values"].items():
            if key not in self.values:
                self.values[key] = np.full(self.n, np.nan)
            self.values[key][off : off + len(arr)] = arr
        self.soft.update(res["soft"])
        for key, reason in res["skips"].items():
            self.skips.setdefault(key, reason)
        self.faults += res["faults"]
        t = res["timing"]
        for k in ("draw_s", "reference_s", "reference_aux_s", "samples"):
            self.timing[k] += t[k]
        for sv, x in t["series"].items():
            acc = self.timing["series"].setdefault(sv, [0.0, 0.0, 0, 0])
            for j in range(4):
                acc[j] += x[j]


def completed_index_ranges(mask: np.ndarray, start: int) -> list[list[int]]:
    """Index ranges [a, b) where mask is True."""
    out, i, n = [], 0, len(mask)
    while i < n:
        if mask[i]:
            j = i
            while j < n and mask[j]:
                j += 1
            out.append([start + i, start + j])
            i = j
        else:
            i += 1
    return out


def _histogram(v: np.ndarray) -> dict:
    nb = round((HIST_HI - HIST_LO) / HIST_STEP)
    fin = v[np.isfinite(v)]
    pos = fin[fin > 0]
    lg = np.log10(pos)
    inside = lg[(lg >= HIST_LO) & (lg < HIST_HI)]
    counts = np.bincount(
        np.floor((inside - HIST_LO) / HIST_STEP).astype(int).clip(0, nb - 1), minlength=nb
    )
    return {
        "log10_lo": HIST_LO,
        "log10_hi": HIST_HI,
        "log10_step": HIST_STEP,
        "counts": counts.tolist(),
        "zero": int((fin == 0).sum()),
        "below": int((lg < HIST_LO).sum()),
        "above": int((lg >= HIST_HI).sum()),
        "nonfinite": int((~np.isfinite(v)).sum()),
    }


def _fmt_floats(x) -> str:
    return ",".join(repr(float(v)) for v in np.asarray(x, float).ravel())


def reproduce_commands(
    cfg: Campaign, model: str, formulation: str, engine: str | None, index: int, nm, t, q, u
) -> dict:
    """Command lines that reproduce one sample: the one-sample sweep (same numbers, bit for
    bit) and `crosscheck eval` of the reference at that case."""
    argv = [
        "crosscheck",
        "sweep",
        model,
        "--seed",
        str(cfg.seed),
        "--index",
        str(index),
        "--samples",
        "1",
        "--workers",
        "1",
    ]
    if engine and engine != REFERENCE:
        argv += ["--engines", engine]
        for p, rel in sorted(cfg.perturb.get(engine, {}).items()):
            argv += ["--perturb", f"{engine}:{p}={rel!r}"]
    if cfg.formulation:
        argv += ["--formulation", cfg.formulation]
    argv += ["--out", f"repro/{model}-{index}"]
    ev = ["crosscheck", "eval", model, "--formulation", formulation]
    for k, v in nm.params.items():
        ev += ["--set", f"{k}={float(v)!r}"]
    ev += [f"--q={_fmt_floats(q)}", f"--u={_fmt_floats(u)}", "--t", repr(float(t)), "--json"]
    return {"sweep": shlex.join(argv), "eval": shlex.join(ev)}


def campaign_meta(cfg: Campaign, aggs) -> dict:
    return {
        "seed": cfg.seed,
        "samples": cfg.samples,
        "index": cfg.index,
        "models": list(cfg.models),
        "engines": list(cfg.engines),
        "formulations": {n: a.formulation for n, a in aggs.items()},
        "perturb": cfg.perturb,
        "sampler": "crosscheck.checks.sampling.draw_instance (the property tests' generator): "
        "parameters x U(0.8, 1.25) (signed loads U(-1, 1) x max(1, |default|)), "
        "t ~ U(0, 2), initial state + N(0, 0.3) / N(0, 1) noise, projected",
        "seeding": "sample i of model M: numpy default_rng(sample_seed), sample_seed = "
        "SeedSequence([seed, crc32(M), i]).generate_state(1, uint32)[0]",
        "quantiles": {"levels": list(QUANTILES), "method": QUANTILE_METHOD},
        "metrics": {
            **C.METRICS,
            "relative_energy_error": "|(K + V)_engine - (K + V)_reference| / max(|K| + |V|, 1)",
        },
    }


def _group_faults(cfg: Campaign, name: str, agg, fault_groups: dict, fault_records: list) -> None:
    """One model's faults into their groups; the first FAULTS_KEPT of each kept with the
    command that reproduces it."""
    faults = sorted(
        agg.faults, key=lambda f: (f["index"], str(f["engine"]), str(f["variant"]), f["stage"])
    )
    for f in faults:
        key = (name, f["engine"], f["variant"], f["stage"], f["type"])
        g = fault_groups.setdefault(
            key,
            {
                "model": name,
                "engine": f["engine"],
                "variant": f["variant"],
                "stage": f["stage"],
                "type": f["type"],
                "count": 0,
                "first_reason": f["reason"],
            },
        )
        g["count"] += 1
        if g["count"] <= FAULTS_KEPT:
            f = dict(f)
            f["reproduce"] = _fault_command(cfg, name, f)
            fault_records.append(f)


def _quantity_record(
    cfg: Campaign, name: str, agg, e: str, v, qn: str, soft: bool, case
) -> tuple[dict, int | None]:
    """The results row of one model x engine x variant x quantity, and how many samples are
    outside its tolerance (None: no tolerance)."""
    if qn in DERIVATIVE_QUANTITIES:
        tol, metric = DERIVED, "error_over_derived_tolerance"
    else:
        tol, metric = tolerance(qn, soft, cached_adapter(e), name)
    row = {"model": name, "formulation": agg.formulation, "engine": e, "variant": v, "quantity": qn}
    if (e, v, qn) not in agg.values:
        return {**row, "skipped": agg.skips[(e, v, qn)], "count": 0}, None
    arr = agg.values[(e, v, qn)]
    idx = np.flatnonzero(~np.isnan(arr))
    vals = arr[idx]
    fin = np.isfinite(vals)
    outside = None
    if tol is not None:
        outside = int(np.sum(~(vals <= tol.value)))
    order = np.lexsort((idx, -np.where(fin, vals, np.inf)))[: cfg.worst]
    worst = []
    for j in order:
        i = int(cfg.index + idx[j])
        s, nm, t, q, u = case(i)
        w = {
            "index": i,
            "sample_seed": s,
            "error": float(vals[j]),
            "parameters": nm.params,
            "t": t,
            "q": np.asarray(q).tolist(),
            "u": np.asarray(u).tolist(),
            "reproduce": reproduce_commands(cfg, name, agg.formulation, e, i, nm, t, q, u),
        }
        if cfg.perturb.get(e):
            w["engine_parameters"] = perturbed(name, nm.params, cfg.perturb[e])
        worst.append(w)
    rec = {
        **row,
        "metric": metric,
        "tolerance": None if tol is None else tol.value,
        "reason": SOFT_ERROR_REASON if tol is None else tol.reason,
        "count": len(vals),
        "nonfinite": int(np.sum(~fin)),
        "outside_tolerance": outside,
        "max": float(vals.max()) if len(vals) else None,
        "mean": float(vals[fin].mean()) if fin.any() else None,
        "quantiles": (
            {
                str(p): float(x)
                for p, x in zip(
                    QUANTILES, np.quantile(vals, QUANTILES, method=QUANTILE_METHOD), strict=True
                )
            }
            if len(vals)
            else {}
        ),
        "histogram": _histogram(vals),
        "worst": worst,
    }
    if soft and qn in ("accelerations", "multipliers"):
        rec["answer"] = rigid_answer(e)
    return rec, outside


def _redrawer(base, seed):
    """Sample i of a model, drawn again on first use (the faults' reproduction cases)."""
    redrawn = {}

    def case(i):
        if i not in redrawn:
            redrawn[i] = draw_sample(base, seed, i)
        return redrawn[i]

    return case


def summarize(cfg: Campaign, aggs, stopped, done) -> dict:
    results, series_rows, fault_groups, fault_records, chunk_faults = [], [], {}, [], []
    outside_total = 0
    for name, agg in aggs.items():
        base = base_model(name, cfg.formulation)
        case = _redrawer(base, cfg.seed)

        _group_faults(cfg, name, agg, fault_groups, fault_records)
        chunk_faults += agg.chunk_faults
        for (e, v), reason in agg.unsupported.items():
            series_rows.append(
                {
                    "model": name,
                    "engine": e,
                    "variant": v,
                    "unsupported": reason,
                    "samples": done[name],
                    "evaluated": 0,
                    "faults": 0,
                }
            )
        for e, v in agg.series:
            n_faults = sum(1 for f in agg.faults if f["engine"] == e and f["variant"] == v)
            keys = [k for k in QUANTITY_ORDER if (e, v, k) in agg.values or (e, v, k) in agg.skips]
            evaluated = 0
            for qn in keys:
                if (e, v, qn) in agg.values:
                    evaluated = int(np.sum(~np.isnan(agg.values[(e, v, qn)])))
                    break
            series_rows.append(
                {
                    "model": name,
                    "engine": e,
                    "variant": v,
                    "unsupported": None,
                    "samples": done[name],
                    "evaluated": evaluated,
                    "faults": n_faults,
                }
            )
            soft = bool(agg.soft.get((e, v)))
            for qn in keys:
                rec, outside = _quantity_record(cfg, name, agg, e, v, qn, soft, case)
                if outside is not None:
                    outside_total += outside
                results.append(rec)
    n_faults = sum(g["count"] for g in fault_groups.values())
    complete = stopped is None and all(d == cfg.samples for d in done.values())
    status = {
        "complete": complete,
        "stopped": stopped,
        "requested": {n: cfg.samples for n in aggs},
        "completed": done,
        "completed_ranges": {
            n: completed_index_ranges(a.completed, cfg.index) for n, a in aggs.items()
        },
        "outside_tolerance": outside_total,
        "faults": n_faults + len(chunk_faults),
    }
    # an incomplete campaign never reads as passed: what it did not run, it did not check
    clean = outside_total == 0 and n_faults == 0 and not chunk_faults
    status["verdict"] = "failed" if not clean else "passed" if complete else "incomplete"
    status["passed"] = status["verdict"] == "passed"
    return {
        "status": status,
        "series": series_rows,
        "results": results,
        "faults": {
            "groups": list(fault_groups.values()),
            "records": fault_records,
            "kept_per_group": FAULTS_KEPT,
            "chunks": chunk_faults,
        },
    }


def _fault_command(cfg: Campaign, model: str, f: dict) -> str:
    argv = [
        "crosscheck",
        "sweep",
        model,
        "--seed",
        str(cfg.seed),
        "--index",
        str(f["index"]),
        "--samples",
        "1",
        "--workers",
        "1",
    ]
    if f["engine"] != REFERENCE:
        argv += ["--engines", f["engine"]]
        for p, rel in sorted(cfg.perturb.get(f["engine"], {}).items()):
            argv += ["--perturb", f"{f['engine']}:{p}={rel!r}"]
    if cfg.formulation:
        argv += ["--formulation", cfg.formulation]
    return shlex.join([*argv, "--out", f"repro/{model}-{f['index']}"])


def timing_summary(aggs, wall: float) -> dict:
    """Where the time went (not part of the deterministic results)."""
    rows = []
    for name, a in aggs.items():
        n = max(a.timing["samples"], 1)
        rows.append(
            {
                "model": name,
                "engine": REFERENCE,
                "variant": None,
                "samples": a.timing["samples"],
                "draw_us_per_sample": 1e6 * a.timing["draw_s"] / n,
                "reference_batched_us_per_sample": 1e6 * a.timing["reference_s"] / n,
                "reference_mass_matrix_energy_us_per_sample": 1e6 * a.timing["reference_aux_s"] / n,
            }
        )
        for (e, v), (b, ev, tried, c) in a.timing["series"].items():
            rows.append(
                {
                    "model": name,
                    "engine": e,
                    "variant": v,
                    "builds": tried,
                    "evaluated": c,
                    "build_s": b,
                    "evaluate_s": ev,
                    "build_us_per_sample": 1e6 * b / max(tried, 1),
                    "evaluate_us_per_sample": 1e6 * ev / max(c, 1),
                    "build_fraction": b / (b + ev) if b + ev > 0 else None,
                }
            )
    return {
        "wall_s": wall,
        "per_series": rows,
        "note": "summed over workers (CPU-seconds of each stage), wall_s is the campaign's",
    }
