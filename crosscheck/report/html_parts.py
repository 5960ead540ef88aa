"""HTML building blocks shared by the report's sections: escaping, anchors, tables and
figures holding an SVG inline (the page stays one self-contained file)."""

from __future__ import annotations

import base64
import html


def e(x) -> str:
    return html.escape(str(x), quote=True)


def anchor(model: str) -> str:
    return "model-" + "".join(c if c.isalnum() or c in "-_" else "-" for c in model)


def img(svg: str | None, alt: str, caption: str) -> str:
    if not svg:
        return ""
    data = base64.b64encode(svg.encode("utf-8")).decode("ascii")
    return (
        f'<figure><img src="data:image/svg+xml;base64,{data}" alt="{e(alt)}">'
        f"<figcaption>{caption}</figcaption></figure>"
    )


def table(
    headers: list[str],
    rows: list[list[str]],
    classes: list[str] | None = None,
    num_cols: set[int] = frozenset(),
) -> str:
    out = [
        "<table><thead><tr>" + "".join(f"<th>{h}</th>" for h in headers) + "</tr></thead>",
        "<tbody>",
    ]
    for i, row in enumerate(rows):
        cls = f' class="{classes[i]}"' if classes and classes[i] else ""
        cells = "".join(
            f'<td class="num">{c}</td>' if j in num_cols else f"<td>{c}</td>"
            for j, c in enumerate(row)
        )
        out.append(f"<tr{cls}>{cells}</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)
