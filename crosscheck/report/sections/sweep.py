"""The report's sweep section: DIR/sweep.json of `crosscheck sweep`, as HTML (its Markdown is
in report_md)."""

from __future__ import annotations

from crosscheck.report.content import (
    SWEEP_HEADERS,
    fmt,
    fmt_tol,
    sweep_label,
    sweep_models,
    sweep_rows,
    sweep_verdict,
)
from crosscheck.report.html_parts import anchor, e, img, table


def html(c) -> str:
    """The sweep section: verdict, per-model quantiles and histograms, faults."""

    sw = c.sweep
    meta = sw.get("meta") or {}
    ok, verdict = sweep_verdict(sw)
    out = [
        '<h2 id="sweep">Sweep</h2>',
        f'<p class="sub">seed {e(meta.get("seed", "?"))}, {e(meta.get("samples", "?"))} '
        f"samples per model from index {e(meta.get('index', 0))}; sampler: "
        f"{e(meta.get('sampler', 'not recorded'))}</p>",
        f'<div class="banner {"ok" if ok else "bad"}">{e(verdict)}</div>',
    ]
    for m in sweep_models(sw):
        out += _model(sw, m)
    out += _faults(sw)
    return "\n".join(out)


def _model(sw: dict, m: str) -> list[str]:
    """One model's quantile table, histogram and the worst samples' commands."""
    from crosscheck.report import plots

    out = []
    out.append(f'<h3 id="sweep-{anchor(m)}">{e(m)}</h3>')
    for s in sw.get("series", []):
        if s.get("model") == m and s.get("unsupported"):
            out.append(
                f'<p class="note">{e(sweep_label(s))}: not run, the engine cannot '
                f"represent the model: {e(s['unsupported'])}</p>"
            )
    rows = sweep_rows(sw, m)
    if rows:
        body, classes = [], []
        for r in rows:
            status_cell = r[9]
            cls = (
                "fail"
                if status_cell == "fail"
                else ("skip" if status_cell.startswith("skip") else "")
            )
            body.append(
                [
                    e(r[0]),
                    e(r[1]),
                    e(r[2]),
                    e(fmt(r[3])),
                    e(fmt(r[4])),
                    e(fmt(r[5])),
                    e(fmt_tol(r[6])),
                    e("—" if r[7] is None else r[7]),
                    e("—" if r[8] is None else r[8]),
                    f'<span class="reason">{e(status_cell)}</span>',
                ]
            )
            classes.append(cls)
        out.append(table(SWEEP_HEADERS, body, classes, {2, 3, 4, 5, 6, 7, 8}))
    recs = [r for r in sw.get("results", []) if r.get("model") == m]
    out.append(
        img(
            plots.sweep_histogram_svg(recs),
            f"sweep error histograms for {m}",
            "Distribution of each quantity's error over the sweep's samples "
            "(log-spaced bins, one line per engine; dashed: that engine's "
            "tolerance). Exact zeros and values outside the binned range are "
            "counted in the legend.",
        )
    )
    worst = [(r, w) for r in recs for w in (r.get("worst") or [])[:1] if r.get("outside_tolerance")]
    if worst:
        out.append(
            "<details><summary>reproduce the worst samples outside tolerance"
            "</summary><pre>"
            + e(
                "\n".join(
                    f"# {sweep_label(r)} {r.get('quantity')}: error {fmt(w.get('error'))}"
                    f"\n{(w.get('reproduce') or {}).get('sweep', '')}"
                    f"\n{(w.get('reproduce') or {}).get('eval', '')}"
                    for r, w in worst
                )
            )
            + "</pre></details>"
        )
    return out


def _faults(sw: dict) -> list[str]:
    """Fault groups (and chunks that failed whole) with the commands that reproduce them."""
    out: list[str] = []
    faults = sw.get("faults") or {}
    groups = faults.get("groups") or []
    if groups or faults.get("chunks"):
        out.append("<h3>Faults</h3>")
        body = [
            [
                e(g.get("model")),
                e(sweep_label(g)),
                e(g.get("stage")),
                e(g.get("type")),
                e(g.get("count")),
                e(g.get("first_reason")),
            ]
            for g in groups
        ]
        body += [
            [
                e(ch.get("model")),
                "—",
                "chunk",
                e(ch.get("type")),
                e(f"[{ch.get('start')}, {ch.get('stop')})"),
                e(ch.get("reason")),
            ]
            for ch in faults.get("chunks") or []
        ]
        out.append(
            table(
                ["model", "engine", "stage", "type", "samples", "first reason"],
                body,
                ["fail"] * len(body),
                {4},
            )
        )
        cmds = [
            f"# {f.get('model')} {sweep_label(f)} {f.get('stage')} sample "
            f"{f.get('index')}: {f.get('reason', '')[:120]}\n{f.get('reproduce', '')}"
            for f in faults.get("records") or []
        ]
        if cmds:
            out.append(
                "<details><summary>reproduce faulty samples (the first "
                f"{e(faults.get('kept_per_group', ''))} per group)</summary><pre>"
                + e("\n".join(cmds))
                + "</pre></details>"
            )
    return out
