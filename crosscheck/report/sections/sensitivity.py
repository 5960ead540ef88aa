"""The report's sensitivity section: DIR/sensitivity.json of `crosscheck sensitivity`, when it
lies beside the report's results.json, as a table and a plot.

One row per model and parameter, one column per engine: the smallest relative change of that
parameter in that engine's model that some check of the suite catches ("1e-11": a change of
1e-11 is caught, by the record named in the cell's title; "(trajectory)" when only the
trajectory comparison sees the parameter). A parameter nothing catches up to 10 % is shown in
red with the reason. The plot draws the same thresholds on a log axis, the
parameters not caught in red at the top.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from crosscheck.report.markdown_table import md_table

SENSITIVITY_FILE = "sensitivity.json"
NOT_CAUGHT_AT = 1.0  # where the plot draws a parameter nothing caught (above every decade)


def load(c) -> dict | None:
    """sensitivity.json beside the report's results.json, or None (no file, or not readable as
    sensitivity data: then the section says so rather than failing the report)."""
    if not getattr(c, "results_path", None):
        return None
    path = Path(c.results_path).parent / SENSITIVITY_FILE
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        return {"error": f"{path}: not readable as JSON ({exc})", "path": str(path)}
    if not isinstance(doc, dict) or not isinstance(doc.get("thresholds"), list):
        return {
            "error": f'{path}: no "thresholds" list (not written by crosscheck sensitivity)',
            "path": str(path),
        }
    doc["path"] = str(path)
    return doc


def _fmt(x) -> str:
    return "—" if x is None else f"{float(x):.0e}"


def table(doc: dict) -> tuple[list[str], list[list[dict]], list[str]]:
    """(engines, rows, row labels): rows[i][j] is the threshold of row i for engine j, or {}."""
    engines = list(dict.fromkeys(t.get("engine", "?") for t in doc["thresholds"]))
    keys = list(
        dict.fromkeys((t.get("model", "?"), t.get("parameter", "?")) for t in doc["thresholds"])
    )
    cell = {(t.get("model"), t.get("parameter"), t.get("engine")): t for t in doc["thresholds"]}
    rows = [[cell.get((m, p, e), {}) for e in engines] for m, p in keys]
    return engines, rows, [f"{m} / {p}" for m, p in keys]


def _caught(t: dict) -> bool:
    return t.get("caught_at") is not None


def _caught_text(t: dict) -> str:
    """The caught decade, marked when only the trajectory comparison caught it (a parameter
    no instantaneous check sees); files without "comparison" are all instantaneous."""
    via = t.get("comparison", "instantaneous")
    return _fmt(t["caught_at"]) + ("" if via == "instantaneous" else f" ({via})")


def plot_svg(doc: dict) -> str | None:
    """Thresholds per parameter (x) and engine (marker colour), log y; not caught: red x."""
    from crosscheck.report.plots import FAIL_COLOR, axes_style, engine_color, new_figure, svg_text

    engines, rows, labels = table(doc)
    if not rows:
        return None
    fig = new_figure(max(6.0, 0.28 * len(rows) + 2.0), 3.6)
    ax = fig.add_subplot(1, 1, 1)
    axes_style(ax)
    width = 0.6 / max(len(engines), 1)
    for j, e in enumerate(engines):
        xs, ys, xr = [], [], []
        for i, row in enumerate(rows):
            t = row[j]
            if not t:
                continue
            x = i + (j - (len(engines) - 1) / 2) * width
            if _caught(t):
                xs.append(x)
                ys.append(float(t["caught_at"]))
            else:
                xr.append(x)
        ax.scatter(xs, ys, s=18, color=engine_color(e, engines), label=e, zorder=3)
        if xr:
            ax.scatter(
                xr,
                [NOT_CAUGHT_AT] * len(xr),
                s=30,
                marker="x",
                color=FAIL_COLOR,
                zorder=4,
                label=f"{e}: not caught" if len(engines) > 1 else "not caught",
            )
    ax.set_yscale("log")
    decades = doc.get("decades") or [1e-13, 1e-1]
    ax.set_ylim(min(decades) / 3, NOT_CAUGHT_AT * 3)
    ax.axhline(max(decades), color="#999999", linewidth=0.6, linestyle=":")
    ax.set_xticks(range(len(labels)))
    ax.set_xticklabels(labels, rotation=70, ha="right", fontsize=6)
    ax.set_ylabel("smallest relative change caught", fontsize=8)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0), frameon=False)
    return svg_text(fig)


def html(c) -> str:
    """The section (empty without a sensitivity.json beside results.json)."""
    from crosscheck.report.html_parts import e as _e
    from crosscheck.report.html_parts import img as _img
    from crosscheck.report.html_parts import table as _table

    doc = load(c)
    if doc is None:
        return ""
    out = ['<h2 id="sensitivity">Sensitivity: the smallest error the suite catches</h2>']
    if "error" in doc:
        return "\n".join([*out, f'<p class="note">{_e(doc["error"])}</p>'])
    engines, rows, labels = table(doc)
    out.append(
        f'<p class="sub"><code>{_e(doc["path"])}</code>: '
        f"<code>{_e(doc.get('command', 'crosscheck sensitivity'))}</code>; each cell is "
        "the smallest relative change of the parameter in that engine's model alone "
        "that some check fails (decades 1e-13 .. 1e-1); (trajectory): no instantaneous "
        "check sees the parameter and a trajectory record caught it; red: nothing caught "
        "it.</p>"
    )
    body, classes = [], []
    for label, row in zip(labels, rows, strict=True):
        cells, missed = [_e(label)], False
        for t in row:
            if not t:
                cells.append("—")
            elif _caught(t):
                title = "; ".join(x for x in (t.get("failing_check"), t.get("reason")) if x)
                cells.append(f'<span title="{_e(title)}">{_e(_caught_text(t))}</span>')
            else:
                missed = True
                cells.append(
                    f'<span class="badge fail">not caught</span> {_e(t.get("reason", ""))}'
                )
        body.append(cells)
        classes.append("fail" if missed else "")
    out.append(_table(["model / parameter"] + [_e(e) for e in engines], body, classes))
    out.append(
        _img(
            plot_svg(doc),
            "sensitivity thresholds",
            "Smallest relative change caught, per parameter and engine (log scale); "
            "red crosses at the top: not caught up to 10 %.",
        )
    )
    return "\n".join(out)


def md(c) -> list[str]:
    """The Markdown section (empty without a sensitivity.json beside results.json)."""
    doc = load(c)
    if doc is None:
        return []
    out = ["## Sensitivity", ""]
    if "error" in doc:
        return [*out, doc["error"], ""]
    engines, rows, labels = table(doc)
    command = doc.get("command", "crosscheck sensitivity")
    out += [
        f"Smallest relative change of one parameter in one engine's model that the suite "
        f"catches (`{command}`); (trajectory): caught by a trajectory record, no "
        "instantaneous check sees the parameter:",
        "",
    ]
    body = [
        [label]
        + [
            (
                "—"
                if not t
                else _caught_text(t)
                if _caught(t)
                else f"NOT CAUGHT: {t.get('reason', '')}"
            )
            for t in row
        ]
        for label, row in zip(labels, rows, strict=True)
    ]
    return out + md_table(["model / parameter", *engines], body)


def worst(doc: dict) -> float:
    """The largest caught threshold (the suite's weakest caught parameter), or nan."""
    vals = [float(t["caught_at"]) for t in doc.get("thresholds", []) if _caught(t)]
    return max(vals) if vals else math.nan
