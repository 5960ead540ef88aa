"""The report as one self-contained HTML page (index.html); see crosscheck.report.write."""

from __future__ import annotations

import json

from crosscheck.report.content import (
    CHECK_HEADERS,
    Content,
    ReportInputError,
    conserves_energy,
    details,
    energy_heading,
    engine_anchors,
    engine_label,
    fmt,
    fmt_ratio,
    fmt_time,
    fmt_tol,
    machine_text,
    model_info,
    named_items,
    ratio_to_tolerance,
    record_id,
    series_stats,
    status,
    version_keys,
    versions_of,
    wp_row,
)
from crosscheck.report.html_parts import anchor, e, img, table
from crosscheck.report.sections import agreement as report_agreement
from crosscheck.report.sections import sensitivity as report_sensitivity
from crosscheck.report.sections import sweep as report_sweep

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
details.model>summary{cursor:pointer;list-style-position:outside;margin-top:2em}
details.model>summary h2{display:inline;margin:0;border:0}
details.model{border-bottom:2px solid #ddd;padding-bottom:.4em}
.note{color:#555;font-size:.88em}.reason{color:#444;font-size:.92em}
ol.notes{font-size:.8em;color:#444;margin-top:0}ol.notes li{margin:.15em 0}
figure{margin:.6em 0 1.2em}figure img{max-width:100%;height:auto;border:1px solid #eee}
figcaption{font-size:.82em;color:#555;max-width:60em}
nav{display:flex;flex-wrap:wrap;gap:.25em 1em;margin:.4em 0}
footer{margin-top:3em;border-top:2px solid #ddd;padding-top:.6em;font-size:.85em;color:#333}
pre{background:#f5f5f5;padding:8px 10px;overflow-x:auto;font-size:.92em}
code{font-family:ui-monospace,"DejaVu Sans Mono",monospace}
"""


# a link to a folded model (the overview, the failing checks) opens its section; without
# script the section's summary line is still where the link lands
_UNFOLD_ON_LINK = """<script>
function unfold(){var t=location.hash&&document.getElementById(location.hash.slice(1));
var d=t&&t.closest("details");if(d){d.open=true;t.scrollIntoView();}}
addEventListener("hashchange",unfold);unfold();
</script>"""


def _named_items_html(section) -> str:
    rows, classes = [], []
    for name, st, cls, desc, crit, notes, rest in named_items(section):
        rest_html = (
            f"<details><summary>details</summary><pre>"
            f"{e(json.dumps(rest, indent=1, allow_nan=True))}</pre></details>"
            if rest
            else ""
        )
        rows.append(
            [
                f"<b>{e(name)}</b>",
                f'<span class="badge {cls}">{e(st)}</span>' if st else "",
                e(desc) + (f'<br><span class="note">criterion: {e(crit)}</span>' if crit else ""),
                "<br>".join(e(n) for n in notes),
                rest_html,
            ]
        )
        classes.append("fail" if cls == "fail" else "")
    if not rows:
        return '<p class="note">(empty)</p>'
    return table(["name", "status", "what", "notes", "figures"], rows, classes)


def _checks_html(c: Content, model: str, recs: list[dict]) -> str:
    notes: list[str] = []
    rows, classes = [], []
    for r in recs:
        st = status(r)
        reason = str(r.get("reason") or "")
        if st == "skip":
            why = f'<span class="reason">skipped: {e(reason or "no reason given")}</span>'
        else:
            if reason and reason not in notes:
                notes.append(reason)
            why = (
                f'<a href="#{anchor(model)}-n{notes.index(reason) + 1}">'
                f"[{notes.index(reason) + 1}]</a>"
                if reason
                else ""
            )
        extra = details(r)
        label = {"pass": "PASS", "fail": "FAIL", "skip": "SKIP"}[st]
        rows.append(
            [
                f'<span class="badge {st}">{label}</span>',
                e(r.get("formulation", "")),
                e(engine_label(r)),
                e(r.get("check", "")),
                e(r.get("quantity", "")),
                e(fmt(r.get("error"))),
                e(fmt_tol(r.get("tolerance"))),
                e(fmt(ratio_to_tolerance(r), 1)) if st != "skip" else "—",
                why
                + (
                    ("<br>" if why else "") + f'<span class="note">{e(extra)}</span>'
                    if extra
                    else ""
                ),
            ]
        )
        classes.append(st)
    out = table(
        CHECK_HEADERS,
        rows,
        classes,
        {5, 6, 7},
    )
    if notes:
        out += (
            '<p class="note" style="margin-bottom:0">Tolerances and their reasons:</p>'
            '<ol class="notes">'
            + "".join(f'<li id="{anchor(model)}-n{i + 1}">{e(n)}</li>' for i, n in enumerate(notes))
            + "</ol>"
        )
    return out


def _timing_html(c: Content, model: str) -> str:
    rows, anchors = c.timing_rows(model)
    if not rows:
        return ""
    headers = ["engine", "path", "batch", "µs / state (median)", "µs / state (min)"]
    headers += [f"× {label}" for _, (label, _) in anchors.items()]
    body, classes = [], []
    for r, ratios in rows:
        skipped = r.get("skipped")
        line = [
            e(r.get("engine", "")),
            e(r.get("path", "")),
            e(r.get("batch", "")),
            e(fmt_time(r.get("us_per_state")))
            if not skipped
            else f'<span class="reason">skipped: {e(skipped)}</span>',
            e(fmt_time(r.get("us_per_state_min"))),
        ]
        line += [e(fmt_ratio(ratios[k])) for k in anchors]
        body.append(line)
        classes.append("skip" if skipped else "")
    num = set(range(2, len(headers)))
    out = table(headers, body, classes, num)
    if anchors:
        names = " and ".join(label for label, _ in anchors.values())
        out += (
            f'<p class="note">× {names}: this path\'s median time per state divided by the '
            f"engine's constrained forward call at the same state, both measured in the same "
            f"bench run (so the ratio, not the absolute time, is what carries over between "
            f"machines; &lt; 1× means faster than the engine).</p>"
        )
    else:
        out += (
            '<p class="note">No engine was timed in this bench run, so there are no ratios '
            f"against {' or '.join(label for _, label in engine_anchors())} (run "
            f"<code>crosscheck bench --engines "
            f"{','.join(e for e, _ in engine_anchors())}</code>).</p>"
        )
    return out


def _work_precision_html(c: Content, model: str) -> str:
    from crosscheck.report import plots

    rows = c.work_precision_of(model)
    if not rows:
        if c.bench is None:
            return ""
        return (
            '<p class="note">No work-precision data for this model in bench.json '
            '("work_precision" has no rows for it).</p>'
        )
    out = [
        img(
            plots.work_precision_svg(rows),
            f"work-precision diagram for {model}",
            "Wall time against the error at the end of the run (and the largest constraint "
            "residual and energy drift where recorded), log-log; one line per method and "
            "engine, points along the tolerance or step-size ladder. Lower left is better.",
        )
    ]
    keys = ["method", "engine", "setting", "wall [s]", "error", "residual", "energy drift", "nfev"]
    body = [[e(v) for v in wp_row(r)] for r in rows]
    points = table(keys, body, None, {3, 4, 5, 6, 7})
    if len(rows) > 12:  # long ladders fold away under the diagram
        points = f"<details><summary>table of the {len(rows)} points</summary>{points}</details>"
    out.append(points)
    return "\n".join(out)


def _trajectory_html(c: Content, model: str) -> str:
    from crosscheck.report import plots

    note = c.series_note(model)
    if note:
        return f'<p class="note">{e(note)}</p>'
    ss = c.series_of(model)
    out = [img(plots.trajectory_svg(ss), f"trajectories of {model}", _trajectory_caption(ss))]
    body = []
    for s in ss:
        st = series_stats(s)
        body.append(
            [
                e(plots.series_label(s)),
                e(st["points"]),
                e(f"{st['t_end']:g}"),
                e(fmt(st["state_error"])),
                e(fmt(st["residual"])),
                e(fmt(st["energy"])),
            ]
        )
    out.append(
        table(
            [
                "series",
                "points",
                "t end [s]",
                "max state error",
                "max residual",
                energy_heading(ss),
            ],
            body,
            None,
            {1, 2, 3, 4, 5},
        )
    )
    return "\n".join(out)


# a page with more models than this shows each passing model folded (its summary line stays);
# a model with a failing check is always unfolded
UNFOLDED_MODELS = 3


_PANEL_TEXT = {
    "state_error": "the state's difference from the reference trajectory",
    "residual": "the largest position-constraint violation |f(q, t)|",
    "energy": "the energy drift |E − E(0)| / max(max |E|, 1)",
}
_BALANCE_TEXT = (
    "the work-energy balance |E − E(0) − W| / max(max |E|, 1) (energy is not "
    "conserved here: W is the work of loads and moving constraints)"
)


def _trajectory_caption(series: list[dict]) -> str:
    """Names exactly the panels drawn; a quantity exactly 0 in every line has no panel."""
    from crosscheck.report import plots

    drawn = [k for k, _ in plots.trajectory_panels(series)]
    texts = [
        (_BALANCE_TEXT if k == "energy" and not conserves_energy(series) else _PANEL_TEXT[k])
        for k in drawn
    ]
    listed = ", ".join(texts[:-1]) + (" and " if len(texts) > 1 else "") + texts[-1]
    absent = [_PANEL_TEXT[k].removeprefix("the ") for k in _PANEL_TEXT if k not in drawn]
    note = f" No panel for {' or '.join(absent)}: exactly 0 in every line." if absent else ""
    return (
        f"Against time, log scale: {listed}. A line that is exactly 0 throughout is named "
        f"in its panel; other zeros are drawn at {plots.ZERO_AT:.0e}.{note}"
    )


def _model_html(c: Content, model: str) -> str:
    """One model's section: a <details> whose summary is its heading and verdict, folded on a
    long page unless a check failed (no script needed; one opens it on a link, below)."""
    from crosscheck.report import plots

    source, title = model_info(model)
    recs = c.records_of(model)
    n = {k: sum(1 for r in recs if status(r) == k) for k in ("pass", "fail", "skip")}
    head = f'<h2 id="{anchor(model)}">{e(model)}'
    if title or source:
        src = f" ({e(source)})" if source else ""
        head += f' <span class="sub">— {e(title)}{src}</span>'
    head += "</h2>"
    verdict = (
        f'<span class="sub"> · {n["pass"]} passed, {n["fail"]} failed, {n["skip"]} skipped</span>'
        if recs
        else ""
    )
    unfold = n["fail"] > 0 or len(c.models) <= UNFOLDED_MODELS
    out = [f'<details class="model"{" open" if unfold else ""}><summary>{head}{verdict}</summary>']
    if recs:
        out.append("<h3>Checks</h3>")
        out.append(_checks_html(c, model, recs))
        out.append("<h3>Agreement</h3>")
        out.append(
            img(
                plots.agreement_svg(recs),
                f"agreement plot for {model}",
                "Each executed check's error (dot, one colour per engine) beside its "
                "tolerance (black bar), log scale: a dot left of its bar passes. Failing "
                "checks are ringed in red; skipped checks are named in grey.",
            )
        )
        matrix = report_agreement.html(c, model)
        if matrix:
            out.append("<h3>Engine against engine</h3>")
            out.append(matrix)
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
    out.append("</details>")
    return "\n".join(out)


def _footer_html(c: Content) -> str:
    out = [
        '<footer id="footer"><h3>Regenerate</h3><pre><code>'
        + e("\n".join(c.regenerate()))
        + "</code></pre>"
    ]
    metas = c.meta_rows()
    if metas:
        headers = [""] + [label for label, _ in metas]
        rows = [
            ["command"] + [f"<code>{e(m.get('command', 'not recorded'))}</code>" for _, m in metas],
            ["date (UTC)"] + [e(m.get("date", "not recorded")) for _, m in metas],
            ["machine"] + [e(machine_text(m)) for _, m in metas],
        ]
        for k in version_keys():
            rows.append([k] + [e(versions_of(m)[k]) for _, m in metas])
        out.append("<h3>Machine and versions</h3>")
        out.append(table(headers, rows))
    out.append(
        '<p class="note">Generated by <code>crosscheck report</code> from the files above; '
        "do not edit by hand.</p></footer>"
    )
    return "\n".join(out)


def _banner(c: Content) -> str:
    """The verdict line under the title."""
    n = c.counts
    executed = n["pass"] + n["fail"]
    if c.records:
        if n["fail"]:
            return (
                f'<div class="banner bad">{n["fail"]} of {executed} executed checks FAIL '
                f"({n['pass']} passed, {n['skip']} skipped)</div>"
            )
        return (
            f'<div class="banner ok">All {executed} executed checks pass '
            f"({n['skip']} skipped)</div>"
        )
    if c.sweep is not None and c.bench is None:
        return '<div class="banner ok">No cross-check results given: sweep only</div>'
    return '<div class="banner ok">No cross-check results given: benchmarks only</div>'


def _sources(c: Content) -> str:
    """Which files the page shows, with their dates."""
    sources = []
    if c.results_path is not None:
        sources.append(
            f"results <code>{e(c.results_path)}</code> "
            f"({e((c.results.get('meta') or {}).get('date', 'undated'))})"
        )
    if c.bench_path is not None:
        sources.append(
            f"bench <code>{e(c.bench_path)}</code> "
            f"({e((c.bench.get('meta') or {}).get('date', 'undated'))})"
        )
    if c.sweep_path is not None:
        sources.append(
            f"sweep <code>{e(c.sweep_path)}</code> "
            f"({e((c.sweep.get('meta') or {}).get('date', 'undated'))})"
        )
    return " · ".join(sources)


def _overview(c: Content) -> list[str]:
    """The per-model overview table and the list of failing checks."""
    parts: list[str] = []
    headers = ["model", "passed", "failed", "skipped", "engines"]
    headers += ["trajectories"] if c.series is not None else []
    headers += ["forward timings", "work-precision points"] if c.bench is not None else []
    overview = []
    for m in c.models:
        recs = c.records_of(m)
        k = {s: sum(1 for r in recs if status(r) == s) for s in ("pass", "fail", "skip")}
        engines = ", ".join(dict.fromkeys(r.get("engine", "?") for r in recs))
        row = [
            f'<a href="#{anchor(m)}">{e(m)}</a>',
            str(k["pass"]),
            f"<b>{k['fail']}</b>" if k["fail"] else "0",
            str(k["skip"]),
            e(engines),
        ]
        row += [str(len(c.series_of(m)))] if c.series is not None else []
        row += (
            [str(len(c.forward_of(m))), str(len(c.work_precision_of(m)))]
            if c.bench is not None
            else []
        )
        overview.append(row)
    if overview:
        parts.append("<h3>Overview</h3>")
        parts.append(
            table(
                headers,
                overview,
                ["fail" if "<b>" in row[2] else "" for row in overview],
                {1, 2, 3} | set(range(5, len(headers))),
            )
        )
    if c.failing:
        parts.append("<h3>Failing checks</h3><ul>")
        for r in c.failing:
            parts.append(
                f'<li><a href="#{anchor(r.get("model", "?"))}">{e(record_id(r))}</a>: '
                f"error {e(fmt(r.get('error')))} &gt; tolerance "
                f"{e(fmt_tol(r.get('tolerance')))}</li>"
            )
        parts.append("</ul>")
    return parts


def render_html(c: Content) -> str:
    try:  # fail before writing anything, with one line, if the plotting library is missing
        import matplotlib  # noqa: F401
    except ImportError:
        raise ReportInputError(
            "the report's plots need matplotlib (a dependency of this package: pip install -e .)"
        ) from None
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        "<title>multibody-crosscheck report</title>",
        f"<style>{CSS}</style></head>",
        "<body><main>",
        "<h1>multibody-crosscheck report</h1>",
        f'<p class="sub">{_sources(c)}</p>',
        _banner(c),
    ]
    if c.models:
        parts.append(
            "<nav>"
            + "".join(f'<a href="#{anchor(m)}">{e(m)}</a>' for m in c.models)
            + ('<a href="#bench-more">more from bench.json</a>' if c.other_bench else "")
            + ('<a href="#sweep">sweep</a>' if c.sweep is not None else "")
            + '<a href="#footer">versions</a></nav>'
        )
    parts += _overview(c)
    for m in c.models:
        parts.append(_model_html(c, m))
    if c.other_bench:
        parts.append('<h2 id="bench-more">More from bench.json</h2>')
        for key, section in c.other_bench.items():
            parts.append(f"<h3>{e(key)}</h3>")
            parts.append(_named_items_html(section))
    if c.sweep is not None:
        parts.append(report_sweep.html(c))
    parts.append(report_sensitivity.html(c))
    parts.append(_footer_html(c))
    parts.append(_UNFOLD_ON_LINK)
    parts.append("</main></body></html>")
    return "\n".join(p for p in parts if p) + "\n"
