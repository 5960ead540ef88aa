"""The report's sweep section: DIR/sweep.json of `crosscheck sweep`, as HTML (its Markdown is
in report_md)."""

from __future__ import annotations

import math

from crosscheck.report.content import (
    SWEEP_HEADERS,
    fmt,
    fmt_tol,
    sweep_label,
    sweep_models,
    sweep_rows,
    sweep_verdict,
    to_float,
)
from crosscheck.report.html_parts import anchor, e, img, table
from crosscheck.report.plots import axes_style, engine_color, svg_text


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
            histogram_svg(recs),
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


def histogram_svg(rows: list[dict], title: str = "") -> str | None:
    """Error histograms of one model's sweep, one panel per quantity, one step line per engine
    (and variant), from the log10 histograms in sweep.json; each engine's tolerance is a dashed
    line in its colour.
    Exact zeros, values outside the binned range and non-finite values are counted in the
    legend (a log axis cannot place them)."""
    rows = [r for r in rows if isinstance(r.get("histogram"), dict) and r.get("count")]
    if not rows:
        return None
    quantities = list(dict.fromkeys(r.get("quantity", "?") for r in rows))
    engines = list(dict.fromkeys(r.get("engine", "?") for r in rows))
    ncols = 2 if len(quantities) > 1 else 1
    nrows = math.ceil(len(quantities) / ncols)
    height = 0.6 + 2.1 * nrows
    from matplotlib.backends.backend_svg import FigureCanvasSVG
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.6, height))  # fixed margins: constrained layout doubles the cost
    FigureCanvasSVG(fig)
    top = 0.35 + (0.25 if title else 0.0)
    fig.subplots_adjust(
        left=0.075, right=0.985, top=1 - top / height, bottom=0.45 / height, hspace=0.5, wspace=0.2
    )
    axes = fig.subplots(nrows, ncols, squeeze=False)
    styles = ["-", "--", ":", "-."]
    for ax in axes.flat[len(quantities) :]:
        ax.set_visible(False)
    for ax, qn in zip(axes.flat[: len(quantities)], quantities, strict=True):
        axes_style(ax)
        ax.set_xscale("log")
        ax.set_title(qn, fontsize=8.5, loc="left")
        tols = set()
        span: list[float] = []  # edges of the non-empty bins, to zoom on them
        variants: dict[str, list] = {}
        for r in (r for r in rows if r.get("quantity") == qn):
            h = r["histogram"]
            lo, step = to_float(h.get("log10_lo")), to_float(h.get("log10_step"))
            counts = [int(c) for c in h.get("counts", [])]
            eng = r.get("engine", "?")
            var = r.get("variant")
            vlist = variants.setdefault(eng, [])
            if var not in vlist:
                vlist.append(var)
            top = lo + len(counts) * step
            if not (math.isfinite(lo) and math.isfinite(step) and -300 < lo and top < 300):
                continue  # bins off any log axis: the table has the counts
            edges = [10 ** (lo + k * step) for k in range(len(counts) + 1)]
            span += [edges[k] for k, c in enumerate(counts) if c]
            span += [edges[k + 1] for k, c in enumerate(counts) if c]
            extra = [f"{h[k]} {k}" for k in ("zero", "below", "above", "nonfinite") if h.get(k)]
            label = eng + (f"/{var}" if var else "") + f" (n={r.get('count')}"
            label += (", " + ", ".join(extra) if extra else "") + ")"
            ax.stairs(
                counts,
                edges,
                color=engine_color(eng, engines),
                linewidth=1.4,
                linestyle=styles[vlist.index(var) % len(styles)],
                label=label,
            )
            tol = to_float(r.get("tolerance"))
            if math.isfinite(tol) and tol > 0:
                tols.add((tol, eng))
        for tol, eng in sorted(tols):  # in the engine's colour: engines may differ (rigid recovery)
            ax.axvline(tol, color=engine_color(eng, engines), linestyle="--", linewidth=1.0)
        span += sorted(t for t, _ in tols)
        if span:
            ax.set_xlim(min(span) / 10, max(span) * 10)
        from matplotlib.ticker import LogLocator, NullLocator

        ax.xaxis.set_major_locator(LogLocator(numticks=6))  # few labels: text is the cost here
        ax.xaxis.set_minor_locator(NullLocator())
        ax.set_ylabel("samples", fontsize=7.5)
        ax.legend(fontsize=6.5, loc="upper left", frameon=False)
    for ax in axes[-1]:
        ax.set_xlabel("error (log; dashed: the engine's tolerance)", fontsize=7.5)
    if title:
        fig.suptitle(title, fontsize=10, x=0.01, y=1 - 0.05 / height, ha="left", va="top")
    return svg_text(fig)
