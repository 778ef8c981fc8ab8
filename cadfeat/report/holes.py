"""The drawing's hole table of the delivered design: name, face, x, y, z, Ø, depth, kind (report and holes.csv).

Rows come from results.json ``holes.after`` (the delivered design: the rebuilt, shop-rounded one, with the
added target holes of ``[add_targets]`` when it recommends some; part frame, mm). ``changed`` is "yes" for a
hole moved or resized, "added" for an added target hole, "no" otherwise. ``face`` is the
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
from cadfeat.results import Holes, Shop, StudyResults, present, section

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import JsonDict

HOLE_COLUMNS = ("name", "face", "x_mm", "y_mm", "z_mm", "diameter_mm", "depth_mm", "kind", "changed")
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
                     "kind": kind.strip(), "changed": "added" if h.added else "yes" if moved else "no"})
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
                        r["kind"], r["changed"]])
    return path


def hole_table(results: StudyResults | Mapping[str, Any]) -> str:
    """The hole table as HTML (id ``hole-table``) with a note on the rounding that produced it."""
    rows = hole_rows(results)
    if not rows:
        return ""
    cells = ["".join([text(r["name"]), text(r["face"]), num(r["x_mm"], digits=7), num(r["y_mm"], digits=7),
                      num(r["z_mm"], digits=7), num(r["diameter_mm"], digits=6), num(r["depth_mm"], digits=6),
                      text(r["kind"]), text("" if r["changed"] == "no" else r["changed"])]) for r in rows]
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
        " (the delivered design of <code>optimised.step</code>; the rows changed \"added\" are the added target "
        "holes cadfeat recommends)" if any(r["changed"] == "added" for r in rows) else "") + ".</p>"
