"""The plain Markdown the reports write (headings, paragraphs, pipe tables) as HTML body elements: one converter
for the sweep report and the engine / realism comparisons."""

from __future__ import annotations

import html
from collections.abc import Iterable

__all__ = ["markdown_body"]


def markdown_body(lines: Iterable[str]) -> list[str]:
    """HTML elements for Markdown `lines`: `#`/`##` headings, pipe-table rows (consecutive ones in one table, the
    `|---` separator dropped), other non-empty lines as paragraphs; everything escaped."""
    body: list[str] = []
    in_table = False
    for line in lines:
        if line.startswith("|---"):
            continue
        row = line.startswith("|")
        if row and not in_table:
            body.append("<table>")
        elif not row and in_table:
            body.append("</table>")
        in_table = row
        if line.startswith("## "):
            body.append(f"<h2>{html.escape(line[3:])}</h2>")
        elif line.startswith("# "):
            body.append(f"<h1>{html.escape(line[2:])}</h1>")
        elif row:
            cells = [html.escape(c.strip()) for c in line.strip().strip("|").split("|")]
            body.append("<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
        elif line:
            body.append(f"<p>{html.escape(line)}</p>")
    if in_table:
        body.append("</table>")
    return body
