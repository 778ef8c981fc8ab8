"""Reading report.html back with the standard library's html.parser (for the report tests)."""

from __future__ import annotations

from dataclasses import dataclass, field
from html.parser import HTMLParser
from pathlib import Path


@dataclass
class Cell:
    text: str
    value: float | None  # the data-value attribute, when the cell holds a number
    css: str


@dataclass
class Row:
    css: str
    cells: list[Cell] = field(default_factory=list)


class ReportParser(HTMLParser):
    """Tables by id (rows of cells, header rows excluded), img src list, element text by id, all text."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tables: dict[str, list[Row]] = {}
        self.images: list[str] = []
        self.image_srcs: list[str] = []
        self.by_id: dict[str, str] = {}
        self.text: list[str] = []
        self.scripts = 0
        self._table: str | None = None
        self._in_body_rows = False
        self._cell: Cell | None = None
        self._ids: list[tuple[str, str, list[str]]] = []  # (tag, id, text parts)

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "script":
            self.scripts += 1
        if tag == "img":  # an embedded image: its file beside the report is in data-file
            self.images.append(a.get("data-file") or a.get("src") or "")
            self.image_srcs.append(a.get("src") or "")
        if tag == "table":
            self._table = a.get("id") or f"table{len(self.tables)}"
            self.tables[self._table] = []
        elif tag == "tbody":
            self._in_body_rows = True
        elif tag == "tr" and self._table and self._in_body_rows:
            self.tables[self._table].append(Row(a.get("class") or ""))
        elif tag == "td" and self._table and self._in_body_rows:
            value = a.get("data-value")
            self._cell = Cell("", float(value) if value is not None else None, a.get("class") or "")
        if a.get("id"):
            self._ids.append((tag, a["id"], []))

    def handle_endtag(self, tag: str) -> None:
        if tag == "td" and self._cell is not None:
            self.tables[self._table][-1].cells.append(self._cell)
            self._cell = None
        elif tag == "tbody":
            self._in_body_rows = False
        elif tag == "table":
            self._table = None
        if self._ids and self._ids[-1][0] == tag:
            _, ident, parts = self._ids.pop()
            self.by_id[ident] = "".join(parts)

    def handle_data(self, data: str) -> None:
        self.text.append(data)
        if self._cell is not None:
            self._cell.text += data
        for _, _, parts in self._ids:
            parts.append(data)


def parse_report(path: str | Path) -> ReportParser:
    parser = ReportParser()
    parser.feed(Path(path).read_text(encoding="utf-8"))
    parser.close()
    return parser
