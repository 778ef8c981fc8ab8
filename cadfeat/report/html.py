"""HTML building blocks for report.html: escaping, numbers, tables, figures and the page (CSS inline; the only
scripts are the interactive 3-D view's, ``cadfeat.report.view3d``).

Every string that comes from the inputs (study, part and hole names, file names, notes, errors) goes
through ``esc``; numbers go through ``num`` which keeps the full value in a ``data-value`` attribute so
that the page can be checked against results.json.
"""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import TypeAlias

CSS = """
body{font-family:-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:0 auto;max-width:1200px;
padding:1em 2em;color:#222;background:#fff;line-height:1.4}
h1{border-bottom:2px solid #d62728;padding-bottom:.2em} h2{margin-top:1.6em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;margin:.6em 0;font-size:.9em}
th,td{border:1px solid #ccc;padding:.25em .55em;text-align:right;vertical-align:top}
th{background:#f3f3f3;text-align:center} td.text,th.text{text-align:left}
td.mono{font-family:ui-monospace,Menlo,Consolas,"DejaVu Sans Mono",monospace;font-size:.95em;text-align:left}
tr.ok td.status{background:#e3f6e3;color:#1a6b1a;font-weight:bold}
tr.violated td{background:#fde4e4} tr.violated td.status{color:#a00;font-weight:bold}
td.better{color:#1a6b1a} td.worse{color:#a00} td.nz{background:#fff3cd}
.warning{background:#fde4e4;border:1px solid #a00;padding:.6em 1em;margin:1em 0}
.note{background:#f6f6f6;border-left:4px solid #999;padding:.5em 1em;margin:.8em 0}
.pair{display:flex;flex-wrap:wrap;gap:1em} .pair figure{flex:1 1 45%;margin:0}
figure{margin:.8em 0} figure img{max-width:100%;border:1px solid #ddd}
figcaption{font-size:.85em;color:#555}
.verdict{font-weight:bold} .big{font-size:1.15em}
.verdict-box{padding:.7em 1em;margin:1em 0;border:2px solid #999;font-weight:bold}
.verdict-box.adopt{background:#e3f6e3;border-color:#1a6b1a} .verdict-box.care{background:#fff3cd;border-color:#b8860b}
.verdict-box.reject{background:#fde4e4;border-color:#a00}
tr.care td{background:#fff3cd} tr.reject td{background:#fde4e4} tr.adopt td:nth-child(2){color:#1a6b1a}
tr.active td{background:#fff3cd} tr.active td.status{color:#8a6d00;font-weight:bold}
details{margin:.6em 0} summary{cursor:pointer;color:#444}
"""

Relative: TypeAlias = Callable[[Path], "str | tuple[str, str]"]
"""How a section links a file of the output folder in the report: its path relative to report.html, or (data URI,
that path) when the report embeds it (``figure``'s ``src``)."""


def esc(value: object) -> str:
    """HTML-escape any value's text (quotes too, so it is safe in attributes)."""
    return html.escape(str(value), quote=True)


def fmt(value: object, digits: int = 4) -> str:
    """A number as shown in the report: ``digits`` significant digits; bools, None and text as text."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "NaN"
        if math.isinf(value):
            return "∞" if value > 0 else "−∞"
        return f"{value:.{digits}g}"
    return str(value)


def num(value: object, css: str = "", digits: int = 4) -> str:
    """A table cell for a number; the exact value is kept in ``data-value`` (repr of the float)."""
    cls = f' class="{esc(css)}"' if css else ""
    if isinstance(value, int | float) and not isinstance(value, bool):
        return f'<td{cls} data-value="{esc(repr(float(value)))}">{esc(fmt(value, digits))}</td>'
    return f'<td{cls}>{esc(fmt(value, digits))}</td>'


def text(value: object, css: str = "text") -> str:
    """A table cell for text."""
    return f'<td class="{esc(css)}">{esc(fmt(value))}</td>'


def _header_row(header: Sequence[str | tuple[str, int]]) -> str:
    cells = []
    for h in header:
        label, span = h if isinstance(h, tuple) else (h, 1)
        cells.append(f'<th colspan="{span}">{esc(label)}</th>' if span > 1 else f"<th>{esc(label)}</th>")
    return "<tr>" + "".join(cells) + "</tr>"


def table(header: Sequence[str | tuple[str, int]], rows: Iterable[str], table_id: str = "",
          header2: Sequence[str] | None = None, row_classes: Sequence[str] | None = None) -> str:
    """A table: ``header`` (plain strings or (string, colspan), escaped; no header row when all are empty),
    an optional second header row, ``rows`` already made of ``<td>`` cells."""
    tid = f' id="{esc(table_id)}"' if table_id else ""
    head = _header_row(header) if any(h for h in header) else ""
    if header2:
        head += _header_row(header2)
    rows = list(rows)
    classes = list(row_classes) if row_classes is not None else [""] * len(rows)
    body = "".join(f'<tr class="{esc(c)}">{r}</tr>' if c else f"<tr>{r}</tr>"
                   for r, c in zip(rows, classes, strict=True))
    thead = f"<thead>{head}</thead>" if head else ""
    return f"<table{tid}>{thead}<tbody>{body}</tbody></table>"


def figure(src: str | tuple[str, str], caption: str, alt: str = "") -> str:
    """An image with a caption. ``src``: a path relative to report.html, or (data URI, that relative path) for
    an embedded image (the path kept in ``data-file``: the PNG is also written beside the report)."""
    src, file = src if isinstance(src, tuple) else (src, "")
    data_file = f' data-file="{esc(file)}"' if file else ""
    return (f'<figure><img src="{esc(src)}"{data_file} alt="{esc(alt or caption)}" loading="eager">'
            f"<figcaption>{esc(caption)}</figcaption></figure>")


def data_uri(path: str | Path) -> str:
    """The file as a ``data:`` URI (PNG, SVG, JPEG by suffix; base64)."""
    path = Path(path)
    mime = {".png": "image/png", ".svg": "image/svg+xml", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}.get(
        path.suffix.lower(), "application/octet-stream")
    return f"data:{mime};base64,{base64.b64encode(path.read_bytes()).decode('ascii')}"


def note(message: str, css: str = "note") -> str:
    """A boxed note (``css`` "note" or "warning")."""
    return f'<div class="{esc(css)}">{esc(message)}</div>'


def section(title: str, body: str, section_id: str) -> str:
    """A titled section."""
    return f'<section id="{esc(section_id)}"><h2>{esc(title)}</h2>{body}</section>'


def page(title: str, subtitle: str, sections: Sequence[str]) -> str:
    """The whole document: inline CSS, UTF-8 (scripts only inside sections that bring them: the 3-D view)."""
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>{esc(title)}</title><style>{CSS}</style></head><body>"
            f"<h1>{esc(title)}</h1><p>{esc(subtitle)}</p>" + "\n".join(sections) + "\n</body></html>\n")
