"""The regression gate: compare a fresh results.json (and bench.json) with a committed baseline.

    crosscheck gate --baseline reports/baseline.json --results out/results.json [--bench FILE]
                    [--factor F] [--floor X] [--timing-band B] [--update]

Exit 0 when nothing regressed, 1 with the list of regressions, 2 on usage errors (missing file,
bad JSON, a file that is not results/bench/baseline data) with one line.

Records are matched by (model, formulation, engine, check, quantity). A regression is
- a record of the baseline missing from the results (a check that stopped being run);
- a check that passed in the baseline and now fails, or is now skipped (coverage lost);
- a record new to the results that fails (failing checks enter the baseline only by --update);
- a record new to the results at all, unless --accept-new (then listed as accepted): a gate
  that compared nothing must not pass (a baseline of one model against the whole suite);
- an accuracy figure (the record's error; with --bench, a work-precision row's error, residual
  or energy drift) worse than FACTOR times its baseline value, both first raised to FLOOR;
- with --bench, a forward timing that became slower than TIMING_BAND times its baseline, where
  each timing is a ratio to another path timed in the same bench run (never an absolute time).
Checks failing in the baseline and still failing are known failures: listed, not regressions.
`--update` takes new records (and everything else) into the baseline.

`--update` rewrites the baseline from the results (and bench) deliberately, printing what
changed; it exits 0. The baseline keeps the records, the timing ratios and the work-precision
rows, not the trajectories ("series") or absolute timings.
"""

from __future__ import annotations

import math

from crosscheck.report.inputs import ReportInputError, check_results, load_json

# An accuracy figure may grow by this factor before it is a regression. The figures are worst
# cases over a handful of states or a tolerance ladder; a real defect (a wrong sign, a missing
# term, a lost stabilisation) moves them by orders of magnitude, while a legitimate change of
# BLAS kernel, compiler or state moves them by a small factor. 10x separates the two.
FACTOR = 10.0
# Errors are scaled (max |difference| / max(|reference|, 1)), so this floor is in units of the
# quantity's own size. Below ~1e-13 (about 450 ulp, eps = 2.2e-16) a figure is round-off of the
# KKT solves: reordering the same sums (another BLAS kernel, CPU SIMD width or library version)
# changes it by 10-100x without any change of method, so values below the floor count as equal.
ROUND_OFF_FLOOR = 1e-13
# Timing ratios measured in one run still move with machine load: the same setting's medians vary
# by 1.3-3x between runs on the 2-core shared machines (crosscheck/bench/timing.py,
# docs/tolerances.md), and a ratio combines two such timings. A 5x slowdown is beyond that noise
# and is what a real loss looks like (falling off the compiled path costs 10-100x).
TIMING_BAND = 5.0

KEY_FIELDS = ("model", "formulation", "engine", "check", "quantity")
WP_KEY_FIELDS = ("model", "engine", "method", "integrator", "setting")
WP_FIGURES = ("error", "residual", "energy_drift")
# the timing a path is divided by, in order of preference: the engines' constrained forward
# calls (the ratio the report shows), else the plain lambdify+solve baseline of the same run
BASELINE_ANCHOR = "baseline-lambdify-solve"


def timing_anchors() -> tuple[str, ...]:
    """Every available engine's forward path in the registry's order, then the baseline."""
    from crosscheck.engines.registry import available_engines

    return (*tuple(f"engine:{e}" for e in available_engines()), BASELINE_ANCHOR)


class GateInputError(ReportInputError):
    """A gate input is missing or malformed (one line, exit status 2)."""


# ---- matching -----------------------------------------------------------------------------
def record_key(r: dict) -> str:
    """model/formulation/engine[variant]/check/quantity: an engine with several models of one
    reference model (Example 4 as free bodies and as a ball-joint tree) has one record each."""
    parts = [str(r.get(k, "?")) for k in KEY_FIELDS]
    if r.get("variant"):
        parts[2] += f"[{r['variant']}]"
    return "/".join(parts)


def index(rows: list[dict], keyfn) -> dict[str, dict]:
    """{key: row}; a repeated key gets '#2', '#3' in file order so no row is silently lost."""
    out: dict[str, dict] = {}
    for r in rows:
        k = keyfn(r)
        if k in out:
            n = 2
            while f"{k}#{n}" in out:
                n += 1
            k = f"{k}#{n}"
        out[k] = r
    return out


def _f(x) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def verdict(r: dict) -> str:
    if r.get("skipped") or r.get("passed") is None:
        return "skipped"
    return "passed" if r.get("passed") is True else "failed"


def worsened(old, new, factor: float = FACTOR, floor: float = ROUND_OFF_FLOOR) -> bool:
    """True when `new` is worse than factor * old, both raised to the round-off floor first.

    A figure that becomes non-finite (inf, NaN, missing) while the baseline's was finite is
    worse; a baseline that was already non-finite or missing cannot get worse.
    """
    old, new = _f(old), _f(new)
    if not math.isfinite(old):
        return False
    if not math.isfinite(new):
        return True
    return max(abs(new), floor) > factor * max(abs(old), floor)


def fmt(x) -> str:
    if x is None:
        return "none"
    x = _f(x)
    if math.isnan(x):
        return "NaN"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:.3g}"


# ---- timings as same-run ratios ------------------------------------------------------------
def timing_ratios(bench: dict) -> dict[str, dict]:
    """{model/path/anchor: {model, path, anchor, ratio}}: each timed path over an anchor path
    of the same model in the same bench run (minimum over repeats: least disturbed by load)."""
    out: dict[str, dict] = {}
    by_model: dict[str, dict[str, float]] = {}
    anchors = timing_anchors()
    for r in bench.get("forward", []) or []:
        t = _f(r.get("us_per_state_min", r.get("us_per_state")))
        if math.isfinite(t) and t > 0 and not r.get("skipped"):
            by_model.setdefault(str(r.get("model", "?")), {})[str(r.get("path", "?"))] = t
    for model, paths in by_model.items():
        for anchor in anchors:
            if anchor not in paths:
                continue
            for path, t in paths.items():
                if path != anchor:
                    out[f"{model}/{path}/{anchor}"] = {
                        "model": model,
                        "path": path,
                        "anchor": anchor,
                        "ratio": float(f"{t / paths[anchor]:.3g}"),
                    }
            break
    return out


def wp_key(r: dict) -> str:
    return "/".join(str(r[k]) for k in WP_KEY_FIELDS if r.get(k) is not None)


# ---- comparison ----------------------------------------------------------------------------
class Outcome:
    def __init__(self):
        self.regressions: list[str] = []
        self.known_failures: list[str] = []
        self.improvements: list[str] = []
        self.new: list[str] = []  # records the baseline lacks: regressions, unless accepted
        self.accepted: list[str] = []  # the same, accepted by --accept-new
        self.notes: list[str] = []


def compare(
    baseline: dict,
    results: dict,
    bench: dict | None = None,
    factor: float = FACTOR,
    floor: float = ROUND_OFF_FLOOR,
    band: float = TIMING_BAND,
    accept_new: bool = False,
) -> Outcome:
    """The gate's verdict. A record the baseline lacks is ungated: a regression (a baseline of
    one model must not pass a run of the whole suite by comparing nothing) unless accept_new,
    which lists it as accepted; a new record that fails is a regression either way."""
    out = Outcome()
    old = index(baseline.get("records", []), record_key)
    new = index(results.get("records", []), record_key)
    for k, b in old.items():
        r = new.get(k)
        if r is None:
            out.regressions.append(
                f"{k}: in the baseline ({verdict(b)}) but missing from the results"
            )
            continue
        vb, vr = verdict(b), verdict(r)
        why = []
        if vb == "passed" and vr == "failed":
            why.append(
                f"passed -> failed (error {fmt(r.get('error'))} > tolerance "
                f"{fmt(r.get('tolerance'))})"
            )
        elif vb == "passed" and vr == "skipped":
            why.append(f"passed -> skipped ({r.get('reason') or 'no reason given'})")
        if (
            vb != "skipped"
            and vr != "skipped"
            and worsened(b.get("error"), r.get("error"), factor, floor)
        ):
            why.append(
                f"error {fmt(b.get('error'))} -> {fmt(r.get('error'))} (worse than "
                f"{factor:g}x; floor {floor:g})"
            )
        if why:
            out.regressions.append(f"{k}: " + "; ".join(why))
        elif vb == "failed" and vr == "failed":
            out.known_failures.append(
                f"{k}: failing in the baseline too (error "
                f"{fmt(r.get('error'))}, tolerance "
                f"{fmt(r.get('tolerance'))})"
            )
        elif vb != "passed" and vr == "passed":
            out.improvements.append(f"{k}: {vb} -> passed")
        elif vb == "passed" and worsened(r.get("error"), b.get("error"), factor, floor):
            out.improvements.append(f"{k}: error {fmt(b.get('error'))} -> {fmt(r.get('error'))}")
    for k, r in new.items():
        if k in old:
            continue
        if verdict(r) == "failed":  # a failing check enters the baseline only by --update
            out.regressions.append(
                f"{k}: new record, failing (error {fmt(r.get('error'))} > "
                f"tolerance {fmt(r.get('tolerance'))}); not in the baseline"
            )
        else:
            out.new.append(f"{k}: new record ({verdict(r)})")
    _compare_bench(baseline.get("bench"), bench, out, factor, floor, band)
    if accept_new:
        out.accepted, out.new = out.new, []
    else:
        out.regressions += [
            f"{n}; not in the baseline (gate it with --update, or accept it with --accept-new)"
            for n in out.new
        ]
    return out


def _compare_bench(base: dict | None, bench: dict | None, out: Outcome, factor, floor, band):
    if bench is None:
        if base:
            out.notes.append("benchmarks not compared: no --bench given")
        return
    if not base:
        out.notes.append(
            "the baseline has no benchmark section: nothing to compare the bench "
            "against (record one with --update --bench FILE)"
        )
        return
    ratios = timing_ratios(bench)
    for k, b in index(
        base.get("timing_ratios", []),
        lambda r: "/".join(str(r.get(f)) for f in ("model", "path", "anchor")),
    ).items():
        r = ratios.get(k)
        if r is None:
            # which paths are timed depends on bench options (--engines): a note, not a failure
            out.notes.append(f"timing {k}: in the baseline, not timed in this bench run")
            continue
        if worsened(b.get("ratio"), r["ratio"], band, 0.0):
            out.regressions.append(
                f"timing {k}: ratio {fmt(b.get('ratio'))} -> "
                f"{fmt(r['ratio'])} (slower than {band:g}x the baseline's "
                f"same-run ratio)"
            )
    old_wp = index(base.get("work_precision", []), wp_key)
    new_wp = index(bench.get("work_precision", []) or [], wp_key)
    for k, b in old_wp.items():
        r = new_wp.get(k)
        if r is None:
            out.regressions.append(
                f"work-precision {k}: in the baseline but missing from the bench"
            )
            continue
        why = [
            f"{f} {fmt(b.get(f))} -> {fmt(r.get(f))}"
            for f in WP_FIGURES
            if worsened(b.get(f), r.get(f), factor, floor)
        ]
        if why:
            out.regressions.append(
                f"work-precision {k}: "
                + "; ".join(why)
                + f" (worse than {factor:g}x; floor {floor:g})"
            )
    out.new += [f"work-precision {k}: new row" for k in new_wp if k not in old_wp]


# ---- baseline --------------------------------------------------------------------------------
def make_baseline(results: dict, bench: dict | None, command: str) -> dict:
    base = {
        "meta": {"command": command, "results_meta": results.get("meta") or {}},
        "records": results.get("records", []),
    }
    if bench is not None:
        base["meta"]["bench_meta"] = bench.get("meta") or {}
        base["bench"] = {
            "timing_ratios": list(timing_ratios(bench).values()),
            "work_precision": bench.get("work_precision", []) or [],
        }
    return base


def load_baseline(path: str) -> dict:
    data = load_json(path, "baseline")
    try:
        check_results(data, path)
    except ReportInputError as exc:  # the schema's own words: which field, where, and why
        raise GateInputError(
            f"baseline: {exc} (a baseline is written by `crosscheck gate --update`)"
        ) from None
    b = data.get("bench")
    if b is not None and not (
        isinstance(b, dict)
        and isinstance(b.get("timing_ratios", []), list)
        and isinstance(b.get("work_precision", []), list)
    ):
        raise GateInputError(
            f'baseline file {path!r}: "bench" must hold "timing_ratios" and "work_precision" lists'
        )
    return data
