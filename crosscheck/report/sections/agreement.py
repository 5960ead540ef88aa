"""The report's engine-against-engine tables (results.json "agreement",
crosscheck.checks.agreement): one table per model and quantity, every side against every other, a
cell outside its bound marked, and the side that disagrees with all others named."""

from __future__ import annotations

from crosscheck.report.content import fmt
from crosscheck.report.markdown_table import md_table


def _cells(m: dict):
    """(row side, [(error text, outside its bound)]) per row."""
    for i, side in enumerate(m["sides"]):
        row = []
        for j, err in enumerate(m["errors"][i]):
            out = i != j and not (err is not None and err <= m["bounds"][i][j])
            row.append(("—" if i == j else fmt(err), out))
        yield side, row


def _verdict(m: dict) -> str:
    if m.get("odd_one_out"):
        return (
            f"{m['odd_one_out']} disagrees with every other side while they agree: "
            f"it is the odd one out"
        )
    outside = any(o for _, row in _cells(m) for _, o in row)
    return (
        "some pairs disagree and no single side is the odd one out"
        if outside
        else "every pair agrees within its bound"
    )


CAPTION = (
    "Each cell: the largest difference of the two sides' answers over the run's states, "
    "max |a − b| / max(max |a|, max |b|, 1); a pair is held to the sum of its two sides' "
    "tolerances against the reference (marked where outside). A soft engine enters with "
    "its rigid recovery."
)


def html(c, model: str) -> str:
    from crosscheck.report.html_parts import e, table

    out = []
    for m in c.agreement_of(model):
        body, classes = [], []
        for side, row in _cells(m):
            body.append([f"<b>{e(side)}</b>"] + [f"<b>{e(t)}</b>" if o else e(t) for t, o in row])
            classes.append("fail" if any(o for _, o in row) else "")
        out.append(f'<p class="sub">{e(m["quantity"])}: {e(_verdict(m))}</p>')
        out.append(
            table(
                [""] + [e(s) for s in m["sides"]], body, classes, set(range(1, len(m["sides"]) + 1))
            )
        )
    if out:
        out.append(f'<p class="note">{e(CAPTION)}</p>')
    return "\n".join(out)


def md(c, model: str) -> list[str]:
    out: list[str] = []
    for m in c.agreement_of(model):
        out += [f"Engine against engine, {m['quantity']}: {_verdict(m)}", ""]
        rows = [[side] + [f"**{t}**" if o else t for t, o in row] for side, row in _cells(m)]
        out += md_table(["", *m["sides"]], rows)
    if out:
        out += [CAPTION, ""]
    return out
