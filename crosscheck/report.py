"""`crosscheck report`: results.json (+ bench.json) -> DIR/index.html, DIR/report.md, DIR/junit.xml.

- index.html is one self-contained file (inline CSS, figures as data: URIs, no script, nothing
  fetched), so it opens from disk or a CI artifact with no network.
- Per model: a table of every check (failing rows kept and marked, skipped rows with their
  reason), the agreement plot (error against tolerance per quantity and engine, log scale),
  trajectories from results.json's "series" (state error against the reference, constraint
  residual, energy drift against time), work-precision diagrams and the forward timing table
  from bench.json, with ratios against the engines timed in the same bench run.
- junit.xml: one test case per record; failures carry the error, the tolerance and the reason;
  skipped records are <skipped message=reason>.
- Every page ends with the commands that regenerate it, the machine and the package versions,
  taken from the inputs' "meta" (the run that produced the numbers, not the report's process).

Output is deterministic for the same inputs and arguments: nothing here reads the clock, and the
figures are rendered with fixed ids (see crosscheck.plots).
"""
from __future__ import annotations

import base64
import html
import json
import math
import shlex
import xml.etree.ElementTree as ET
from pathlib import Path

from reference.errors import ModelInputError

from . import report_sensitivity  # the section of sensitivity.json beside results.json

DEFAULT_RESULTS = "out/results.json"
BASE_VERSION_KEYS = ("python", "numpy", "scipy", "sympy")


def version_keys() -> tuple[str, ...]:
    """The versions results record: the numerical stack and every available engine's package."""
    from .engines.registry import engine_distributions
    return BASE_VERSION_KEYS + engine_distributions()


def engine_anchors() -> tuple[tuple[str, str], ...]:
    """(engine, label) of every available engine, in the registry's order."""
    from .engines.registry import available_engines, engine_label
    return tuple((e, engine_label(e)) for e in available_engines())
# record fields shown in their own columns; any other field goes to the "details" column
STANDARD_FIELDS = {"model", "formulation", "engine", "check", "quantity", "error", "tolerance",
                   "passed", "skipped", "reason"}


class ReportInputError(ModelInputError):
    """A report input is missing or malformed (printed as one line, exit status 2)."""


# ---- inputs ----------------------------------------------------------------------------------

def engine_label(r: dict) -> str:
    """The engine, with its variant where it has several models of one system."""
    return f"{r.get('engine', '')} [{r['variant']}]" if r.get("variant") else str(r.get("engine", ""))

def load_json(path: str | Path, what: str) -> dict:
    path = Path(path)
    if not path.is_file():
        raise ReportInputError(f"{what} file {str(path)!r} not found")
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ReportInputError(f"{what} file {str(path)!r} is not valid JSON: {exc}")
    if not isinstance(data, dict):
        raise ReportInputError(f"{what} file {str(path)!r}: expected a JSON object at the top")
    return data


def _record_problem(r) -> str | None:
    """What is wrong with one record, or None: the fields every report and gate reads."""
    if not isinstance(r, dict):
        return "is not an object"
    for key in ("model", "engine", "check", "quantity"):
        if not isinstance(r.get(key), str) or not r[key]:
            return f"has no {key!r} name"
    if r.get("passed") not in (True, False, None):
        return f"has \"passed\": {r.get('passed')!r} (expected true, false or null)"
    for key in ("error", "tolerance"):
        v = r.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))):
            return f"has {key!r}: {v!r} (expected a number or null)"
    if r.get("passed") is not None and r.get("tolerance") is None:
        return "is judged (\"passed\" set) but has no tolerance"
    return None


def check_results(data: dict, path) -> dict:
    recs = data.get("records")
    if not isinstance(recs, list):
        raise ReportInputError(f"results file {str(path)!r} has no \"records\" list of objects "
                               f"(is it a results.json written by `crosscheck run`?)")
    for i, r in enumerate(recs):
        problem = _record_problem(r)
        if problem:
            raise ReportInputError(f"results file {str(path)!r}: record {i} {problem} (is it "
                                   f"a results.json written by `crosscheck run`?)")
    series = data.get("series")
    if series is not None and not (isinstance(series, list)
                                   and all(isinstance(s, dict) for s in series)):
        raise ReportInputError(f"results file {str(path)!r}: \"series\" must be a list of "
                               f"objects")
    return data


def check_bench(data: dict, path) -> dict:
    for key in ("forward", "work_precision"):
        rows = data.get(key, [])
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            raise ReportInputError(f"bench file {str(path)!r}: \"{key}\" must be a list of "
                                   f"objects (is it a bench.json written by `crosscheck bench`?)")
    if "forward" not in data and "work_precision" not in data:
        raise ReportInputError(f"bench file {str(path)!r} has neither \"forward\" nor "
                               f"\"work_precision\" (is it a bench.json?)")
    return data


def check_sweep(data: dict, path) -> dict:
    rows = data.get("results")
    if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows) \
            or not isinstance(data.get("status"), dict):
        raise ReportInputError(f"sweep file {str(path)!r} has no \"results\" list of objects "
                               f"and \"status\" object (is it a sweep.json written by "
                               f"`crosscheck sweep`?)")
    return data


# ---- small helpers ---------------------------------------------------------------------------
def status(r: dict) -> str:
    if r.get("skipped") or r.get("passed") is None:
        return "skip"
    return "pass" if r.get("passed") is True else "fail"


def _f(x) -> float:
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
    """A tolerance as written where it is named: 1e-11, 3."""
    if x is None or isinstance(x, bool) or not isinstance(x, (int, float)):
        return "—" if x is None else str(x)
    return f"{x:g}"


def fmt_time(us) -> str:
    if us is None or not math.isfinite(_f(us)):
        return "—"
    us = float(us)
    return f"{us:.3g}" if us < 1000 else f"{us:,.0f}"


def fmt_ratio(x: float) -> str:
    if not math.isfinite(x):
        return "—"
    return f"{x:.3g}×"


def ratio_to_tolerance(r: dict) -> float:
    e, t = _f(r.get("error")), _f(r.get("tolerance"))
    if not math.isfinite(t) or t <= 0 or math.isnan(e):
        return math.nan
    return e / t


def record_id(r: dict) -> str:
    return "/".join(str(r.get(k, "?")) for k in ("model", "formulation", "engine", "check",
                                                  "quantity"))


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


STATUS_CLASS = {"ok": "pass", "met": "pass", "pass": "pass", "passed": "pass",
                "flagged": "flag", "warning": "flag", "not met": "fail", "fail": "fail",
                "failed": "fail", "error": "fail"}


def named_items(section) -> list[tuple]:
    """A bench.json section this report has no dedicated layout for ("stress", "targets",
    "skips", ...) as rows (name, status, badge class, what, criterion, notes, other fields).

    A dict is read as {name: item}, a list as items named by their "scene" or "name"."""
    if isinstance(section, dict):
        items = list(section.items())
    elif isinstance(section, list):
        items = [(str(it.get("scene") or it.get("name") or it.get("id") or f"#{i + 1}")
                  if isinstance(it, dict) else f"#{i + 1}", it) for i, it in enumerate(section)]
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
            st = {True: "met", False: "not met"}.get(it["met"], "not evaluated")
        else:
            st = ""
        desc = str(it.get("what") or it.get("statement") or "")
        crit = str(it.get("tolerance") or "") if isinstance(it.get("tolerance"), str) else ""
        reasons = it.get("reasons")
        notes = [str(x) for x in reasons] if isinstance(reasons, list) else []
        for k in ("reason", "note"):
            if it.get(k):
                notes.append(str(it[k]))
        shown = {"status", "met", "what", "statement", "reasons", "reason", "note", "scene",
                 "name"} | ({"tolerance"} if crit else set())
        rest = {k: v for k, v in it.items() if k not in shown}
        out.append((str(name), st, STATUS_CLASS.get(st.lower(), "skip"), desc, crit, notes, rest))
    return out


def wp_row(r: dict) -> list[str]:
    """A work-precision row as table cells: method/integrator, engine, setting, figures."""
    from .plots import method_label
    setting = r.get("setting", "")
    setting = fmt_tol(setting) if isinstance(setting, (int, float)) else str(setting)
    if r.get("setting_kind"):
        setting = f"{r['setting_kind']} {setting}"
    return [method_label(r), str(r.get("engine", "")), setting,
            fmt(_f(r.get("wall_s"))) if r.get("wall_s") is not None else "—",
            fmt(r.get("error")), fmt(r.get("residual")), fmt(r.get("energy_drift")),
            str(r.get("nfev", "—"))]


def model_info(name: str) -> tuple[str, str]:
    """(source, title) from the model registry, or ('', '') for a name it does not know."""
    try:
        from reference import models
        m = models.get(name)
        return str(getattr(m, "source", "") or ""), str(getattr(m, "title", "") or "")
    except Exception:  # a renamed or unloadable model must not stop the report
        return "", ""


def _series_stats(s: dict) -> dict:
    def col(key):
        return [_f(v) for v in (s.get(key) or [])]
    t = col("t")
    out = {"points": len(t), "t_end": t[-1] if t else math.nan}
    for key in ("state_error", "residual"):
        v = [abs(x) for x in col(key) if not math.isnan(x)]
        out[key] = max(v) if v else math.nan
    e = col("energy")
    if e and math.isfinite(e[0]):
        drift = [abs(x - e[0]) / max(abs(e[0]), 1.0) for x in e if not math.isnan(x)]
        out["energy"] = max(drift) if drift else math.nan
    else:
        out["energy"] = math.nan
    return out


# ---- the report's content, shared by the HTML and the Markdown -------------------------------
class Content:
    def __init__(self, results: dict | None, bench: dict | None, command: str,
                 results_path: str | None = None, bench_path: str | None = None,
                 sweep: dict | None = None, sweep_path: str | None = None):
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
        self.counts = {k: sum(1 for r in self.records if status(r) == k)
                       for k in ("pass", "fail", "skip")}
        self.failing = [r for r in self.records if status(r) == "fail"]
        # bench sections this report has no dedicated layout for (e.g. "targets", "stress")
        self.other_bench = {k: v for k, v in (bench or {}).items()
                            if k not in ("meta", "forward", "work_precision")}

    def records_of(self, model):
        return [r for r in self.records if r.get("model", "?") == model]

    def series_of(self, model):
        return [s for s in (self.series or []) if s.get("model", "?") == model]

    def forward_of(self, model):
        return [r for r in self.forward if r.get("model", "?") == model]

    def work_precision_of(self, model):
        return [r for r in self.work_precision if r.get("model", "?") == model]

    def series_note(self, model) -> str:
        if self.results_path is None:
            return "No trajectory shown: the report was made without a results.json."
        if not self.series:
            return ("No trajectory was run: results.json has no \"series\" (the run recorded "
                    "instantaneous checks only).")
        if not self.series_of(model):
            return "No trajectory of this model in results.json's \"series\"."
        return ""

    def timing_rows(self, model):
        """Forward rows with ratios against each engine's forward call in the same bench run."""
        rows = self.forward_of(model)
        anchors = {}
        for key, label in engine_anchors():
            for r in rows:
                if r.get("path") == f"engine:{key}" and _f(r.get("us_per_state")) > 0:
                    anchors[key] = (label, _f(r["us_per_state"]))
        out = []
        for r in rows:
            us = _f(r.get("us_per_state"))
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
        return cmds + [self.command]


def _machine(meta: dict) -> str:
    m = meta.get("machine")
    if isinstance(m, dict):
        parts = [str(m.get("platform", "")), str(m.get("processor", ""))]
        if m.get("cpus"):
            parts.append(f"{m['cpus']} CPUs")
        return ", ".join(p for p in parts if p)
    return str(m) if m else "not recorded"


def _versions(meta: dict) -> dict:
    v = meta.get("versions") or {}
    return {k: (v.get(k) if v.get(k) is not None else "not installed") if k in v
            else "not recorded" for k in version_keys()}


# ---- HTML ------------------------------------------------------------------------------------
CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,"DejaVu Sans",sans-serif;color:#1d1d1d;
margin:0;background:#fafafa;line-height:1.4}
main{max-width:1180px;margin:0 auto;padding:18px 26px 40px;background:#fff}
h1{font-size:1.6em;margin:.2em 0}h2{font-size:1.3em;margin-top:2em;border-bottom:2px solid #ddd;
padding-bottom:.2em}h3{font-size:1.05em;margin:1.4em 0 .5em}
.sub{color:#555;font-size:.9em}
.banner{padding:10px 14px;border-radius:6px;font-weight:600;margin:14px 0}
.banner.ok{background:#e6f4ea;color:#145c2c;border:1px solid #9ccfaa}
.banner.bad{background:#fde8e8;color:#8a1111;border:1px solid #f0a0a0}
table{border-collapse:collapse;font-size:.84em;margin:.4em 0 .8em}
th,td{border:1px solid #d8d8d8;padding:3px 7px;text-align:left;vertical-align:top}
th{background:#f0f0f0;font-weight:600}
td.num{text-align:right;font-family:ui-monospace,"DejaVu Sans Mono",monospace;white-space:nowrap}
tr.fail td{background:#fde8e8}tr.skip td{color:#666;background:#f7f7f7}
.badge{display:inline-block;padding:0 6px;border-radius:3px;font-weight:700;font-size:.85em}
.badge.pass{background:#d7f0dd;color:#145c2c}.badge.fail{background:#d62728;color:#fff}
.badge.skip{background:#e4e4e4;color:#555}.badge.flag{background:#f5c542;color:#4a3500}
details pre{max-height:24em;overflow:auto;font-size:.85em}
.note{color:#555;font-size:.88em}.reason{color:#444;font-size:.92em}
ol.notes{font-size:.8em;color:#444;margin-top:0}ol.notes li{margin:.15em 0}
figure{margin:.6em 0 1.2em}figure img{max-width:100%;height:auto;border:1px solid #eee}
figcaption{font-size:.82em;color:#555;max-width:60em}
nav{display:flex;flex-wrap:wrap;gap:.25em 1em;margin:.4em 0}
footer{margin-top:3em;border-top:2px solid #ddd;padding-top:.6em;font-size:.85em;color:#333}
pre{background:#f5f5f5;padding:8px 10px;overflow-x:auto;font-size:.92em}
code{font-family:ui-monospace,"DejaVu Sans Mono",monospace}
"""


def _e(x) -> str:
    return html.escape(str(x), quote=True)


def _anchor(model: str) -> str:
    return "model-" + "".join(c if c.isalnum() or c in "-_" else "-" for c in model)


def _img(svg: str | None, alt: str, caption: str) -> str:
    if not svg:
        return ""
    data = base64.b64encode(svg.encode("utf-8")).decode("ascii")
    return (f'<figure><img src="data:image/svg+xml;base64,{data}" alt="{_e(alt)}">'
            f"<figcaption>{caption}</figcaption></figure>")


def _table(headers: list[str], rows: list[list[str]], classes: list[str] | None = None,
           num_cols: set[int] = frozenset()) -> str:
    out = ["<table><thead><tr>" + "".join(f"<th>{h}</th>" for h in headers) + "</tr></thead>",
           "<tbody>"]
    for i, row in enumerate(rows):
        cls = f' class="{classes[i]}"' if classes and classes[i] else ""
        cells = "".join(f'<td class="num">{c}</td>' if j in num_cols else f"<td>{c}</td>"
                        for j, c in enumerate(row))
        out.append(f"<tr{cls}>{cells}</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


def _named_items_html(section) -> str:
    rows, classes = [], []
    for name, st, cls, desc, crit, notes, rest in named_items(section):
        rest_html = (f"<details><summary>details</summary><pre>"
                     f"{_e(json.dumps(rest, indent=1, allow_nan=True))}</pre></details>"
                     if rest else "")
        rows.append([f"<b>{_e(name)}</b>", f'<span class="badge {cls}">{_e(st)}</span>' if st
                     else "", _e(desc) + (f'<br><span class="note">criterion: {_e(crit)}</span>'
                                          if crit else ""),
                     "<br>".join(_e(n) for n in notes), rest_html])
        classes.append("fail" if cls == "fail" else "")
    if not rows:
        return '<p class="note">(empty)</p>'
    return _table(["name", "status", "what", "notes", "figures"], rows, classes)


def _checks_html(c: Content, model: str, recs: list[dict]) -> str:
    notes: list[str] = []
    rows, classes = [], []
    for r in recs:
        st = status(r)
        reason = str(r.get("reason") or "")
        if st == "skip":
            why = f'<span class="reason">skipped: {_e(reason or "no reason given")}</span>'
        else:
            if reason and reason not in notes:
                notes.append(reason)
            why = (f'<a href="#{_anchor(model)}-n{notes.index(reason) + 1}">'
                   f"[{notes.index(reason) + 1}]</a>" if reason else "")
        extra = details(r)
        label = {"pass": "PASS", "fail": "FAIL", "skip": "SKIP"}[st]
        rows.append([f'<span class="badge {st}">{label}</span>', _e(r.get("formulation", "")),
                     _e(engine_label(r)), _e(r.get("check", "")), _e(r.get("quantity", "")),
                     _e(fmt(r.get("error"))), _e(fmt_tol(r.get("tolerance"))),
                     _e(fmt(ratio_to_tolerance(r), 1)) if st != "skip" else "—",
                     why + (("<br>" if why else "") + f'<span class="note">{_e(extra)}</span>'
                            if extra else "")])
        classes.append(st)
    table = _table(["status", "formulation", "engine", "check", "quantity", "error", "tolerance",
                    "error / tolerance", "reason and details"], rows, classes, {5, 6, 7})
    if notes:
        table += ('<p class="note" style="margin-bottom:0">Tolerances and their reasons:</p>'
                  '<ol class="notes">' + "".join(
                      f'<li id="{_anchor(model)}-n{i + 1}">{_e(n)}</li>'
                      for i, n in enumerate(notes)) + "</ol>")
    return table


def _timing_html(c: Content, model: str) -> str:
    rows, anchors = c.timing_rows(model)
    if not rows:
        return ""
    headers = ["engine", "path", "batch", "µs / state (median)", "µs / state (min)"]
    headers += [f"× {label}" for _, (label, _) in anchors.items()]
    body, classes = [], []
    for r, ratios in rows:
        skipped = r.get("skipped")
        line = [_e(r.get("engine", "")), _e(r.get("path", "")), _e(r.get("batch", "")),
                _e(fmt_time(r.get("us_per_state"))) if not skipped else
                f'<span class="reason">skipped: {_e(skipped)}</span>',
                _e(fmt_time(r.get("us_per_state_min")))]
        line += [_e(fmt_ratio(ratios[k])) for k in anchors]
        body.append(line)
        classes.append("skip" if skipped else "")
    num = set(range(2, len(headers)))
    out = _table(headers, body, classes, num)
    if anchors:
        names = " and ".join(label for label, _ in anchors.values())
        out += (f'<p class="note">× {names}: this path\'s median time per state divided by the '
                f"engine's constrained forward call at the same state, both measured in the same "
                f"bench run (so the ratio, not the absolute time, is what carries over between "
                f"machines; &lt; 1× means faster than the engine).</p>")
    else:
        out += ('<p class="note">No engine was timed in this bench run, so there are no ratios '
                f"against {' or '.join(label for _, label in engine_anchors())} (run "
                f"<code>crosscheck bench --engines "
                f"{','.join(e for e, _ in engine_anchors())}</code>).</p>")
    return out


def _work_precision_html(c: Content, model: str) -> str:
    from . import plots
    rows = c.work_precision_of(model)
    if not rows:
        if c.bench is None:
            return ""
        return ('<p class="note">No work-precision data for this model in bench.json '
                '("work_precision" has no rows for it).</p>')
    out = [_img(plots.work_precision_svg(rows), f"work-precision diagram for {model}",
                "Wall time against the error at the end of the run (and the largest constraint "
                "residual and energy drift where recorded), log-log; one line per method and "
                "engine, points along the tolerance or step-size ladder. Lower left is better.")]
    keys = ["method", "engine", "setting", "wall [s]", "error", "residual", "energy drift",
            "nfev"]
    body = [[_e(v) for v in wp_row(r)] for r in rows]
    table = _table(keys, body, None, {3, 4, 5, 6, 7})
    if len(rows) > 12:  # long ladders fold away under the diagram (no script: <details>)
        table = f"<details><summary>table of the {len(rows)} points</summary>{table}</details>"
    out.append(table)
    return "\n".join(out)


def _trajectory_html(c: Content, model: str) -> str:
    from . import plots
    note = c.series_note(model)
    if note:
        return f'<p class="note">{_e(note)}</p>'
    ss = c.series_of(model)
    out = [_img(plots.trajectory_svg(ss), f"trajectories of {model}",
                "Against time, log scale: the state's difference from the reference trajectory, "
                "the largest constraint violation, and the energy drift |E − E(0)| / "
                f"max(|E(0)|, 1). A line that is exactly 0 throughout is named in its panel; "
                f"other zeros are drawn at {plots.ZERO_AT:.0e}.")]
    body = []
    for s in ss:
        st = _series_stats(s)
        body.append([_e(plots.series_label(s)), _e(st["points"]), _e(f"{st['t_end']:g}"),
                     _e(fmt(st["state_error"])), _e(fmt(st["residual"])),
                     _e(fmt(st["energy"]))])
    out.append(_table(["series", "points", "t end [s]", "max state error", "max residual",
                       "max energy drift"], body, None, {1, 2, 3, 4, 5}))
    return "\n".join(out)


def _model_html(c: Content, model: str) -> str:
    from . import plots
    source, title = model_info(model)
    recs = c.records_of(model)
    head = f'<h2 id="{_anchor(model)}">{_e(model)}'
    if title or source:
        src = f" ({_e(source)})" if source else ""
        head += f' <span class="sub">— {_e(title)}{src}</span>'
    head += "</h2>"
    out = [head]
    n = {k: sum(1 for r in recs if status(r) == k) for k in ("pass", "fail", "skip")}
    if recs:
        out.append(f'<p class="sub">{n["pass"]} passed, {n["fail"]} failed, {n["skip"]} '
                   f"skipped</p>")
        out.append("<h3>Checks</h3>")
        out.append(_checks_html(c, model, recs))
        out.append("<h3>Agreement</h3>")
        out.append(_img(plots.agreement_svg(recs), f"agreement plot for {model}",
                        "Each executed check's error (dot, one colour per engine) beside its "
                        "tolerance (black bar), log scale: a dot left of its bar passes. Failing "
                        "checks are ringed in red; skipped checks are named in grey."))
    else:
        out.append('<p class="note">No cross-check records for this model in results.json.</p>')
    out.append("<h3>Trajectories</h3>")
    out.append(_trajectory_html(c, model))
    if c.bench is not None:
        out.append("<h3>Work-precision</h3>")
        out.append(_work_precision_html(c, model))
        timing = _timing_html(c, model)
        out.append("<h3>Forward dynamics timings</h3>")
        out.append(timing or '<p class="note">This model was not timed in bench.json.</p>')
    return "\n".join(out)


def _footer_html(c: Content) -> str:
    out = ['<footer id="footer"><h3>Regenerate</h3><pre><code>'
           + _e("\n".join(c.regenerate())) + "</code></pre>"]
    metas = c.meta_rows()
    if metas:
        headers = [""] + [label for label, _ in metas]
        rows = [["command"] + [f"<code>{_e(m.get('command', 'not recorded'))}</code>"
                               for _, m in metas],
                ["date (UTC)"] + [_e(m.get("date", "not recorded")) for _, m in metas],
                ["machine"] + [_e(_machine(m)) for _, m in metas]]
        for k in version_keys():
            rows.append([k] + [_e(_versions(m)[k]) for _, m in metas])
        out.append("<h3>Machine and versions</h3>")
        out.append(_table(headers, rows))
    out.append('<p class="note">Generated by <code>crosscheck report</code> from the files above; '
               "do not edit by hand.</p></footer>")
    return "\n".join(out)


def render_html(c: Content) -> str:
    try:  # fail before writing anything, with one line, if the plotting library is missing
        import matplotlib  # noqa: F401
    except ImportError:
        raise ReportInputError("the report's plots need matplotlib (a dependency of this "
                               "package: pip install -e .)")
    n = c.counts
    executed = n["pass"] + n["fail"]
    if c.records:
        if n["fail"]:
            banner = (f'<div class="banner bad">{n["fail"]} of {executed} executed checks FAIL '
                      f'({n["pass"]} passed, {n["skip"]} skipped)</div>')
        else:
            banner = (f'<div class="banner ok">All {executed} executed checks pass '
                      f'({n["skip"]} skipped)</div>')
    elif c.sweep is not None and c.bench is None:
        banner = '<div class="banner ok">No cross-check results given: sweep only</div>'
    else:
        banner = '<div class="banner ok">No cross-check results given: benchmarks only</div>'
    sources = []
    if c.results_path is not None:
        sources.append(f"results <code>{_e(c.results_path)}</code> "
                       f"({_e((c.results.get('meta') or {}).get('date', 'undated'))})")
    if c.bench_path is not None:
        sources.append(f"bench <code>{_e(c.bench_path)}</code> "
                       f"({_e((c.bench.get('meta') or {}).get('date', 'undated'))})")
    if c.sweep_path is not None:
        sources.append(f"sweep <code>{_e(c.sweep_path)}</code> "
                       f"({_e((c.sweep.get('meta') or {}).get('date', 'undated'))})")
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             '<meta name="viewport" content="width=device-width, initial-scale=1">',
             "<title>multibody-crosscheck report</title>", f"<style>{CSS}</style></head>",
             "<body><main>", "<h1>multibody-crosscheck report</h1>",
             f'<p class="sub">{" · ".join(sources)}</p>', banner]
    if c.models:
        parts.append("<nav>" + "".join(f'<a href="#{_anchor(m)}">{_e(m)}</a>'
                                       for m in c.models)
                     + ('<a href="#bench-more">more from bench.json</a>' if c.other_bench else "")
                     + ('<a href="#sweep">sweep</a>' if c.sweep is not None else "")
                     + '<a href="#footer">versions</a></nav>')
    headers = ["model", "passed", "failed", "skipped", "engines"]
    headers += ["trajectories"] if c.series is not None else []
    headers += ["forward timings", "work-precision points"] if c.bench is not None else []
    overview = []
    for m in c.models:
        recs = c.records_of(m)
        k = {s: sum(1 for r in recs if status(r) == s) for s in ("pass", "fail", "skip")}
        engines = ", ".join(dict.fromkeys(r.get("engine", "?") for r in recs))
        row = [f'<a href="#{_anchor(m)}">{_e(m)}</a>', str(k["pass"]),
               f'<b>{k["fail"]}</b>' if k["fail"] else "0", str(k["skip"]), _e(engines)]
        row += [str(len(c.series_of(m)))] if c.series is not None else []
        row += ([str(len(c.forward_of(m))), str(len(c.work_precision_of(m)))]
                if c.bench is not None else [])
        overview.append(row)
    if overview:
        parts.append("<h3>Overview</h3>")
        parts.append(_table(headers, overview,
                            ["fail" if "<b>" in row[2] else "" for row in overview],
                            {1, 2, 3} | set(range(5, len(headers)))))
    if c.failing:
        parts.append("<h3>Failing checks</h3><ul>")
        for r in c.failing:
            parts.append(f'<li><a href="#{_anchor(r.get("model", "?"))}">{_e(record_id(r))}</a>: '
                         f'error {_e(fmt(r.get("error")))} &gt; tolerance '
                         f'{_e(fmt_tol(r.get("tolerance")))}</li>')
        parts.append("</ul>")
    for m in c.models:
        parts.append(_model_html(c, m))
    if c.other_bench:
        parts.append('<h2 id="bench-more">More from bench.json</h2>')
        for key, section in c.other_bench.items():
            parts.append(f"<h3>{_e(key)}</h3>")
            parts.append(_named_items_html(section))
    if c.sweep is not None:
        parts.append(_sweep_html(c))
    parts.append(report_sensitivity.html(c))
    parts.append(_footer_html(c))
    parts.append("</main></body></html>")
    return "\n".join(p for p in parts if p) + "\n"


# ---- sweep section (sweep.json of `crosscheck sweep`) ----------------------------------------
def _sweep_label(r: dict) -> str:
    return engine_label(r)


def _sweep_verdict(sw: dict) -> tuple[bool, str]:
    st = sw.get("status") or {}
    done = sum((st.get("completed") or {}).values())
    asked = sum((st.get("requested") or {}).values())
    ok = bool(st.get("passed"))
    text = (f"{done} of {asked} samples, {st.get('outside_tolerance', '?')} outside tolerance, "
            f"{st.get('faults', '?')} faults")
    if st.get("stopped"):
        text += f"; stopped: {st['stopped']}"
    return ok, text


def _sweep_rows(sw: dict, model: str) -> list[list]:
    """[label, quantity, count, max, q0.5, q0.99, tolerance, outside, worst index, status]."""
    out = []
    for r in sw.get("results", []):
        if r.get("model") != model:
            continue
        if r.get("skipped"):
            out.append([_sweep_label(r), r.get("quantity", "?"), 0, None, None, None, None,
                        None, None, "skip: " + str(r["skipped"])])
            continue
        q = r.get("quantiles") or {}
        worst = (r.get("worst") or [{}])[0]
        outside = r.get("outside_tolerance")
        st = "—" if outside is None else ("fail" if outside else "pass")
        out.append([_sweep_label(r), r.get("quantity", "?"), r.get("count"), r.get("max"),
                    q.get("0.5"), q.get("0.99"), r.get("tolerance"), outside,
                    worst.get("index"), st])
    return out


def _sweep_models(sw: dict) -> list[str]:
    return list(dict.fromkeys([r.get("model", "?") for r in sw.get("results", [])]
                              + [r.get("model", "?") for r in sw.get("series", [])]))


def _sweep_html(c: Content) -> str:
    from . import plots
    sw = c.sweep
    meta = sw.get("meta") or {}
    ok, verdict = _sweep_verdict(sw)
    out = ['<h2 id="sweep">Sweep</h2>',
           f'<p class="sub">seed {_e(meta.get("seed", "?"))}, {_e(meta.get("samples", "?"))} '
           f'samples per model from index {_e(meta.get("index", 0))}; sampler: '
           f'{_e(meta.get("sampler", "not recorded"))}</p>',
           f'<div class="banner {"ok" if ok else "bad"}">{_e(verdict)}</div>']
    headers = ["engine", "quantity", "samples", "max", "median", "q0.99", "tolerance",
               "outside", "worst sample", "status"]
    for m in _sweep_models(sw):
        out.append(f'<h3 id="sweep-{_anchor(m)}">{_e(m)}</h3>')
        for s in sw.get("series", []):
            if s.get("model") == m and s.get("unsupported"):
                out.append(f'<p class="note">{_e(_sweep_label(s))}: not run, the engine cannot '
                           f'represent the model: {_e(s["unsupported"])}</p>')
        rows = _sweep_rows(sw, m)
        if rows:
            body, classes = [], []
            for r in rows:
                status_cell = r[9]
                cls = "fail" if status_cell == "fail" else ("skip" if status_cell.startswith(
                    "skip") else "")
                body.append([_e(r[0]), _e(r[1]), _e(r[2]), _e(fmt(r[3])), _e(fmt(r[4])),
                             _e(fmt(r[5])), _e(fmt_tol(r[6])), _e("—" if r[7] is None else r[7]),
                             _e("—" if r[8] is None else r[8]),
                             f'<span class="reason">{_e(status_cell)}</span>'])
                classes.append(cls)
            out.append(_table(headers, body, classes, {2, 3, 4, 5, 6, 7, 8}))
        recs = [r for r in sw.get("results", []) if r.get("model") == m]
        out.append(_img(plots.sweep_histogram_svg(recs), f"sweep error histograms for {m}",
                        "Distribution of each quantity's error over the sweep's samples "
                        "(log-spaced bins, one line per engine; dashed: that engine's "
                        "tolerance). Exact zeros and values outside the binned range are "
                        "counted in the legend."))
        worst = [(r, w) for r in recs for w in (r.get("worst") or [])[:1]
                 if r.get("outside_tolerance")]
        if worst:
            out.append("<details><summary>reproduce the worst samples outside tolerance"
                       "</summary><pre>" + _e("\n".join(
                           f"# {_sweep_label(r)} {r.get('quantity')}: error {fmt(w.get('error'))}"
                           f"\n{(w.get('reproduce') or {}).get('sweep', '')}"
                           f"\n{(w.get('reproduce') or {}).get('eval', '')}"
                           for r, w in worst)) + "</pre></details>")
    faults = sw.get("faults") or {}
    groups = faults.get("groups") or []
    if groups or faults.get("chunks"):
        out.append("<h3>Faults</h3>")
        body = [[_e(g.get("model")), _e(_sweep_label(g)), _e(g.get("stage")), _e(g.get("type")),
                 _e(g.get("count")), _e(g.get("first_reason"))] for g in groups]
        body += [[_e(ch.get("model")), "—", "chunk", _e(ch.get("type")),
                  _e(f"[{ch.get('start')}, {ch.get('stop')})"), _e(ch.get("reason"))]
                 for ch in faults.get("chunks") or []]
        out.append(_table(["model", "engine", "stage", "type", "samples", "first reason"],
                          body, ["fail"] * len(body), {4}))
        cmds = [f"# {f.get('model')} {_sweep_label(f)} {f.get('stage')} sample "
                f"{f.get('index')}: {f.get('reason', '')[:120]}\n{f.get('reproduce', '')}"
                for f in faults.get("records") or []]
        if cmds:
            out.append("<details><summary>reproduce faulty samples (the first "
                       f"{_e(faults.get('kept_per_group', ''))} per group)</summary><pre>"
                       + _e("\n".join(cmds)) + "</pre></details>")
    return "\n".join(out)


def _sweep_md(c: Content) -> list[str]:
    sw = c.sweep
    meta = sw.get("meta") or {}
    ok, verdict = _sweep_verdict(sw)
    out = ["## Sweep", "", f"**{'pass' if ok else 'FAIL'}**: {verdict} (seed "
           f"{meta.get('seed', '?')}, {meta.get('samples', '?')} samples per model). "
           "Histograms are in `index.html`.", ""]
    for m in _sweep_models(sw):
        out += [f"### {m}", ""]
        for s in sw.get("series", []):
            if s.get("model") == m and s.get("unsupported"):
                out += [f"- {_sweep_label(s)}: not run: {s['unsupported']}"]
        rows = _sweep_rows(sw, m)
        if rows:
            out += [""] + _md_table(
                ["engine", "quantity", "samples", "max", "median", "q0.99", "tolerance",
                 "outside", "worst sample", "status"],
                [[r[0], r[1], r[2], fmt(r[3]), fmt(r[4]), fmt(r[5]), fmt_tol(r[6]),
                  "—" if r[7] is None else r[7], "—" if r[8] is None else r[8], r[9]]
                 for r in rows])
    groups = (sw.get("faults") or {}).get("groups") or []
    if groups:
        out += ["### Faults", ""] + _md_table(
            ["model", "engine", "stage", "type", "samples", "first reason"],
            [[g.get("model"), _sweep_label(g), g.get("stage"), g.get("type"), g.get("count"),
              g.get("first_reason")] for g in groups])
    return out


# ---- Markdown --------------------------------------------------------------------------------
def _md_cell(x) -> str:
    return str(x).replace("|", "\\|").replace("\n", " ")


def _md_table(headers, rows) -> list[str]:
    out = ["| " + " | ".join(_md_cell(h) for h in headers) + " |",
           "|" + "|".join("---" for _ in headers) + "|"]
    out += ["| " + " | ".join(_md_cell(c) for c in row) + " |" for row in rows]
    return out + [""]


def render_md(c: Content) -> str:
    n = c.counts
    out = ["# multibody-crosscheck report", ""]
    if c.records:
        verdict = (f"**{n['fail']} failing**" if n["fail"] else "**all executed checks pass**")
        out += [f"{verdict}: {n['pass']} passed, {n['fail']} failed, {n['skip']} skipped. "
                "Plots are in `index.html` beside this file.", ""]
    for r in c.failing:
        out.append(f"- FAIL `{record_id(r)}`: error {fmt(r.get('error'))} > tolerance "
                   f"{fmt_tol(r.get('tolerance'))}")
    if c.failing:
        out.append("")
    for m in c.models:
        source, title = model_info(m)
        out += [f"## {m}" + (f" — {title} ({source})" if title or source else ""), ""]
        recs = c.records_of(m)
        if recs:
            notes: list[str] = []
            rows = []
            for r in recs:
                st = status(r)
                reason = str(r.get("reason") or "")
                if st == "skip":
                    why = "skipped: " + (reason or "no reason given")
                else:
                    if reason and reason not in notes:
                        notes.append(reason)
                    why = f"[{notes.index(reason) + 1}]" if reason else ""
                extra = details(r)
                rows.append([st.upper(), r.get("formulation", ""), engine_label(r),
                             r.get("check", ""), r.get("quantity", ""), fmt(r.get("error")),
                             fmt_tol(r.get("tolerance")),
                             fmt(ratio_to_tolerance(r), 1) if st != "skip" else "—",
                             "; ".join(x for x in (why, extra) if x)])
            out += _md_table(["status", "formulation", "engine", "check", "quantity", "error",
                              "tolerance", "error/tol", "reason and details"], rows)
            out += [f"{i + 1}. {t}" for i, t in enumerate(notes)] + [""]
        note = c.series_note(m)
        if note:
            out += [f"Trajectories: {note}", ""]
        else:
            out += ["Trajectories:", ""]
            rows = []
            for s in c.series_of(m):
                st = _series_stats(s)
                from .plots import series_label
                rows.append([series_label(s), st["points"], f"{st['t_end']:g}",
                             fmt(st["state_error"]), fmt(st["residual"]), fmt(st["energy"])])
            out += _md_table(["series", "points", "t end [s]", "max state error",
                              "max residual", "max energy drift"], rows)
        if c.bench is not None:
            wp = c.work_precision_of(m)
            if wp:
                out += ["Work-precision:", ""]
                out += _md_table(["method", "engine", "setting", "wall [s]", "error", "residual",
                                  "energy drift", "nfev"], [wp_row(r) for r in wp])
            rows, anchors = c.timing_rows(m)
            if rows:
                out += ["Forward dynamics timings (ratios: median time per state over the "
                        "engine's, same bench run):", ""]
                headers = ["engine", "path", "batch", "µs/state (median)", "µs/state (min)"]
                headers += [f"× {label}" for label, _ in anchors.values()]
                out += _md_table(headers, [
                    [r.get("engine", ""), r.get("path", ""), r.get("batch", ""),
                     fmt_time(r.get("us_per_state")) if not r.get("skipped")
                     else f"skipped: {r['skipped']}", fmt_time(r.get("us_per_state_min"))]
                    + [fmt_ratio(ratios[k]) for k in anchors] for r, ratios in rows])
                if not anchors:
                    out += ["No engine was timed in this bench run: no ratios against "
                            "Pinocchio or MuJoCo.", ""]
    if c.other_bench:
        out += ["## More from bench.json", ""]
        for key, section in c.other_bench.items():
            out += [f"### {key}", ""]
            out += _md_table(["name", "status", "what", "notes"],
                             [[name, st, desc, "; ".join(notes)]
                              for name, st, _, desc, _, notes, _ in named_items(section)])
    if c.sweep is not None:
        out += _sweep_md(c)
    out += report_sensitivity.md(c)
    out += ["---", "", "Regenerate:", "", "```bash"] + c.regenerate() + ["```", ""]
    for label, m in c.meta_rows():
        v = _versions(m)
        out += [f"- {label}: `{m.get('command', 'not recorded')}` on {m.get('date', 'undated')}, "
                f"machine {_machine(m)}; " + ", ".join(f"{k} {v[k]}" for k in version_keys())]
    out += ["", "Generated by `crosscheck report`; do not edit by hand.", ""]
    return "\n".join(out)


# ---- JUnit -----------------------------------------------------------------------------------
def render_junit(c: Content) -> str:
    """One <testsuite> per model, one <testcase> per record."""
    meta = c.results.get("meta") or {}
    root = ET.Element("testsuites", name="crosscheck", tests=str(len(c.records)),
                      failures=str(c.counts["fail"]), skipped=str(c.counts["skip"]),
                      errors="0", time="0")
    for m in dict.fromkeys(r.get("model", "?") for r in c.records):
        recs = c.records_of(m)
        suite = ET.SubElement(root, "testsuite", name=f"crosscheck.{m}", tests=str(len(recs)),
                              failures=str(sum(status(r) == "fail" for r in recs)),
                              skipped=str(sum(status(r) == "skip" for r in recs)),
                              errors="0", time="0")
        props = ET.SubElement(suite, "properties")
        ET.SubElement(props, "property", name="command", value=str(meta.get("command", "")))
        ET.SubElement(props, "property", name="machine", value=_machine(meta))
        for k, v in _versions(meta).items():
            ET.SubElement(props, "property", name=k, value=str(v))
        for r in recs:
            tc = ET.SubElement(suite, "testcase",
                               classname=f"crosscheck.{m}.{r.get('engine', '?')}",
                               name=f"{r.get('formulation', '?')}.{r.get('check', '?')}."
                                    f"{r.get('quantity', '?')}", time="0")
            st = status(r)
            if st == "skip":
                ET.SubElement(tc, "skipped", message=str(r.get("reason") or "no reason given"))
            elif st == "fail":
                reason = str(r.get("reason") or "")
                f = ET.SubElement(tc, "failure", type="ToleranceExceeded",
                                  message=f"error {fmt(r.get('error'))} > tolerance "
                                          f"{fmt_tol(r.get('tolerance'))}"
                                          + (f": {reason}" if reason else ""))
                f.text = "\n".join(x for x in (
                    f"{record_id(r)}: error {r.get('error')!r}, tolerance "
                    f"{r.get('tolerance')!r}", f"tolerance reason: {reason}" if reason else "",
                    details(r)) if x)
            elif details(r):
                ET.SubElement(tc, "system-out").text = details(r)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


# ---- entry points ----------------------------------------------------------------------------
def write_report(results: dict | None, bench: dict | None, out_dir: str | Path, command: str,
                 results_path: str | None = None, bench_path: str | None = None,
                 sweep: dict | None = None, sweep_path: str | None = None,
                 outputs=None) -> dict:
    """Write index.html, report.md and junit.xml into out_dir; returns their paths.

    The files are staged and renamed into place together (crosscheck.output), so an interrupt
    leaves the previous report or this one, never a mix; with `outputs` given (a run staging
    its results.json too) they are only staged, and the caller commits them all at once."""
    from .output import Outputs
    c = Content(results, bench, command, results_path, bench_path, sweep, sweep_path)
    names = {"html": "index.html", "md": "report.md", "junit": "junit.xml"}
    if results is None:
        names.pop("junit")
    renderers = {"html": render_html, "md": render_md, "junit": render_junit}
    if outputs is not None:
        for key, name in names.items():
            outputs.stage(name, renderers[key](c))
        return {k: outputs.path(v) for k, v in names.items()}
    with Outputs(out_dir) as staged:
        for key, name in names.items():
            staged.stage(name, renderers[key](c))
        staged.commit(stale=("junit.xml",))  # no results: an old junit.xml is not this one
    return {k: staged.path(v) for k, v in names.items()}


def generate(results_path: str | None, bench_path: str | None, out_dir: str,
             sweep_path: str | None = None, outputs=None, results_text: str | None = None
             ) -> dict:
    """Load and check the inputs, then write the report (`run` calls this with its staged
    outputs and the results.json text it is about to commit)."""
    if results_text is not None:
        results = check_results(json.loads(results_text), results_path)
    else:
        results = check_results(load_json(results_path, "results"), results_path) \
            if results_path else None
    bench = check_bench(load_json(bench_path, "bench"), bench_path) if bench_path else None
    sweep = check_sweep(load_json(sweep_path, "sweep"), sweep_path) if sweep_path else None
    argv = ["crosscheck", "report"]
    if results_path:
        argv += ["--results", str(results_path)]
    if bench_path:
        argv += ["--bench", str(bench_path)]
    if sweep_path:
        argv += ["--sweep", str(sweep_path)]
    argv += ["--out", str(out_dir)]
    return write_report(results, bench, out_dir, shlex.join(argv), results_path, bench_path,
                        sweep, sweep_path, outputs)


def cmd_report(args) -> int:
    results_path = args.results
    sweep_path = getattr(args, "sweep", None)
    if results_path is None:
        results_path = DEFAULT_RESULTS
        if not Path(results_path).is_file():
            if args.bench is None and sweep_path is None:
                raise ReportInputError(f"no results file: {DEFAULT_RESULTS} does not exist "
                                       f"(run `crosscheck run` first, or give --results FILE)")
            results_path = None  # a benchmark-only report
    bench_path = args.bench
    if bench_path is None and results_path is not None:
        beside = Path(results_path).parent / "bench.json"  # the same --out of run and bench
        if beside.is_file():
            bench_path = str(beside)
    if sweep_path is None and results_path is not None:
        beside = Path(results_path).parent / "sweep.json"  # the same --out of run and sweep
        if beside.is_file():
            sweep_path = str(beside)
    out_dir = args.out or str(Path(results_path or bench_path or sweep_path).parent)
    from .arguments import output_dir
    output_dir(out_dir)
    paths = generate(results_path, bench_path, out_dir, sweep_path)
    print("crosscheck report: " + ", ".join(str(p) for p in paths.values()))
    return 0


def register(sub):
    r = sub.add_parser("report", help="HTML, Markdown and JUnit reports from results/bench JSON",
                       description="Write DIR/index.html (self-contained), DIR/report.md and "
                                   "DIR/junit.xml from a results.json and an optional bench.json.")
    r.add_argument("--results", default=None, metavar="FILE",
                   help=f"results.json from `crosscheck run` (default: {DEFAULT_RESULTS})")
    r.add_argument("--bench", default=None, metavar="FILE",
                   help="bench.json from `crosscheck bench` (default: bench.json beside the "
                        "results file, when it exists)")
    r.add_argument("--sweep", default=None, metavar="FILE",
                   help="sweep.json from `crosscheck sweep`: error histograms per quantity "
                        "(default: sweep.json beside the results file, when it exists)")
    r.add_argument("--out", default=None, metavar="DIR",
                   help="output directory (default: the results file's directory)")
    r.set_defaults(func=cmd_report)
