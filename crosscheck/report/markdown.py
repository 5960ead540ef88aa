"""The report as Markdown (report.md); see crosscheck.report.write."""

from __future__ import annotations

from crosscheck.report.content import (
    CHECK_HEADERS,
    SWEEP_HEADERS,
    Content,
    details,
    energy_heading,
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
    sweep_label,
    sweep_models,
    sweep_rows,
    sweep_verdict,
    version_keys,
    versions_of,
    wp_row,
)
from crosscheck.report.markdown_table import md_table
from crosscheck.report.sections import agreement as report_agreement
from crosscheck.report.sections import sensitivity as report_sensitivity


def _sweep_md(c: Content) -> list[str]:
    sw = c.sweep
    meta = sw.get("meta") or {}
    ok, verdict = sweep_verdict(sw)
    out = [
        "## Sweep",
        "",
        f"**{'pass' if ok else 'FAIL'}**: {verdict} (seed "
        f"{meta.get('seed', '?')}, {meta.get('samples', '?')} samples per model). "
        "Histograms are in `index.html`.",
        "",
    ]
    for m in sweep_models(sw):
        out += [f"### {m}", ""]
        for s in sw.get("series", []):
            if s.get("model") == m and s.get("unsupported"):
                out += [f"- {sweep_label(s)}: not run: {s['unsupported']}"]
        rows = sweep_rows(sw, m)
        if rows:
            out += [
                "",
                *md_table(
                    SWEEP_HEADERS,
                    [
                        [
                            r[0],
                            r[1],
                            r[2],
                            fmt(r[3]),
                            fmt(r[4]),
                            fmt(r[5]),
                            fmt_tol(r[6]),
                            "—" if r[7] is None else r[7],
                            "—" if r[8] is None else r[8],
                            r[9],
                        ]
                        for r in rows
                    ],
                ),
            ]
    groups = (sw.get("faults") or {}).get("groups") or []
    if groups:
        out += [
            "### Faults",
            "",
            *md_table(
                ["model", "engine", "stage", "type", "samples", "first reason"],
                [
                    [
                        g.get("model"),
                        sweep_label(g),
                        g.get("stage"),
                        g.get("type"),
                        g.get("count"),
                        g.get("first_reason"),
                    ]
                    for g in groups
                ],
            ),
        ]
    return out


# ---- Markdown --------------------------------------------------------------------------------


def _checks_md(c: Content, m: str) -> list[str]:
    """One model's checks table, reasons as numbered notes under it."""
    out: list[str] = []
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
            rows.append(
                [
                    st.upper(),
                    r.get("formulation", ""),
                    engine_label(r),
                    r.get("check", ""),
                    r.get("quantity", ""),
                    fmt(r.get("error")),
                    fmt_tol(r.get("tolerance")),
                    fmt(ratio_to_tolerance(r), 1) if st != "skip" else "—",
                    "; ".join(x for x in (why, extra) if x),
                ]
            )
        out += md_table(CHECK_HEADERS, rows)
        out += [f"{i + 1}. {t}" for i, t in enumerate(notes)] + [""]
    return out


def _trajectories_md(c: Content, m: str) -> list[str]:
    out: list[str] = []
    note = c.series_note(m)
    if note:
        out += [f"Trajectories: {note}", ""]
    else:
        out += ["Trajectories:", ""]
        rows = []
        for s in c.series_of(m):
            st = series_stats(s)
            from crosscheck.report.plots import series_label

            rows.append(
                [
                    series_label(s),
                    st["points"],
                    f"{st['t_end']:g}",
                    fmt(st["state_error"]),
                    fmt(st["residual"]),
                    fmt(st["energy"]),
                ]
            )
        out += md_table(
            [
                "series",
                "points",
                "t end [s]",
                "max state error",
                "max residual",
                energy_heading(c.series_of(m)),
            ],
            rows,
        )
    return out


def _bench_md(c: Content, m: str) -> list[str]:
    """One model's work-precision rows and forward-dynamics timings from bench.json."""
    out: list[str] = []
    wp = c.work_precision_of(m)
    if wp:
        out += ["Work-precision:", ""]
        out += md_table(
            [
                "method",
                "engine",
                "setting",
                "wall [s]",
                "error",
                "residual",
                "energy drift",
                "nfev",
            ],
            [wp_row(r) for r in wp],
        )
    rows, anchors = c.timing_rows(m)
    if rows:
        out += [
            "Forward dynamics timings (ratios: median time per state over the "
            "engine's, same bench run):",
            "",
        ]
        headers = ["engine", "path", "batch", "µs/state (median)", "µs/state (min)"]
        headers += [f"× {label}" for label, _ in anchors.values()]
        out += md_table(
            headers,
            [
                [
                    r.get("engine", ""),
                    r.get("path", ""),
                    r.get("batch", ""),
                    fmt_time(r.get("us_per_state"))
                    if not r.get("skipped")
                    else f"skipped: {r['skipped']}",
                    fmt_time(r.get("us_per_state_min")),
                ]
                + [fmt_ratio(ratios[k]) for k in anchors]
                for r, ratios in rows
            ],
        )
        if not anchors:
            out += [
                "No engine was timed in this bench run: no ratios against Pinocchio or MuJoCo.",
                "",
            ]
    return out


def render_md(c: Content) -> str:
    n = c.counts
    out = ["# multibody-crosscheck report", ""]
    if c.records:
        verdict = f"**{n['fail']} failing**" if n["fail"] else "**all executed checks pass**"
        out += [
            f"{verdict}: {n['pass']} passed, {n['fail']} failed, {n['skip']} skipped. "
            "Plots are in `index.html` beside this file.",
            "",
        ]
    for r in c.failing:
        out.append(
            f"- FAIL `{record_id(r)}`: error {fmt(r.get('error'))} > tolerance "
            f"{fmt_tol(r.get('tolerance'))}"
        )
    if c.failing:
        out.append("")
    for m in c.models:
        source, title = model_info(m)
        out += [f"## {m}" + (f" — {title} ({source})" if title or source else ""), ""]
        out += _checks_md(c, m)
        out += report_agreement.md(c, m)
        out += _trajectories_md(c, m)
        if c.bench is not None:
            out += _bench_md(c, m)
    if c.other_bench:
        out += ["## More from bench.json", ""]
        for key, section in c.other_bench.items():
            out += [f"### {key}", ""]
            out += md_table(
                ["name", "status", "what", "notes"],
                [
                    [name, st, desc, "; ".join(notes)]
                    for name, st, _, desc, _, notes, _ in named_items(section)
                ],
            )
    if c.sweep is not None:
        out += _sweep_md(c)
    out += report_sensitivity.md(c)
    out += _footer_md(c)
    return "\n".join(out)


def _footer_md(c: Content) -> list[str]:
    out = ["---", "", "Regenerate:", "", "```bash", *c.regenerate(), "```", ""]
    for label, m in c.meta_rows():
        v = versions_of(m)
        out += [
            f"- {label}: `{m.get('command', 'not recorded')}` on {m.get('date', 'undated')}, "
            f"machine {machine_text(m)}; " + ", ".join(f"{k} {v[k]}" for k in version_keys())
        ]
    out += ["", "Generated by `crosscheck report`; do not edit by hand.", ""]
    return out
