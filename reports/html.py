"""Building blocks of the self-contained ``report.html``: every image is an inline base64 data URI, tables are
inline, the only external references are relative links to files beside the report (the PLY point clouds).
No JavaScript, no network access.
"""

from __future__ import annotations

import base64
import html

import pandas as pd

__all__ = ["esc", "data_uri", "img", "table", "link", "details", "page"]

CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; margin: 1.5em auto;
       max-width: 1500px; padding: 0 1em; color: #222; line-height: 1.4; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: .2em; margin-top: 2em; }
table { border-collapse: collapse; font-size: .85em; margin: .8em 0; }
th, td { border: 1px solid #ccc; padding: .25em .55em; text-align: right; white-space: nowrap; }
th { background: #f0f0f0; } td.text, th.text { text-align: left; }
tr.paper td { background: #fff6dd; font-style: italic; }
figure { margin: 1em 0; } figure img { max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption { font-size: .85em; color: #555; }
.problems { background: #fdecea; border: 1px solid #e0a0a0; padding: .6em 1em; }
.note { font-size: .9em; color: #444; }
details { margin: .6em 0 .6em 1em; } summary { cursor: pointer; font-weight: 600; }
ul.files { font-size: .85em; columns: 2; }
"""


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


def link(href: str, text: str) -> str:
    """An ``<a>`` to a relative path (each path segment URL-quoted)."""
    from urllib.parse import quote

    return f'<a href="{esc(quote(href))}">{esc(text)}</a>'


def details(summary: str, body: str, open_: bool = False) -> str:
    """A collapsible ``<details>`` block."""
    return f"<details{' open' if open_ else ''}><summary>{esc(summary)}</summary>{body}</details>"


def page(title: str, body: str) -> str:
    """A complete HTML5 document."""
    return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f'<meta name="viewport" content="width=device-width, initial-scale=1">\n'
            f"<title>{esc(title)}</title>\n<style>{CSS}</style>\n</head>\n<body>\n{body}\n</body>\n</html>\n")
