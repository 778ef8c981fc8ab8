"""The campaign's summary: ``campaign.csv`` (a row per case), ``campaign.json`` and ``campaign.html``.

A row holds the case's swept values, status and error, the combined objective before/after and each
objective before/after (results.json ``objectives``), the report's verdict (``cadfeat.report.verdict.decide``:
adopt / adopt with care / do not adopt), the predicted pose error when results.json has one
(``pose_accuracy``-like sections) and the closed-loop pose error (``tracking``: per estimator the Monte-Carlo
mean of the translation (mm) and rotation (deg) RMS error, before/after), and times (case wall time,
the study's own phase total). Nothing here computes a measure: it reads what each study wrote.

``campaign.html`` is one self-contained file: the table, sortable by clicking a column header (a few lines of
inline JavaScript), and per swept axis two matplotlib plots (PNG inlined as base64): the combined objective
before/after against the axis value, and the verdicts per axis value.
"""

from __future__ import annotations

import base64
import csv
import html
import io
import json
import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, cast

from cadfeat.campaign.plan import Campaign
from cadfeat.campaign.store import CampaignStore, atomic_write

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from cadfeat.results import JsonDict

__all__ = ["case_row", "write_csv", "write_summary"]

_PREDICTED_KEYS = ("pose_accuracy", "accuracy", "pose_information", "predicted_pose_error")


def _num(x: object) -> float | None:
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) else None


def _table(value: object) -> Mapping[str, object]:
    """A JSON object of results.json (an empty one for anything else: a summary reads odd results too)."""
    return cast("Mapping[str, object]", value) if isinstance(value, Mapping) else {}


def verdict(results: Mapping[str, object]) -> str | None:
    """The report's decision for a study (None when the report module cannot decide)."""
    try:
        from cadfeat.report.verdict import decide

        return str(decide(dict(results)).decision)
    except Exception:  # noqa: BLE001 - a summary never fails on one study's odd results
        return None


def _leaves(data: object, prefix: str) -> dict[str, float]:
    """Numeric leaves of nested dicts, keyed by dotted path."""
    out: dict[str, float] = {}
    if isinstance(data, Mapping):
        for k, v in _table(data).items():
            out.update(_leaves(v, f"{prefix}.{k}" if prefix else str(k)))
    elif (value := _num(data)) is not None:
        out[prefix] = value
    return out


def predicted_pose_error(results: Mapping[str, object]) -> dict[str, float]:
    """Predicted pose errors (mm, deg) before/after if a pose-accuracy section is in results.json."""
    for key in _PREDICTED_KEYS:
        section = results.get(key)
        if isinstance(section, Mapping):
            leaves: dict[str, float] = {}
            for side in ("before", "after"):
                for path, v in _leaves(_table(section).get(side), "").items():
                    if "_mm" in path or "_deg" in path:
                        leaves[f"predicted.{path}.{side}"] = v
            return leaves
    return {}


def closed_loop_pose_error(results: Mapping[str, object]) -> dict[str, float | str]:
    """Closed-loop tracking errors (results.json ``tracking``): Monte-Carlo mean RMS per estimator and its
    paired verdict."""
    tr = results.get("tracking")
    if not isinstance(tr, Mapping):
        return {}
    tr = _table(tr)
    out: dict[str, float | str] = {}
    designs = _table(tr.get("designs"))
    for side in ("before", "after"):
        for est, summary in _table(_table(designs.get(side)).get("estimators")).items():
            for metric in ("trans_mm_rms", "rot_deg_rms"):
                v = _num(_table(_table(summary).get(metric)).get("mean"))
                if v is not None:
                    out[f"tracking.{est}.{metric}.{side}"] = v
    for est, v in _table(tr.get("verdicts")).items():
        out[f"tracking.{est}.verdict"] = str(_table(v).get("verdict", "")) if isinstance(v, Mapping) else str(v)
    return out


def case_row(record: Mapping[str, object], results: Mapping[str, object] | None, axes: Sequence[str]) -> JsonDict:
    """One summary row of a case from its record and (if it finished) its results.json."""
    values = _table(record.get("values"))
    row: JsonDict = {"case": record.get("case"), "status": record.get("status")}
    for axis in axes:
        v = values.get(axis)
        row[axis] = json.dumps(v) if isinstance(v, list | dict) else v
    row.update({"combined_before": None, "combined_after": None, "verdict": None})
    if results:
        obj = _table(results.get("objectives"))
        row["combined_before"], row["combined_after"] = _num(obj.get("combined_before")), \
            _num(obj.get("combined_after"))
        row["verdict"] = verdict(results)
        for side in ("before", "after"):
            for name, v in _table(obj.get(side)).items():
                row[f"{name}.{side}"] = _num(v)
        row.update(predicted_pose_error(results))
        row.update(closed_loop_pose_error(results))
        timings = _table(results.get("timings_s"))
        row["study_s"] = sum(v for v in map(_num, timings.values()) if v is not None) or None
    row["wall_s"] = _num(record.get("wall_s"))
    row["worker"] = record.get("worker") or record.get("host")
    row["error"] = record.get("error")
    row["input_hash"] = str(record.get("input_hash", ""))[:16]
    row["folder"] = f"cases/{record.get('case')}" if record.get("status") == "done" else None
    return row


def rows(store: CampaignStore, campaign: Campaign) -> tuple[list[JsonDict], list[JsonDict]]:
    """The records (case order; a case never run is ``pending``) and the summary rows."""
    records, out = [], []
    for case in campaign.cases:
        rec = store.record(case)
        if rec is None or rec.get("input_hash") != case.input_hash:
            rec = {"case": case.name, "values": case.values, "status": "pending", "input_hash": case.input_hash}
        results = store.results(case) if rec.get("status") == "done" else None
        records.append(rec)
        out.append(case_row(rec, results, campaign.axes))
    return records, out


def _columns(table: Sequence[Mapping[str, object]]) -> list[str]:
    cols: dict[str, None] = {}
    for r in table:
        cols.update(dict.fromkeys(r))
    tail = [c for c in ("study_s", "wall_s", "worker", "error", "input_hash", "folder") if c in cols]
    return [c for c in cols if c not in tail] + tail


def _csv_text(table: Sequence[Mapping[str, object]]) -> str:
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=_columns(table), lineterminator="\n")
    writer.writeheader()
    for r in table:
        writer.writerow({k: ("" if v is None else v) for k, v in r.items()})
    return buf.getvalue()


def write_csv(store: CampaignStore, campaign: Campaign) -> list[JsonDict]:
    """Rewrite ``campaign.csv`` (atomically); returns the records."""
    records, table = rows(store, campaign)
    atomic_write(store.root / "campaign.csv", _csv_text(table))
    return records


def write_summary(store: CampaignStore, campaign: Campaign) -> list[JsonDict]:
    """Write ``campaign.csv``, ``campaign.json`` and ``campaign.html`` (each atomically); returns the records."""
    records, table = rows(store, campaign)
    atomic_write(store.root / "campaign.csv", _csv_text(table))
    atomic_write(store.root / "campaign.json", json.dumps(
        {"campaign": campaign.name, "file": str(campaign.file), "mode": campaign.mode, "axes": list(campaign.axes),
         "rows": table}, indent=1, default=str) + "\n")
    atomic_write(store.root / "campaign.html", html_page(campaign, table))
    return records


# ------------------------------------------------------------------------------------------ html
_SORT_JS = """
document.querySelectorAll('table.sortable th').forEach(function (th, col) {
  th.addEventListener('click', function () {
    var body = th.closest('table').tBodies[0], rows = Array.from(body.rows);
    var asc = th.dataset.order !== 'asc'; th.dataset.order = asc ? 'asc' : 'desc';
    function key(r) { var t = r.cells[col].textContent.trim(), x = Number(t);
      return t === '' ? null : (isNaN(x) ? t : x); }
    rows.sort(function (a, b) { var x = key(a), y = key(b);
      if (x === null) return 1; if (y === null) return -1;
      if (typeof x === 'number' && typeof y === 'number') return asc ? x - y : y - x;
      return asc ? String(x).localeCompare(String(y)) : String(y).localeCompare(String(x)); });
    rows.forEach(function (r) { body.appendChild(r); });
  });
});
"""
_CSS = """body{font-family:system-ui,sans-serif;margin:1.5em;color:#222}
table{border-collapse:collapse;font-size:13px}th,td{border:1px solid #ccc;padding:3px 6px;text-align:left}
th{background:#f0f0f0;cursor:pointer;user-select:none}th:hover{background:#e0e8f0}
tr.done td.status{color:#176b2c}tr.failed td.status,tr.timeout td.status{color:#a31515;font-weight:bold}
tr.interrupted td.status,tr.pending td.status{color:#8a6d00}
td.num{text-align:right;font-variant-numeric:tabular-nums}.plots img{max-width:100%;margin:.5em 0}"""


def _cell(v: object) -> tuple[str, str]:
    if isinstance(v, float):
        return f"{v:.6g}", "num"
    if isinstance(v, int) and not isinstance(v, bool):
        return str(v), "num"
    return ("" if v is None else str(v)), ""


def _table_html(table: Sequence[Mapping[str, object]]) -> str:
    cols = _columns(table)
    head = "".join(f"<th>{html.escape(c)}</th>" for c in cols)
    body = []
    for r in table:
        cells = []
        for c in cols:
            text, cls = _cell(r.get(c))
            cls = "status" if c == "status" else cls
            if c == "folder" and text:
                text_html = f'<a href="{html.escape(text)}/report.html">{html.escape(text)}</a>'
            else:
                text_html = html.escape(text)
            cells.append(f'<td class="{cls}">{text_html}</td>')
        body.append(f'<tr class="{html.escape(str(r.get("status")))}">{"".join(cells)}</tr>')
    return f'<table class="sortable" id="cases"><thead><tr>{head}</tr></thead><tbody>{"".join(body)}</tbody></table>'


def _png(fig: Figure) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def axis_plot(table: Sequence[Mapping[str, object]], axis: str) -> str | None:
    """Base64 PNG: combined objective before/after and verdict counts against one swept axis (finished cases)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    done = [r for r in table if r.get("status") == "done"]
    if not done:
        return None
    def label(r: Mapping[str, object]) -> str:  # a case of a list that does not set this axis: the base study's value
        return "(base)" if r.get(axis) is None else str(r.get(axis))

    labels = sorted({label(r) for r in done})
    pos = {lab: i for i, lab in enumerate(labels)}
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.4))
    for side, marker, face in (("before", "o", "none"), ("after", "s", "C0")):
        pts = [(pos[label(r)], y) for r in done if (y := _num(r.get(f"combined_{side}"))) is not None]
        if pts:
            x, y = zip(*pts, strict=True)
            ax1.scatter(x, y, marker=marker, facecolors=face, edgecolors="C1" if side == "before" else "C0",
                        label=side)
    ax1.set_xticks(range(len(labels)), labels, rotation=20, ha="right", fontsize=8)
    ax1.set_xlabel(axis)
    ax1.set_ylabel("combined objective (larger is better)")
    ax1.legend(fontsize=8)
    verdicts = sorted({str(r.get("verdict")) for r in done})
    bottom = [0] * len(labels)
    for v in verdicts:
        counts = [sum(1 for r in done if label(r) == lab and str(r.get("verdict")) == v) for lab in labels]
        ax2.bar(range(len(labels)), counts, bottom=bottom, label=v)
        bottom = [b + c for b, c in zip(bottom, counts, strict=True)]
    ax2.set_xticks(range(len(labels)), labels, rotation=20, ha="right", fontsize=8)
    ax2.set_xlabel(axis)
    ax2.set_ylabel("cases")
    ax2.set_title("verdict", fontsize=9)
    ax2.legend(fontsize=8)
    try:
        return _png(fig)
    finally:
        plt.close(fig)


def html_page(campaign: Campaign, table: Sequence[Mapping[str, object]]) -> str:
    """The self-contained campaign.html."""
    counts: dict[str, int] = {}
    for r in table:
        counts[str(r.get("status"))] = counts.get(str(r.get("status")), 0) + 1
    status = ", ".join(f"{n} {s}" for s, n in sorted(counts.items()))
    plots = []
    for axis in campaign.axes:
        png = axis_plot(table, axis)
        if png:
            plots.append(f'<h3>{html.escape(axis)}</h3><img alt="combined objective and verdict against '
                         f'{html.escape(axis)}" src="data:image/png;base64,{png}">')
    title = f"campaign {campaign.name}"
    plot_html = "".join(plots) or "(no case finished)"
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1>"
            f"<p>{html.escape(campaign.description)}</p><p>{len(table)} case(s): {html.escape(status)}. Base study "
            f"<code>{html.escape(str(campaign.base_study))}</code>, {campaign.mode} over "
            f"{html.escape(', '.join(campaign.axes))}. Click a column header to sort.</p>"
            f"{_table_html(table)}<h2>Against each swept axis</h2><div class='plots'>{plot_html}</div>"
            f"<script>{_SORT_JS}</script></body></html>\n")
