"""The report's tables, built from the results dict (keys of results.json, contracts.md).

Each function returns an HTML fragment, or "" when its data is absent. Numbers keep their exact value in
``data-value`` (see ``html.num``). Margins follow DESIGN.md: positive = satisfied, larger = better.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from cadfeat.report.html import esc, fmt, note, num, table, text

#: Moves smaller than this (mm) count as "did not move".
MOVE_TOL_MM = 1e-6

#: Per-feature columns of the thesis-Table-5.1-like table: (key in per_feature, heading).
FEATURE_COLUMNS = (("fov_min", "FOV cone margin"), ("fov_px_min", "FOV image margin (px)"),
                   ("focus_min", "focus margin"), ("resolution_px_min", "resolution margin (px)"),
                   ("visible_frac", "visible fraction"), ("worst_pose", "worst pose"))


def _by_index(items: Sequence[dict] | None) -> dict[Any, dict]:
    return {it.get("index", i): it for i, it in enumerate(items or []) if isinstance(it, dict)}


def is_evaluation(results: dict) -> bool:
    """True for results of ``cadfeat evaluate`` (one design, no "after")."""
    return bool(results.get("evaluation_only")) or not ((results.get("measures") or {}).get("after")
                                                         or (results.get("objectives") or {}).get("after"))


def _change_css(before: Any, after: Any) -> str:
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in (before, after)):
        return ""
    return "better" if after > before else "worse" if after < before else ""


def _label(item: dict, index: Any) -> str:
    return str(item.get("name") or f"H{index + 1}")


# ------------------------------------------------------------------------------------------------ summary
def hole_moves(results: dict) -> list[dict]:
    """Per hole present before and after: displacement of the centre (mm) and diameter change (mm)."""
    holes = results.get("holes") or {}
    before, after = _by_index(holes.get("before")), _by_index(holes.get("after"))
    moves = []
    for index, hb in before.items():
        ha = after.get(index)
        if ha is None:
            continue
        cb, ca = np.asarray(hb.get("centre_mm", [np.nan] * 3), float), np.asarray(ha.get("centre_mm", [np.nan] * 3),
                                                                                    float)
        rb, ra = float(hb.get("radius_mm", np.nan)), float(ha.get("radius_mm", np.nan))
        moves.append(dict(index=index, name=_label(ha, index), fixed=bool(hb.get("fixed", False)),
                          centre_before=cb, centre_after=ca, moved_mm=float(np.linalg.norm(ca - cb)),
                          diameter_before=2 * rb, diameter_after=2 * ra))
    return moves


def summary(results: dict) -> str:
    """What moved (mm), what improved (objectives) and the combined objective before → after."""
    parts = []
    if results.get("interrupted"):
        parts.append(note("The optimisation was interrupted: these are the best results found before it "
                          "stopped, not a converged optimum.", "warning"))
    if is_evaluation(results):
        return _evaluation_summary(results)
    moves = hole_moves(results)
    moved = [m for m in moves if m["moved_mm"] > MOVE_TOL_MM or abs(m["diameter_after"] - m["diameter_before"])
             > MOVE_TOL_MM]
    if moves:
        largest = max(moves, key=lambda m: m["moved_mm"])
        parts.append(f'<p class="big">{len(moved)} of {len(moves)} holes changed; the largest move is '
                     f'{esc(fmt(largest["moved_mm"]))} mm ({esc(largest["name"])}).</p>')
    obj = results.get("objectives") or {}
    cb, ca = obj.get("combined_before"), obj.get("combined_after")
    if cb is not None or ca is not None:
        parts.append(f'<p class="big">Combined objective ({esc(obj.get("combine", "?"))}, aggregate '
                     f'{esc(obj.get("aggregate", "?"))}): <span id="combined-before">{esc(fmt(cb))}</span> → '
                     f'<span id="combined-after">{esc(fmt(ca))}</span></p>')
    changes = objective_changes(obj)
    if changes:
        parts.append("<p>" + "; ".join(f"{esc(name)} {esc(fmt(b))} → {esc(fmt(a))}"
                                       + (f" ({'+' if pct >= 0 else '−'}{esc(fmt(abs(pct), 3))} %)"
                                          if pct is not None else "")
                                       for name, b, a, pct in changes) + ".</p>")
    parts += [moves_table(moves), variables_table(results), objectives_table(results)]
    return "".join(p for p in parts if p)


def _evaluation_summary(results: dict) -> str:
    """Summary of an evaluation (no optimisation): the current design's objectives."""
    obj = results.get("objectives") or {}
    n_holes = len((results.get("holes") or {}).get("before") or [])
    pose = (results.get("trajectory") or {}).get("pose")
    where = f"at trajectory sample {esc(pose)}" if pose is not None else "along the whole trajectory"
    out = f'<p class="big">Evaluation of the current design ({n_holes} holes) {where}; nothing was optimised.</p>'
    if obj.get("combined_before") is not None:
        out += (f'<p class="big">Combined objective: <span id="combined-before">'
                f'{esc(fmt(obj["combined_before"]))}</span></p>')
    before = obj.get("before") or {}
    if before:
        rows = ["".join([text(k), num(v)]) for k, v in before.items()]
        out += table(["objective", "value"], rows, "objectives")
    return out


def moves_table(moves: list[dict]) -> str:
    """Hole centres and diameters before and after, with the move length in mm."""
    if not moves:
        return ""
    rows, classes = [], []
    for m in moves:
        cells = [text(m["name"]), text("fixed" if m["fixed"] else "free"),
                 text(", ".join(fmt(float(c)) for c in m["centre_before"]), "mono"),
                 text(", ".join(fmt(float(c)) for c in m["centre_after"]), "mono"),
                 num(m["moved_mm"]), num(m["diameter_before"]), num(m["diameter_after"])]
        rows.append("".join(cells))
        classes.append("moved" if m["moved_mm"] > MOVE_TOL_MM else "")
    return table(["hole", "", "centre before (mm)", "centre after (mm)", "moved (mm)", "Ø before (mm)",
                  "Ø after (mm)"], rows, "moves", row_classes=classes)


def variables_table(results: dict) -> str:
    """Design variables: bounds, value before and after."""
    variables = [v for v in results.get("variables") or [] if isinstance(v, dict)]
    if not variables:
        return ""
    rows = []
    for v in variables:
        b, a = v.get("before"), v.get("after")
        change = a - b if all(isinstance(x, int | float) for x in (a, b)) else None
        sizes = v.get("standard_sizes")
        rows.append("".join([text(v.get("name")), text(v.get("unit", "")), num(v.get("lower")), num(v.get("upper")),
                             num(b), num(a), num(change), text(", ".join(fmt(s) for s in sizes) if sizes else "")]))
    return table(["variable", "unit", "lower", "upper", "before", "after", "change", "standard sizes"], rows,
                 "variables")


def objective_changes(obj: dict) -> list[tuple[str, Any, Any, float | None]]:
    """(name, before, after, relative change in % of |before| or None) for each named objective."""
    before, after = obj.get("before") or {}, obj.get("after") or {}
    names = list(obj.get("names") or []) or list(dict.fromkeys([*before, *after]))
    out = []
    for name in names:
        b, a = before.get(name), after.get(name)
        ok = all(isinstance(x, int | float) and not isinstance(x, bool) for x in (a, b))
        out.append((str(name), b, a, 100.0 * (a - b) / abs(b) if ok and b != 0 else None))
    return out


def objectives_table(results: dict) -> str:
    """Each objective before and after, with the change (objectives are margins: larger is better)."""
    changes = objective_changes(results.get("objectives") or {})
    if not changes:
        return ""
    rows = []
    for name, b, a, rel in changes:
        ok = all(isinstance(x, int | float) and not isinstance(x, bool) for x in (a, b))
        change = a - b if ok else None
        rows.append("".join([text(name), num(b), num(a), num(change, _change_css(b, a)), num(rel, digits=3)]))
    return table(["objective", "before", "after", "change", "change (%)"], rows, "objectives")


# ------------------------------------------------------------------------------------------------ features
def feature_table(results: dict) -> str:
    """Per-hole worst margins before/after (like thesis Table 5.1) from ``measures.*.per_feature``."""
    m = results.get("measures") or {}
    before = _by_index((m.get("before") or {}).get("per_feature"))
    after = _by_index((m.get("after") or {}).get("per_feature"))
    if not before and not after:
        return ""
    designs = [(w, d) for w, d in (("before", before), ("after", after)) if d]
    labels = ["current"] if is_evaluation(results) and len(designs) == 1 else [w for w, _ in designs]
    width = len(designs)
    header: list[str | tuple[str, int]] = ["hole", *((h, width) for _, h in FEATURE_COLUMNS)]
    header2 = [""] + labels * len(FEATURE_COLUMNS)
    rows = []
    for index in dict.fromkeys([*before, *after]):
        fb, fa = before.get(index, {}), after.get(index, {})
        cells = [text(_label(fa or fb, index))]
        for key, _ in FEATURE_COLUMNS:
            b, a = fb.get(key), fa.get(key)
            if before:
                cells.append(num(b))
            if after:
                cells.append(num(a, "" if key == "worst_pose" or not before else _change_css(b, a)))
        rows.append("".join(cells))
    return table(header, rows, "features", header2=header2)


# ------------------------------------------------------------------------------------------------ requirements
def constraints_table(results: dict) -> str:
    """Kept requirements with their margins on the real geometry; violated rows highlighted."""
    checks = [c for c in results.get("constraints") or [] if isinstance(c, dict)]
    if not checks:
        return ""
    holes_info = (results.get("holes") or {})
    names = {h.get("index", i): h.get("name") for i, h in enumerate(holes_info.get("after")
                                                                      or holes_info.get("before") or [])}
    rows, classes = [], []
    for c in checks:
        ok = bool(c.get("ok"))
        holes = c.get("holes")
        if isinstance(holes, list | tuple):
            holes = ", ".join(f"{names[h]} ({h})" if isinstance(h, int) and names.get(h) else str(h) for h in holes)
        rows.append("".join([text(c.get("name")), text(holes if holes is not None else ""), num(c.get("required")),
                             num(c.get("value")), num(c.get("margin")), text(c.get("unit", "")),
                             text(c.get("checked_on", "")), text("ok" if ok else "VIOLATED", "text status")]))
        classes.append("ok" if ok else "violated")
    n_bad = classes.count("violated")
    head = note(f"{n_bad} of {len(checks)} kept requirements are violated.", "warning") if n_bad else \
        f"<p>All {len(checks)} kept requirements hold on the rebuilt geometry.</p>"
    return head + table(["requirement", "holes", "required", "value", "margin", "unit", "checked on", "status"],
                        rows, "constraints", row_classes=classes)


def design_matrix_table(results: dict) -> str:
    """The axiomatic design matrix (§2.2.4) with its coupling verdict; non-zero entries highlighted."""
    dm = results.get("design_matrix")
    if not isinstance(dm, dict) or dm.get("matrix") is None:
        return ""
    matrix = np.atleast_2d(np.asarray(dm["matrix"], dtype=float))
    rows_l = [str(r) for r in dm.get("rows") or []] or [f"F{i + 1}" for i in range(matrix.shape[0])]
    cols_l = [str(c) for c in dm.get("cols") or []] or [f"P{j + 1}" for j in range(matrix.shape[1])]
    scale = float(np.max(np.abs(matrix))) if matrix.size else 0.0
    rows = ["".join([text(r)] + [num(float(v), "nz" if abs(v) > 1e-9 * max(scale, 1.0) else "")
                                 for v in matrix[i]]) for i, r in enumerate(rows_l)]
    out = (f'<p>Verdict: <span class="verdict" id="coupling-verdict">{esc(dm.get("verdict", "?"))}</span></p>'
           + table(["requirement \\ parameter", *cols_l], rows, "design-matrix"))
    if dm.get("note"):
        out += note(str(dm["note"]))
    return out


# ------------------------------------------------------------------------------------------------ provenance
def files_table(results: dict) -> str:
    """Exported files with size and SHA-256."""
    files = [f for f in results.get("files") or [] if isinstance(f, dict)]
    if not files:
        return ""
    rows = ["".join([text(f.get("name")), num(f.get("bytes")), text(f.get("sha256", ""), "mono")]) for f in files]
    return table(["file", "bytes", "SHA-256"], rows, "files")


def verification_table(results: dict) -> str:
    """Round-trip and validity checks of the exported geometry."""
    ver = results.get("verification")
    if not isinstance(ver, dict) or not ver:
        return ""
    rows = ["".join([text(k), num(v) if isinstance(v, int | float) and not isinstance(v, bool) else text(fmt(v))])
            for k, v in ver.items()]
    return table(["check", "result"], rows, "verification")


def key_value_table(data: dict | None, table_id: str, header: tuple[str, str]) -> str:
    """A two-column table of a flat dict (versions, timings)."""
    if not isinstance(data, dict) or not data:
        return ""
    rows = ["".join([text(k), num(v) if isinstance(v, int | float) and not isinstance(v, bool) else text(v)])
            for k, v in data.items()]
    return table(list(header), rows, table_id)


def normalisation_note(results: dict) -> str:
    """How the objectives were made comparable (method, reference values, note)."""
    norm = (results.get("objectives") or {}).get("normalisation")
    if not isinstance(norm, dict) or not norm:
        return ""
    out = f"<p>Method: <b>{esc(norm.get('method', '?'))}</b>.</p>"
    ref = norm.get("reference")
    if isinstance(ref, dict) and ref:
        out += key_value_table(ref, "normalisation-reference", ("objective", "reference value"))
    if norm.get("note"):
        out += note(str(norm["note"]))
    return out


def setup_table(results: dict) -> str:
    """Study, part, camera and trajectory in one short table."""
    study, cam, traj = results.get("study") or {}, results.get("camera") or {}, results.get("trajectory") or {}
    items: list[tuple[str, Any]] = [
        ("study", study.get("name")), ("study file", study.get("file")), ("part", study.get("part")),
        ("part kind", study.get("part_kind")), ("seed", study.get("seed")),
        ("camera", cam.get("name")),
        ("image", f"{cam.get('width')} × {cam.get('height')} px" if cam.get("width") else None),
        ("fx, fy (px)", f"{fmt(cam.get('fx'))}, {fmt(cam.get('fy'))}" if cam.get("fx") else None),
        ("lens", f"{fmt(cam.get('focal_length_mm'))} mm f/{fmt(cam.get('f_number'))}, focus "
                 f"{fmt(cam.get('focus_distance_mm'))} mm" if cam.get("focal_length_mm") else None),
        ("trajectory", traj.get("kind")), ("samples", traj.get("n_samples")),
        ("duration (s)", traj.get("duration_s")), ("cadfeat", results.get("cadfeat_version")),
        ("created", results.get("created"))]
    rows = ["".join([text(k), text(v)]) for k, v in items if v is not None]
    return table(["", ""], rows, "setup") if rows else ""
