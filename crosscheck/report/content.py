"""The report's inputs and content, shared by the HTML, Markdown and JUnit renderers:
loading and checking results/bench/sweep JSON, formatting, and ``Content`` (what each
page shows, per model)."""

from __future__ import annotations

import json
import math

import numpy as np

from crosscheck.checks.instantaneous import energy_error_series
from crosscheck.report.inputs import (  # noqa: F401
    ReportInputError,
    check_bench,
    check_results,
    check_sweep,
    load_json,
)

DEFAULT_RESULTS = "out/results.json"
BASE_VERSION_KEYS = ("python", "numpy", "scipy", "sympy")


def version_keys() -> tuple[str, ...]:
    """The versions results record: the numerical stack and every available engine's package."""
    from crosscheck.engines.registry import engine_distributions

    return BASE_VERSION_KEYS + engine_distributions()


def engine_anchors() -> tuple[tuple[str, str], ...]:
    """(engine, label) of every available engine, in the registry's order."""
    from crosscheck.engines.registry import available_engines, engine_label

    return tuple((e, engine_label(e)) for e in available_engines())


# the columns of a model's checks table and of a sweep's quantiles table (HTML and Markdown)
CHECK_HEADERS = [
    "status",
    "formulation",
    "engine",
    "check",
    "quantity",
    "error",
    "tolerance",
    "error / tolerance",
    "reason and details",
]
SWEEP_HEADERS = [
    "engine",
    "quantity",
    "samples",
    "max",
    "median",
    "q0.99",
    "tolerance",
    "outside",
    "worst sample",
    "status",
]

# record fields shown in their own columns; any other field goes to the "details" column
STANDARD_FIELDS = {
    "model",
    "formulation",
    "engine",
    "check",
    "quantity",
    "error",
    "tolerance",
    "passed",
    "skipped",
    "reason",
}


def engine_label(r: dict) -> str:
    """The engine, with its variant where it has several models of one system."""
    engine = str(r.get("engine", ""))
    return f"{engine} [{r['variant']}]" if r.get("variant") else engine


def status(r: dict) -> str:
    if r.get("skipped") or r.get("passed") is None:
        return "skip"
    return "pass" if r.get("passed") is True else "fail"


def to_float(x) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def fmt(x, digits: int = 2) -> str:
    """Error-like figure: 0, inf and NaN spelled out, None as a dash."""
    if x is None:
        return "—"
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return str(x)
    if x == 0:
        return "0"
    if math.isnan(x):
        return "NaN"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:.{digits}e}"


def fmt_tol(x) -> str:
    """A tolerance as written where it is named (1e-11, 3); a derived one to three digits
    (1.00155e-14 reads 1e-14: the record keeps the exact value)."""
    if x is None or isinstance(x, bool) or not isinstance(x, (int, float)):
        return "—" if x is None else str(x)
    return f"{x:.3g}"


def fmt_time(us) -> str:
    if us is None or not math.isfinite(to_float(us)):
        return "—"
    us = float(us)
    return f"{us:.3g}" if us < 1000 else f"{us:,.0f}"


def fmt_ratio(x: float) -> str:
    if not math.isfinite(x):
        return "—"
    return f"{x:.3g}×"


def ratio_to_tolerance(r: dict) -> float:
    e, t = to_float(r.get("error")), to_float(r.get("tolerance"))
    if not math.isfinite(t) or t <= 0 or math.isnan(e):
        return math.nan
    return e / t


def record_id(r: dict) -> str:
    return "/".join(
        str(r.get(k, "?")) for k in ("model", "formulation", "engine", "check", "quantity")
    )


def details(r: dict) -> str:
    out = []
    for k, v in r.items():
        if k in STANDARD_FIELDS or v is None or v == "":
            continue
        label = k.replace("_", " ")
        if isinstance(v, float):
            v = fmt(v, 1) if (abs(v) < 1e-3 or abs(v) >= 1e4) and v != 0 else f"{v:.4g}"
        elif isinstance(v, (list, dict)):
            v = json.dumps(v, allow_nan=True)
        out.append(f"{label}: {v}")
    return "; ".join(out)


STATUS_CLASS = {
    "ok": "pass",
    "met": "pass",
    "pass": "pass",
    "passed": "pass",
    "flagged": "flag",
    "warning": "flag",
    "not met": "fail",
    "fail": "fail",
    "failed": "fail",
    "error": "fail",
}


def named_items(section) -> list[tuple]:
    """A bench.json section this report has no dedicated layout for ("stress", "targets",
    "skips", ...) as rows (name, status, badge class, what, criterion, notes, other fields).

    A dict is read as {name: item}, a list as items named by their "scene" or "name"."""
    if isinstance(section, dict):
        items = list(section.items())
    elif isinstance(section, list):
        items = [
            (
                str(it.get("scene") or it.get("name") or it.get("id") or f"#{i + 1}")
                if isinstance(it, dict)
                else f"#{i + 1}",
                it,
            )
            for i, it in enumerate(section)
        ]
    else:
        items = [("value", section)]
    out = []
    for name, it in items:
        if not isinstance(it, dict):
            out.append((str(name), "", "skip", "", "", [], it))
            continue
        if it.get("status") is not None:
            st = str(it["status"])
        elif "met" in it:
            met = it["met"]
            if isinstance(met, dict):  # several targets: met only when every one is
                met = (
                    all(met.values())
                    if met and all(isinstance(v, bool) for v in met.values())
                    else None
                )
            st = {True: "met", False: "not met"}.get(met, "not evaluated")
        else:
            st = ""
        desc = str(it.get("what") or it.get("statement") or "")
        crit = str(it.get("tolerance") or "") if isinstance(it.get("tolerance"), str) else ""
        reasons = it.get("reasons")
        notes = [str(x) for x in reasons] if isinstance(reasons, list) else []
        for k in ("reason", "note"):
            if it.get(k):
                notes.append(str(it[k]))
        shown = {
            "status",
            "met",
            "what",
            "statement",
            "reasons",
            "reason",
            "note",
            "scene",
            "name",
        } | ({"tolerance"} if crit else set())
        rest = {k: v for k, v in it.items() if k not in shown}
        out.append((str(name), st, STATUS_CLASS.get(st.lower(), "skip"), desc, crit, notes, rest))
    return out


def method_label(r: dict) -> str:
    """'projection/DOP853': the stabilisation method and the integrator carrying it."""
    m = str(r.get("method", "?"))
    return f"{m}/{r['integrator']}" if r.get("integrator") else m


def wp_row(r: dict) -> list[str]:
    """A work-precision row as table cells: method/integrator, engine, setting, figures."""
    setting = r.get("setting", "")
    setting = fmt_tol(setting) if isinstance(setting, (int, float)) else str(setting)
    if r.get("setting_kind"):
        setting = f"{r['setting_kind']} {setting}"
    return [
        method_label(r),
        str(r.get("engine", "")),
        setting,
        fmt(to_float(r.get("wall_s"))) if r.get("wall_s") is not None else "—",
        fmt(r.get("error")),
        fmt(r.get("residual")),
        fmt(r.get("energy_drift")),
        str(r.get("nfev", "—")),
    ]


def model_info(name: str) -> tuple[str, str]:
    """(source, title) from the model registry, or ('', '') for a name it does not know."""
    try:
        from reference import models

        m = models.get(name)
        return str(getattr(m, "source", "") or ""), str(getattr(m, "title", "") or "")
    except Exception:  # a renamed or unloadable model must not stop the report
        return "", ""


def series_stats(s: dict) -> dict:
    def col(key):
        return [to_float(v) for v in (s.get(key) or [])]

    t = col("t")
    out = {"points": len(t), "t_end": t[-1] if t else math.nan}
    for key in ("state_error", "residual"):
        v = [abs(x) for x in col(key) if not math.isnan(x)]
        out[key] = max(v) if v else math.nan
    e = energy_series(s)
    out["energy"] = float(np.nanmax(e)) if e.size and not np.all(np.isnan(e)) else math.nan
    return out


def energy_series(s: dict) -> np.ndarray:
    """The series' energy error at every time, as its records judge it: the drift, or the
    work-energy balance where the series carries the work W(t) (energy not conserved)."""
    e = np.array([to_float(v) for v in (s.get("energy") or [])])
    if not e.size or not math.isfinite(e[0]):
        return np.full(e.size, math.nan)
    w = s.get("work")
    if w is not None:
        w = np.array([to_float(v) for v in w])[: e.size]
        e = e[: w.size]
    with np.errstate(all="ignore"):  # a run that blew up: inf - inf is drawn as a gap
        return energy_error_series(e, w)


def conserves_energy(series: list[dict]) -> bool:
    return not any(s.get("work") is not None for s in series)


def energy_heading(series: list[dict]) -> str:
    """The energy column's and panel's name for one model's series."""
    return (
        "max energy drift"
        if conserves_energy(series)
        else "max work-energy balance error (energy not conserved)"
    )


# ---- the report's content, shared by the HTML and the Markdown -------------------------------


class Content:
    def __init__(
        self,
        results: dict | None,
        bench: dict | None,
        command: str,
        results_path: str | None = None,
        bench_path: str | None = None,
        sweep: dict | None = None,
        sweep_path: str | None = None,
    ):
        self.sweep = sweep  # sweep.json of `crosscheck sweep` (its own section)
        self.sweep_path = sweep_path
        self.results = results or {}
        self.bench = bench
        self.command = command
        self.results_path = results_path
        self.bench_path = bench_path
        self.records = list(self.results.get("records", []))
        self.series = self.results.get("series")
        self.forward = list((bench or {}).get("forward", []) or [])
        self.work_precision = list((bench or {}).get("work_precision", []) or [])
        names = [r.get("model", "?") for r in self.records]
        names += [r.get("model", "?") for r in self.forward + self.work_precision]
        names += [s.get("model", "?") for s in (self.series or [])]
        self.models = list(dict.fromkeys(names))
        self.counts = {
            k: sum(1 for r in self.records if status(r) == k) for k in ("pass", "fail", "skip")
        }
        self.failing = [r for r in self.records if status(r) == "fail"]
        # bench sections this report has no dedicated layout for (e.g. "targets", "stress")
        self.other_bench = {
            k: v for k, v in (bench or {}).items() if k not in ("meta", "forward", "work_precision")
        }

    def records_of(self, model):
        return [r for r in self.records if r.get("model", "?") == model]

    def series_of(self, model):
        return [s for s in (self.series or []) if s.get("model", "?") == model]

    def agreement_of(self, model) -> list[dict]:
        """The model's agreement matrices (results.json "agreement"; absent in older files)."""
        rows = self.results.get("agreement") or []
        return [m for m in rows if isinstance(m, dict) and m.get("model") == model]

    def forward_of(self, model):
        return [r for r in self.forward if r.get("model", "?") == model]

    def work_precision_of(self, model):
        return [r for r in self.work_precision if r.get("model", "?") == model]

    def series_note(self, model) -> str:
        if self.results_path is None:
            return "No trajectory shown: the report was made without a results.json."
        if not self.series:
            return (
                'No trajectory was run: results.json has no "series" (the run recorded '
                "instantaneous checks only)."
            )
        if not self.series_of(model):
            return 'No trajectory of this model in results.json\'s "series".'
        return ""

    def timing_rows(self, model):
        """Forward rows with ratios against each engine's forward call in the same bench run."""
        rows = self.forward_of(model)
        anchors = {}
        for key, label in engine_anchors():
            for r in rows:
                if r.get("path") == f"engine:{key}" and to_float(r.get("us_per_state")) > 0:
                    anchors[key] = (label, to_float(r["us_per_state"]))
        out = []
        for r in rows:
            us = to_float(r.get("us_per_state"))
            ratios = {k: us / a for k, (_, a) in anchors.items()}
            out.append((r, ratios))
        return out, anchors

    def meta_rows(self):
        """[(label, meta)] for the runs behind the report."""
        out = []
        if self.results_path is not None:
            out.append(("results", self.results.get("meta") or {}))
        if self.bench is not None:
            out.append(("bench", self.bench.get("meta") or {}))
        if self.sweep is not None:
            out.append(("sweep", self.sweep.get("meta") or {}))
        return out

    def regenerate(self) -> list[str]:
        cmds = [str(m.get("command")) for _, m in self.meta_rows() if m.get("command")]
        return [*cmds, self.command]


def machine_text(meta: dict) -> str:
    m = meta.get("machine")
    if isinstance(m, dict):
        parts = [str(m.get("platform", "")), str(m.get("processor", ""))]
        if m.get("cpus"):
            parts.append(f"{m['cpus']} CPUs")
        return ", ".join(p for p in parts if p)
    return str(m) if m else "not recorded"


def versions_of(meta: dict) -> dict:
    v = meta.get("versions") or {}
    return {
        k: (v.get(k) if v.get(k) is not None else "not installed") if k in v else "not recorded"
        for k in version_keys()
    }


# ---- sweep section (sweep.json of `crosscheck sweep`) ----------------------------------------


def sweep_label(r: dict) -> str:
    return engine_label(r)


def sweep_verdict(sw: dict) -> tuple[bool, str]:
    st = sw.get("status") or {}
    done = sum((st.get("completed") or {}).values())
    asked = sum((st.get("requested") or {}).values())
    ok = bool(st.get("passed"))
    text = (
        f"{done} of {asked} samples, {st.get('outside_tolerance', '?')} outside tolerance, "
        f"{st.get('faults', '?')} faults"
    )
    if st.get("stopped"):
        text += f"; stopped: {st['stopped']}"
    return ok, text


def sweep_rows(sw: dict, model: str) -> list[list]:
    """[label, quantity, count, max, q0.5, q0.99, tolerance, outside, worst index, status]."""
    out = []
    for r in sw.get("results", []):
        if r.get("model") != model:
            continue
        if r.get("skipped"):
            out.append(
                [
                    sweep_label(r),
                    r.get("quantity", "?"),
                    0,
                    None,
                    None,
                    None,
                    None,
                    None,
                    None,
                    "skip: " + str(r["skipped"]),
                ]
            )
            continue
        q = r.get("quantiles") or {}
        worst = (r.get("worst") or [{}])[0]
        outside = r.get("outside_tolerance")
        st = "—" if outside is None else ("fail" if outside else "pass")
        out.append(
            [
                sweep_label(r),
                r.get("quantity", "?"),
                r.get("count"),
                r.get("max"),
                q.get("0.5"),
                q.get("0.99"),
                r.get("tolerance"),
                outside,
                worst.get("index"),
                st,
            ]
        )
    return out


def sweep_models(sw: dict) -> list[str]:
    return list(
        dict.fromkeys(
            [r.get("model", "?") for r in sw.get("results", [])]
            + [r.get("model", "?") for r in sw.get("series", [])]
        )
    )
