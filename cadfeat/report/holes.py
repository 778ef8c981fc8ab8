"""The drawing's hole table of the delivered design: name, face, x, y, z, Ø, depth, kind (report and holes.csv).

Rows come from results.json ``holes.after`` (the rebuilt, shop-rounded design; part frame, mm). ``face`` is the
face the hole opens into, named by its outward normal (the hole axis points out of the material): "+Z" for a
hole drilled from the top of a part whose top faces +z; a face that is not axis-aligned is given as its
normal vector. Positions are written to ``POSITION_DECIMALS`` decimals (0.001 mm, finer than the 0.1 mm grid).
"""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cadfeat.report.html import esc, fmt, num, table, text
from cadfeat.results import AddedTargets, Holes, Shop, StudyResults, present, section

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import JsonDict

HOLE_COLUMNS = ("name", "face", "x_mm", "y_mm", "z_mm", "diameter_mm", "depth_mm", "kind", "moved")
POSITION_DECIMALS = 3


def face_label(axis: Sequence[float]) -> str:
    """"+X", "−Y", … for an axis-aligned outward normal; else the normal to 3 decimals."""
    a = np.asarray(axis, float)
    k = int(np.argmax(np.abs(a)))
    if abs(abs(a[k]) - 1.0) < 1e-6:
        return ("+" if a[k] > 0 else "-") + "XYZ"[k]
    return "(" + ", ".join(f"{v:.3f}" for v in a) + ")"


def hole_rows(results: StudyResults | Mapping[str, Any]) -> list[JsonDict]:
    """One row per hole of the delivered design (``holes.after``, else ``holes.before``)."""
    holes = section(results, "holes", Holes)
    if holes is None:
        return []
    before = {h.index: h for h in holes.before}
    rows = []
    for h in holes.after or holes.before:
        c = np.asarray(h.centre_mm, float)
        hb = before.get(h.index, h)
        moved = bool(np.linalg.norm(c - np.asarray(hb.centre_mm, float)) > 1e-6
                     or abs(float(h.radius_mm) - float(hb.radius_mm)) > 1e-6)
        kind = f"{h.kind} {'through' if h.through else 'blind'}"
        rows.append({"name": h.name, "face": face_label(h.axis),
                     "x_mm": float(c[0]), "y_mm": float(c[1]), "z_mm": float(c[2]),
                     "diameter_mm": 2.0 * float(h.radius_mm), "depth_mm": float(h.depth_mm),
                     "kind": kind.strip(), "moved": moved})
    return rows


def write_holes_csv(path: str | Path, results: JsonDict) -> Path:
    """``holes.csv``: the hole table (header ``HOLE_COLUMNS``), positions to ``POSITION_DECIMALS`` decimals."""
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(HOLE_COLUMNS)
        for r in hole_rows(results):
            w.writerow([r["name"], r["face"], *(f"{r[k]:.{POSITION_DECIMALS}f}" for k in ("x_mm", "y_mm", "z_mm",
                                                                                           "diameter_mm", "depth_mm")),
                        r["kind"], "yes" if r["moved"] else "no"])
    return path


def _added_cells(results: StudyResults | Mapping[str, Any]) -> list[str]:
    """Rows of the added target holes (results.json ``added_targets``), changed = "added"."""
    block = section(results, "added_targets", AddedTargets)
    if block is None:
        return []
    return ["".join([text(h.name), text(face_label(h.axis)), num(h.centre[0], digits=7), num(h.centre[1], digits=7),
                     num(h.centre[2], digits=7), num(h.diameter_mm, digits=6), num(h.depth_mm, digits=6),
                     text("plain blind" + (f", {fmt(h.chamfer_mm)} mm chamfer" if h.chamfer_mm else "")),
                     text(h.status)]) for h in block.holes]


def hole_table(results: StudyResults | Mapping[str, Any]) -> str:
    """The hole table as HTML (id ``hole-table``) with a note on the rounding that produced it."""
    rows = hole_rows(results)
    if not rows:
        return ""
    cells = ["".join([text(r["name"]), text(r["face"]), num(r["x_mm"], digits=7), num(r["y_mm"], digits=7),
                      num(r["z_mm"], digits=7), num(r["diameter_mm"], digits=6), num(r["depth_mm"], digits=6),
                      text(r["kind"]), text("yes" if r["moved"] else "")]) for r in rows]
    cells += _added_cells(results)  # issue 31: the recommended added target holes
    shop = section(results, "shop", Shop)
    head = ""
    if shop is not None and present(shop):
        sizes = shop.hole_sizes
        head = (f"<p>Moved holes on a {esc(fmt(shop.grid_mm))} mm grid, resized holes on "
                f"{esc(sizes if isinstance(sizes, str) else 'the study table')} sizes"
                + ("" if shop.applied else " — <b>not applied</b>") + "; every requirement re-verified on "
                "the rebuilt B-rep and the re-imported STEP after rounding.</p>")
        for n in shop.notes:
            head += f'<div class="note">{esc(n)}</div>'
        if shop.combined_optimum is not None and shop.combined_shop is not None:
            head += (f"<p>Combined objective (model): optimum {esc(fmt(shop.combined_optimum))}, shop-ready "
                     f"{esc(fmt(shop.combined_shop))}.</p>")
    return head + table(["hole", "face", "x (mm)", "y (mm)", "z (mm)", "Ø (mm)", "depth (mm)", "kind", "changed"],
                        cells, "hole-table") + "<p>Also written as <code>holes.csv</code>" + (
        " (the delivered design; the rows changed \"added\" are the recommended added target holes of "
        "<code>added_targets.step</code>)" if _added_cells(results) else "") + ".</p>"
