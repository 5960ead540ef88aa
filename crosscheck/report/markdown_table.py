"""Markdown tables for the reports' Markdown sections (report.md and the sections of it that
live beside their own data: agreement, sensitivity)."""

from __future__ import annotations


def md_cell(x) -> str:
    """A table cell: a pipe would end the cell, a newline the row."""
    return str(x).replace("|", "\\|").replace("\n", " ")


def md_table(headers, rows) -> list[str]:
    """The table's lines, a blank line after it."""
    out = [
        "| " + " | ".join(md_cell(h) for h in headers) + " |",
        "|" + "|".join("---" for _ in headers) + "|",
    ]
    out += ["| " + " | ".join(md_cell(c) for c in row) + " |" for row in rows]
    return [*out, ""]
