"""Figures for `crosscheck report`, rendered to SVG text (no pyplot, no display, no files).

Each function takes plain data from results.json / bench.json and returns an SVG document as a
string; the report embeds it as a `data:image/svg+xml;base64,...` image, so index.html stays one
self-contained file, each figure keeps its own element ids (inline <svg> blocks sharing one
document would share ids), and text stays sharp at any zoom.

Output is byte-for-byte deterministic for the same input: the SVG carries no date, and the ids
matplotlib hashes for clip paths use a fixed salt.

Log axes cannot show 0: an error, residual or drift that is exactly 0 is drawn at `ZERO_AT`
with a hollow marker (the caption says so), never dropped, so "exact" stays visible.
"""

from __future__ import annotations

import io
import math

from crosscheck.report.content import energy_series, method_label

ZERO_AT = 1e-17  # below every double round-off figure of a quantity scaled to 1 (eps = 2.2e-16)
# The top of every log axis. A figure above it is a run that blew up (the table beside the
# figure has the number): it is drawn on the edge and said so. Matplotlib's log ticks overflow
# for values near the largest double (1e300 and up), so no axis may reach them.
OFF_SCALE = 1e12
OFF_SCALE_NOTE = f"drawn at {OFF_SCALE:.0e}: above the scale"


def log_clip(values):
    """Values for a log axis: |v| within [ZERO_AT, OFF_SCALE], NaN where not finite (a gap).
    Returns (the array, whether any value was above OFF_SCALE)."""
    import numpy as np

    v = np.abs(np.array([_num(x) for x in values], dtype=float))
    finite = np.isfinite(v)
    above = bool(np.any(v[finite] > OFF_SCALE))
    return np.where(finite, np.clip(v, ZERO_AT, OFF_SCALE), np.nan), above


# one colour per engine, the same in every figure of the report
# (the engines' colours: ENGINE_PALETTE cycled in the registry's order, then the other engines
# of the figure in its order)
REFERENCE_COLOR = "#6b6b6b"
ENGINE_PALETTE = [
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#17becf",
    "#bcbd22",
]
_LINE_COLORS = [
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#17becf",
    "#bcbd22",
    "#7f7f7f",
    "#d62728",
]
_MARKERS = ["o", "s", "^", "D", "v", "P", "X", "<", ">", "*"]
FAIL_COLOR = "#d62728"


def engine_color(engine: str, order: list[str] | None = None) -> str:
    if engine == "reference":
        return REFERENCE_COLOR
    from crosscheck.engines.registry import available_engines

    known = list(available_engines())
    seq = known + [e for e in (order or []) if e not in known and e != "reference"]
    i = seq.index(engine) if engine in seq else len(seq)
    return ENGINE_PALETTE[i % len(ENGINE_PALETTE)]


def _num(x) -> float:
    """JSON value -> float; None and non-numbers become NaN."""
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def new_figure(width, height):
    from matplotlib.backends.backend_svg import FigureCanvasSVG
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasSVG(fig)
    return fig


def svg_text(fig) -> str:
    import matplotlib

    buf = io.StringIO()
    with matplotlib.rc_context({"svg.hashsalt": "multibody-crosscheck", "svg.fonttype": "path"}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    return buf.getvalue()


def axes_style(ax):
    ax.grid(True, which="major", color="#dddddd", linewidth=0.6)
    ax.set_axisbelow(True)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)
    ax.tick_params(labelsize=8)


# ---- agreement -----------------------------------------------------------------------------
def agreement_svg(records: list[dict], title: str = "") -> str | None:
    """Error and tolerance of every executed check, one row per (check, quantity[, formulation]),
    one marker per engine; log x. Failing points are ringed in red; skipped rows are labelled."""
    rows: list[tuple] = []
    by_row: dict[tuple, list[dict]] = {}
    for r in records:
        key = _row_key(r)
        if key not in by_row:
            rows.append(key)
            by_row[key] = []
        by_row[key].append(r)
    if not rows:
        return None
    engines = list(dict.fromkeys(r.get("engine", "?") for r in records))
    finite = [
        v
        for r in records
        for v in (_num(r.get("error")), _num(r.get("tolerance")))
        if math.isfinite(v) and 0 < v <= OFF_SCALE
    ]
    lo = min([ZERO_AT, *finite]) / 3
    hi = max([1.0, *finite]) * 30
    slots = [(key, r) for key in rows for r in by_row[key]]
    height = 1.1 + 0.27 * len(slots) + 0.12 * len(rows)
    fig = new_figure(8.6, height)
    ax = fig.add_subplot()
    axes_style(ax)
    ax.set_xscale("log")
    ax.set_xlim(lo, hi)
    y = 0.0
    yticks, ylabels = [], []
    seen_labels = set()
    notes = {"zero": False, "inf": False, "fail": False}
    for i, key in enumerate(rows):
        group = by_row[key]
        ys = [y - j * 0.8 for j in range(len(group))]
        yticks.append(sum(ys) / len(ys))
        ylabels.append(_row_label(key))
        if i % 2 == 0:
            ax.axhspan(ys[-1] - 0.5, ys[0] + 0.5, color="#f4f4f4", zorder=0, linewidth=0)
        for r, yy in zip(group, ys, strict=True):
            eng = r.get("engine", "?")
            color = engine_color(eng, engines)
            label = eng if eng not in seen_labels else None
            seen_labels.add(eng)
            if r.get("skipped") or r.get("passed") is None:
                ax.text(
                    lo * 1.5,
                    yy,
                    f"{eng}: skipped",
                    va="center",
                    ha="left",
                    fontsize=7,
                    color="#777777",
                    style="italic",
                )
                continue
            _agreement_point(ax, r, yy, color, label, hi, notes)
        y = ys[-1] - 1.3
    ax.set_yticks(yticks, ylabels, fontsize=8)
    ax.set_ylim(y + 0.6, 0.8)
    ax.set_xlabel("error (scaled: max |engine − reference| / max(|reference|, 1))", fontsize=8)
    _agreement_legend(ax, notes)
    if title:
        ax.set_title(title, fontsize=10, loc="left")
    return svg_text(fig)


def _agreement_point(ax, r: dict, yy: float, color, label, hi: float, notes: dict) -> None:
    """One executed check: its tolerance bar, its error marker (0, inf and NaN drawn apart)
    and a red ring when it fails; `notes` records which legend entries are needed."""
    err, tol = _num(r.get("error")), _num(r.get("tolerance"))
    if math.isfinite(tol) and 0 < tol <= OFF_SCALE:
        ax.plot(
            [tol],
            [yy],
            marker="|",
            markersize=13,
            markeredgewidth=2.2,
            color="#222222",
            linestyle="none",
            zorder=3,
        )
    failed = r.get("passed") is False
    if not math.isfinite(err) or err > OFF_SCALE:
        notes["inf"] = True
        ax.plot(
            [hi / 2],
            [yy],
            marker=">",
            markersize=8,
            color=color,
            label=label,
            linestyle="none",
            zorder=4,
        )
        ax.text(
            hi / 8,
            yy,
            "NaN" if err != err else ("inf" if math.isinf(err) else f"{err:.1e}"),
            ha="right",
            va="center",
            fontsize=7,
            color=FAIL_COLOR if failed else color,
        )
    elif err <= 0:
        notes["zero"] = True
        ax.plot(
            [ZERO_AT],
            [yy],
            marker="o",
            markersize=6,
            markerfacecolor="white",
            markeredgecolor=color,
            markeredgewidth=1.6,
            linestyle="none",
            label=label,
            zorder=4,
        )
    else:
        ax.plot(
            [err],
            [yy],
            marker="o",
            markersize=6,
            color=color,
            linestyle="none",
            label=label,
            zorder=4,
        )
    if failed:
        notes["fail"] = True
        x = hi / 2 if not math.isfinite(err) or err > OFF_SCALE else max(err, ZERO_AT)
        ax.plot(
            [x],
            [yy],
            marker="o",
            markersize=12,
            markerfacecolor="none",
            markeredgecolor=FAIL_COLOR,
            markeredgewidth=1.8,
            linestyle="none",
            zorder=5,
        )


def _agreement_legend(ax, notes: dict) -> None:
    """The engines' markers, the tolerance bar, and the entries `notes` asks for."""
    from matplotlib.lines import Line2D

    handles, labels = ax.get_legend_handles_labels()
    handles.append(
        Line2D(
            [],
            [],
            marker="|",
            markersize=11,
            markeredgewidth=2.2,
            color="#222222",
            linestyle="none",
        )
    )
    labels.append("tolerance")
    if notes["zero"]:
        handles.append(
            Line2D(
                [],
                [],
                marker="o",
                markerfacecolor="white",
                markeredgecolor="#555555",
                linestyle="none",
            )
        )
        labels.append(f"exactly 0 (drawn at {ZERO_AT:.0e})")
    if notes["fail"]:
        handles.append(
            Line2D(
                [],
                [],
                marker="o",
                markersize=10,
                markerfacecolor="none",
                markeredgecolor=FAIL_COLOR,
                markeredgewidth=1.8,
                linestyle="none",
            )
        )
        labels.append("failing")
    if notes["inf"]:
        handles.append(Line2D([], [], marker=">", color="#555555", linestyle="none"))
        labels.append("inf / NaN")
    ax.legend(
        handles, labels, fontsize=7.5, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False
    )


def _row_key(r: dict) -> tuple:
    if r.get("engine") == "reference":
        return (
            r.get("check", "?"),
            r.get("quantity", "?"),
            r.get("formulation", "?"),
            r.get("against", ""),
        )
    return (r.get("check", "?"), r.get("quantity", "?"), "", "")


def _row_label(key: tuple) -> str:
    check, quantity, formulation, against = key
    if formulation:
        vs = f" vs {against}" if against else ""
        return f"{check}: {quantity}\n({formulation}{vs})"
    return f"{check}: {quantity}"


# ---- trajectories --------------------------------------------------------------------------
TRAJECTORY_PANELS = (
    ("state_error", "state error vs reference"),
    ("residual", "constraint residual (max |violation|)"),
    ("energy", "energy drift |E − E(0)| / max(max |E|, 1)"),
)
BALANCE_PANEL = "work-energy balance |E − E(0) − W| / max(max |E|, 1)"


def trajectory_panels(series: list[dict]) -> list[tuple[str, str]]:
    """The panels trajectory_svg draws for these series, (key, axis label): a panel where every
    line is exactly 0 has nothing to draw on a log axis and is left out (captions name these)."""
    lines = [s for s in series if s.get("t")]

    def drawable(key):
        return any(s.get(key) and any(_num(x) != 0 for x in s[key]) for s in lines) or (
            key == "energy" and any(len(set(s.get(key) or [])) > 1 for s in lines)
        )

    balance = any(s.get("work") is not None for s in lines)
    return [
        (k, BALANCE_PANEL if k == "energy" and balance else t)
        for k, t in TRAJECTORY_PANELS
        if drawable(k)
    ]


def trajectory_svg(series: list[dict], title: str = "") -> str | None:
    """State error, constraint residual and energy drift against time, log y, one line per
    (engine, formulation, label): colour per label (method), line style per engine. A line that is
    exactly 0 throughout is named in the panel instead of drawn; other zeros sit at ZERO_AT."""
    import numpy as np

    lines = [s for s in series if s.get("t")]
    if not lines:
        return None
    panels = trajectory_panels(lines)
    if not panels:
        return None
    styles = line_styles([_series_key(s) for s in lines])
    fig = new_figure(8.6, 0.6 + 2.15 * len(panels))
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (key, label) in zip(axes, panels, strict=True):
        axes_style(ax)
        ax.set_yscale("log")
        ax.set_ylabel(label, fontsize=8)
        zeros, above = [], False
        for s in lines:
            t = np.array([_num(v) for v in s["t"]])
            vals = s.get(key)
            if not vals:
                continue
            v = np.array([_num(x) for x in vals])
            n = min(len(t), len(v))
            t, v = t[:n], v[:n]
            if key == "energy":  # as the records judge it: drift, or work-energy balance
                v = energy_series(s)
                n = min(len(t), len(v))
                t, v = t[:n], v[:n]
            if n and np.all(v == 0):  # exact zero throughout (e.g. the reference vs itself)
                zeros.append(series_label(s))
                continue
            v, off = log_clip(v)
            above = above or off
            color, style = styles[_series_key(s)]
            ax.plot(t, v, color=color, linestyle=style, linewidth=1.3, label=series_label(s))
        if above:
            ax.text(
                0.99,
                0.98,
                OFF_SCALE_NOTE,
                fontsize=7,
                color="#555555",
                transform=ax.transAxes,
                ha="right",
                va="top",
            )
        if zeros:
            ax.text(
                0.01,
                0.02,
                "exactly 0 throughout: " + "; ".join(zeros),
                fontsize=7,
                color="#555555",
                transform=ax.transAxes,
                va="bottom",
            )
    axes[-1].set_xlabel("t [s]", fontsize=8)
    # one legend under the panels (beside them, long labels squeeze the axes to nothing)
    handles = {}
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(lab, h)
    if handles:
        fig.legend(
            list(handles.values()),
            list(handles),
            fontsize=7.5,
            frameon=False,
            loc="outside lower center",
            ncols=2,
        )
        fig.set_figheight(fig.get_figheight() + 0.22 * ((len(handles) + 1) // 2))
    if title:
        axes[0].set_title(title, fontsize=10, loc="left")
    return svg_text(fig)


def _series_key(s: dict) -> tuple:
    """(method label and engine variant: one colour; engine: one line style; formulation)."""
    variant = f" [{s['variant']}]" if s.get("variant") else ""
    return (s.get("label", "") + variant, s.get("engine", "?"), s.get("formulation", ""))


def line_styles(keys: list[tuple]) -> dict:
    """{(method or label, engine, ...): (colour, line style)}: one colour per method or label,
    one line style per engine, so the same method in two engines reads as one family."""
    labels = list(dict.fromkeys(k[0] for k in keys))
    engines = list(dict.fromkeys(k[1] for k in keys))
    styles = ["-", "--", ":", "-."]
    return {
        k: (
            _LINE_COLORS[labels.index(k[0]) % len(_LINE_COLORS)],
            styles[engines.index(k[1]) % len(styles)],
        )
        for k in keys
    }


def series_label(s: dict) -> str:
    parts = [s.get("engine", "?") + (f" [{s['variant']}]" if s.get("variant") else "")]
    if s.get("formulation"):
        parts.append(s["formulation"])
    if s.get("label"):
        parts.append(s["label"])
    return " · ".join(parts)


# ---- work-precision ------------------------------------------------------------------------
WORK_PRECISION_PANELS = (
    ("error", "error"),
    ("residual", "constraint residual"),
    ("energy_drift", "energy drift"),
)


def work_precision_svg(rows: list[dict], title: str = "") -> str | None:
    """Wall time against error (and residual, energy drift), log-log, one line per (method,
    engine): colour per method, line style and marker per engine; points in the order of the
    tolerance ladder as bench.json lists them."""
    lines: dict[tuple, list[dict]] = {}
    for r in rows:
        lines.setdefault((method_label(r), r.get("engine", "?")), []).append(r)
    panels = [
        (k, lab)
        for k, lab in WORK_PRECISION_PANELS
        if any(math.isfinite(_num(r.get(k))) for r in rows)
    ]
    timed = any(math.isfinite(_num(r.get("wall_s"))) and _num(r.get("wall_s")) > 0 for r in rows)
    if not lines or not panels or not timed:
        return None
    from matplotlib.ticker import LogLocator, NullFormatter

    styles = line_styles(list(lines))
    engines = list(dict.fromkeys(k[1] for k in lines))
    fig = new_figure(min(3.3 * len(panels) + 2.4, 12.0), 3.6)
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    for ax, (key, label) in zip(axes, panels, strict=True):
        axes_style(ax)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(label, fontsize=8)
        for (method, engine), pts in lines.items():
            xs, ys = [], []
            for p in pts:
                x, w = _num(p.get(key)), _num(p.get("wall_s"))
                if math.isfinite(x) and math.isfinite(w) and w > 0:
                    xs.append(min(max(abs(x), ZERO_AT), OFF_SCALE))
                    ys.append(min(max(w, ZERO_AT), OFF_SCALE))
            if not xs:
                continue
            color, style = styles[(method, engine)]
            ax.plot(
                xs,
                ys,
                color=color,
                linestyle=style,
                marker=_MARKERS[engines.index(engine) % len(_MARKERS)],
                markersize=4.5,
                linewidth=1.3,
                label=f"{method} · {engine}",
            )
        ax.xaxis.set_major_locator(LogLocator(numticks=5))
        ax.yaxis.set_major_locator(LogLocator(numticks=6))
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.yaxis.set_minor_formatter(NullFormatter())
    axes[0].set_ylabel("wall time [s]", fontsize=8)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=7.5, loc="outside right upper", frameon=False)
    if title:
        fig.suptitle(title, fontsize=10, x=0.02, ha="left")
    return svg_text(fig)
