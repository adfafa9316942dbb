"""Building blocks of the self-contained ``report.html``: every image is an inline base64 data URI, tables are
inline, the only external references are relative links to files beside the report (PLY point clouds, CSVs).
No network access; the only JavaScript is :data:`SORT_SCRIPT`, inline, which makes ``table.sortable`` tables
sortable by clicking a column header (the page reads fine without it).
"""

from __future__ import annotations

import base64
import html
import math
from urllib.parse import quote

import numpy as np
import pandas as pd

__all__ = ["esc", "data_uri", "img", "table", "sortable_table", "link", "details", "page", "SORT_SCRIPT"]

CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; margin: 1.5em auto;
       max-width: 1500px; padding: 0 1em; color: #222; line-height: 1.4; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: .2em; margin-top: 2em; }
table { border-collapse: collapse; font-size: .85em; margin: .8em 0; }
th, td { border: 1px solid #ccc; padding: .25em .55em; text-align: right; white-space: nowrap; }
th { background: #f0f0f0; } td.text, th.text { text-align: left; }
tr.paper td { background: #fff6dd; font-style: italic; }
tr.reference td { background: #e8eef8; font-style: italic; }
figure { margin: 1em 0; } figure img { max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption { font-size: .85em; color: #555; }
.problems { background: #fdecea; border: 1px solid #e0a0a0; padding: .6em 1em; }
.note { font-size: .9em; color: #444; }
details { margin: .6em 0 .6em 1em; } summary { cursor: pointer; font-weight: 600; }
ul.files { font-size: .85em; columns: 2; }
.scroll { overflow-x: auto; }
table.sortable { font-size: .8em; } table.sortable td, table.sortable th { padding: .2em .4em; }
table.sortable th { cursor: pointer; white-space: normal; vertical-align: bottom; }
table.sortable th.group { cursor: default; text-align: center; }
table.sortable th[data-dir="asc"]::after { content: " \\25B2"; }
table.sortable th[data-dir="desc"]::after { content: " \\25BC"; }
td.best { background: #d9f2d9; font-weight: 700; }
"""

#: Click a header of a ``table.sortable``: sort its body rows by that column's ``data-v`` cell values.  The
#: first click sorts best-first (``data-better="high"``: descending, else ascending), the next reverses; cells
#: without a value (``data-v=""``) always go last; equal keys keep their order (stable sort).
SORT_SCRIPT = """<script>
(function () {
  function sortBy(table, th, col) {
    var head = th.parentNode.cells, dir = th.getAttribute('data-dir');
    dir = dir ? (dir === 'asc' ? 'desc' : 'asc') : (th.getAttribute('data-better') === 'high' ? 'desc' : 'asc');
    for (var i = 0; i < head.length; i++) { head[i].removeAttribute('data-dir'); }
    th.setAttribute('data-dir', dir);
    var num = th.getAttribute('data-type') === 'num', sign = dir === 'asc' ? 1 : -1;
    var body = table.tBodies[0], rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (a, b) {
      var x = a.cells[col].getAttribute('data-v'), y = b.cells[col].getAttribute('data-v');
      if (x === '' || y === '') { return (x === '') - (y === ''); }
      if (num) { return sign * (parseFloat(x) - parseFloat(y)); }
      return sign * x.localeCompare(y);
    });
    rows.forEach(function (r) { body.appendChild(r); });
  }
  Array.prototype.forEach.call(document.querySelectorAll('table.sortable'), function (table) {
    var head = table.tHead.rows[table.tHead.rows.length - 1].cells;
    Array.prototype.forEach.call(head, function (th, col) {
      th.addEventListener('click', function () { sortBy(table, th, col); });
    });
  });
})();
</script>"""


def esc(text) -> str:
    """HTML-escape any value's ``str()``."""
    return html.escape(str(text), quote=True)


def data_uri(png: bytes, mime: str = "image/png") -> str:
    """``data:`` URI of some bytes (base64)."""
    return f"data:{mime};base64,{base64.b64encode(png).decode('ascii')}"


def img(png: bytes, alt: str, caption: str | None = None) -> str:
    """A ``<figure>`` with the PNG embedded as a data URI, and an optional caption (plain text)."""
    cap = f"<figcaption>{esc(caption)}</figcaption>" if caption else ""
    return f'<figure><img src="{data_uri(png)}" alt="{esc(alt)}">{cap}</figure>'


def table(df: pd.DataFrame, text_columns: int = 2, row_classes: list[str] | None = None) -> str:
    """An HTML table of a DataFrame of display strings; the first ``text_columns`` are left-aligned."""
    head = "".join(f'<th class="{"text" if i < text_columns else ""}">{esc(c)}</th>'
                   for i, c in enumerate(df.columns))
    body = []
    for k, (_, row) in enumerate(df.iterrows()):
        cls = f' class="{esc(row_classes[k])}"' if row_classes and row_classes[k] else ""
        cells = "".join(f'<td class="{"text" if i < text_columns else ""}">{esc(v)}</td>'
                        for i, v in enumerate(row))
        body.append(f"<tr{cls}>{cells}</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def _key_text(v) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    return repr(float(v)) if isinstance(v, float | np.floating) else str(v)


def sortable_table(df: pd.DataFrame, keys: list[list], better: list[str], *, table_id: str, text_columns: int = 1,
                   best: np.ndarray | None = None, row_classes: list[str] | None = None,
                   groups: list[tuple[str, int]] | None = None, data_keys: list[str] | None = None) -> str:
    """A ``table.sortable`` (see :data:`SORT_SCRIPT`): click a header to sort by that column.

    Args:
        df: display strings, one column per table column.
        keys: per row, per column, the sort key: a number (numeric column), a string, or None (no value: always
            sorted last).
        better: per column "low" / "high" (numeric; the first click sorts best first), "ref" (numeric, a reference
            that is neither better nor worse; the first click sorts ascending) or "" (text column).
        table_id: the table's ``id``.
        text_columns: the first this many columns are left-aligned.
        best: optional (rows, cols) bool: cells marked ``class="best"`` (highlighted).
        row_classes: optional class per row (e.g. "paper").
        groups: optional header row above the column headers: (label, number of columns spanned) covering all
            columns.
        data_keys: optional per column identifier, written as the header's ``data-key``.
    """
    n = len(df.columns)
    if len(keys) != len(df) or any(len(r) != n for r in keys) or len(better) != n:
        raise ValueError(f"sortable_table: need one sort key per cell ({len(df)} x {n}) and one 'better' per column")
    numeric = [b in ("low", "high", "ref") for b in better]
    head = ""
    if groups:
        head += "<tr>" + "".join(f'<th class="group" colspan="{span}">{esc(label)}</th>' for label, span in groups)
        head += "</tr>"
    cells = []
    for i, c in enumerate(df.columns):
        attrs = f' data-type="{"num" if numeric[i] else "text"}" data-better="{esc(better[i])}"'
        if data_keys:
            attrs += f' data-key="{esc(data_keys[i])}"'
        cells.append(f'<th class="{"text" if i < text_columns else ""}"{attrs} title="click to sort">{esc(c)}</th>')
    head += "<tr>" + "".join(cells) + "</tr>"
    body = []
    for k, (_, row) in enumerate(df.iterrows()):
        cls = f' class="{esc(row_classes[k])}"' if row_classes and row_classes[k] else ""
        tds = []
        for i, v in enumerate(row):
            klass = " ".join(x for x in ("text" if i < text_columns else "",
                                         "best" if best is not None and best[k, i] else "") if x)
            tds.append(f'<td class="{klass}" data-v="{esc(_key_text(keys[k][i]))}">{esc(v)}</td>')
        body.append(f"<tr{cls}>{''.join(tds)}</tr>")
    return (f'<div class="scroll"><table class="sortable" id="{esc(table_id)}"><thead>{head}</thead>'
            f"<tbody>{''.join(body)}</tbody></table></div>")


def link(href: str, text: str) -> str:
    """An ``<a>`` to a relative path (each path segment URL-quoted)."""
    return f'<a href="{esc(quote(href))}">{esc(text)}</a>'


def details(summary: str, body: str, open_: bool = False) -> str:
    """A collapsible ``<details>`` block."""
    return f"<details{' open' if open_ else ''}><summary>{esc(summary)}</summary>{body}</details>"


def page(title: str, body: str) -> str:
    """A complete HTML5 document (with :data:`SORT_SCRIPT` at the end of the body)."""
    return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f'<meta name="viewport" content="width=device-width, initial-scale=1">\n'
            f"<title>{esc(title)}</title>\n<style>{CSS}</style>\n</head>\n<body>\n{body}\n{SORT_SCRIPT}\n"
            "</body>\n</html>\n")
