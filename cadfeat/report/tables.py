"""The report's tables, built from results.json's typed sections (``cadfeat.results``: ``section(results, "x",
Model)``; plain data, as read or built by hand, is validated section by section).

Each function returns an HTML fragment, or "" when its data is absent. Numbers keep their exact value in
``data-value`` (see ``html.num``). Margins follow docs/design.md "Conventions": positive = satisfied, larger = better.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Protocol, TypeVar

import numpy as np

from cadfeat.report.html import esc, fmt, note, num, table, text
from cadfeat.results import (
    DesignMatrix,
    FileEntry,
    Holes,
    Measures,
    Number,
    Objectives,
    Record,
    RequirementCheck,
    Results,
    StudyRecord,
    TrajectoryRecord,
    Variable,
    Verification,
    present,
    section,
    value,
)

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cad.features import ShapeLike
    from cadfeat.results import JsonDict

#: Moves smaller than this (mm) count as "did not move".
MOVE_TOL_MM = 1e-6

#: Per-feature columns of the thesis-Table-5.1-like table: (key in per_feature, heading).
FEATURE_COLUMNS = (("fov_min", "FOV cone margin"), ("fov_px_min", "FOV image margin (px)"),
                   ("focus_min", "focus margin"), ("resolution_px_min", "resolution margin (px)"),
                   ("visible_frac", "visible fraction"), ("worst_pose", "worst pose"))


class _Indexed(Protocol):
    index: int
    name: str


I = TypeVar("I", bound=_Indexed)
R = TypeVar("R", bound=Record)


def _by_index(items: Sequence[I] | None) -> dict[int, I]:
    return {it.index: it for it in items or []}


def _records(results: Results, name: str, model: type[R]) -> list[R]:
    """A list section (``variables``, ``constraints``, ``files``) as typed records ([] when absent)."""
    items = value(results, name)
    return [it if isinstance(it, model) else model.model_validate(it) for it in items or []]


def is_evaluation(results: Results) -> bool:
    """True for results of ``cadfeat evaluate`` (one design, no "after")."""
    measures, obj = section(results, "measures", Measures), section(results, "objectives", Objectives)
    return bool(value(results, "evaluation_only")) or not ((measures is not None and present(measures.after))
                                                           or (obj is not None and bool(obj.after)))


def _change_css(before: ShapeLike, after: ShapeLike) -> str:
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in (before, after)):
        return ""
    return "better" if after > before else "worse" if after < before else ""


def _label(item: _Indexed | None, index: int) -> str:
    return str((item.name if item is not None else "") or f"H{index + 1}")


# ------------------------------------------------------------------------------------------------ summary
def hole_moves(results: Results) -> list[JsonDict]:
    """Per hole present before and after: displacement of the centre (mm) and diameter change (mm)."""
    holes = section(results, "holes", Holes)
    before = _by_index(holes.before if holes else None)
    after = _by_index(holes.after if holes else None)
    moves: list[JsonDict] = []
    for index, hb in before.items():
        ha = after.get(index)
        if ha is None:
            continue
        cb, ca = np.asarray(hb.centre_mm, float), np.asarray(ha.centre_mm, float)
        rb, ra = float(hb.radius_mm), float(ha.radius_mm)
        moves.append(dict(index=index, name=_label(ha, index), fixed=bool(hb.fixed),
                          centre_before=cb, centre_after=ca, moved_mm=float(np.linalg.norm(ca - cb)),
                          diameter_before=2 * rb, diameter_after=2 * ra))
    return moves


def summary(results: Results) -> str:
    """What moved (mm), what improved (objectives) and the combined objective before → after."""
    parts: list[str] = []
    if value(results, "interrupted"):
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
    obj = section(results, "objectives", Objectives)
    cb, ca = (obj.combined_before, obj.combined_after) if obj else (None, None)
    if obj is not None and (cb is not None or ca is not None):
        parts.append(f'<p class="big">Combined objective ({esc(obj.combine)}, aggregate '
                     f'{esc(obj.aggregate)}): <span id="combined-before">{esc(fmt(cb))}</span> → '
                     f'<span id="combined-after">{esc(fmt(ca))}</span></p>')
    changes = objective_changes(obj)
    if changes:
        parts.append("<p>" + "; ".join(f"{esc(name)} {esc(fmt(b))} → {esc(fmt(a))}"
                                       + (f" ({'+' if pct >= 0 else '−'}{esc(fmt(abs(pct), 3))} %)"
                                          if pct is not None else "")
                                       for name, b, a, pct in changes) + ".</p>")
    parts += [moves_table(moves), variables_table(results), objectives_table(results)]
    return "".join(p for p in parts if p)


def _evaluation_summary(results: Results) -> str:
    """Summary of an evaluation (no optimisation): the current design's objectives."""
    obj = section(results, "objectives", Objectives)
    holes = section(results, "holes", Holes)
    n_holes = len(holes.before) if holes else 0
    trajectory = section(results, "trajectory", TrajectoryRecord, partial=True)
    pose = trajectory.pose if trajectory else None
    where = f"at trajectory sample {esc(pose)}" if pose is not None else "along the whole trajectory"
    out = f'<p class="big">Evaluation of the current design ({n_holes} holes) {where}; nothing was optimised.</p>'
    if obj is not None and obj.combined_before is not None:
        out += (f'<p class="big">Combined objective: <span id="combined-before">'
                f'{esc(fmt(obj.combined_before))}</span></p>')
    before = obj.before if obj else {}
    if before:
        rows = ["".join([text(k), num(v)]) for k, v in before.items()]
        out += table(["objective", "value"], rows, "objectives")
    return out


def moves_table(moves: list[JsonDict]) -> str:
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


def variables_table(results: Results) -> str:
    """Design variables: bounds, value before and after."""
    variables: list[Variable] = _records(results, "variables", Variable)
    if not variables:
        return ""
    rows: list[str] = []
    for v in variables:
        b, a = v.before, v.after
        change = a - b if a is not None and b is not None else None
        sizes = v.standard_sizes
        rows.append("".join([text(v.name), text(v.unit), num(v.lower), num(v.upper),
                             num(b), num(a), num(change), text(", ".join(fmt(s) for s in sizes) if sizes else "")]))
    return table(["variable", "unit", "lower", "upper", "before", "after", "change", "standard sizes"], rows,
                 "variables")


def objective_changes(obj: Objectives | None) -> list[tuple[str, Number | None, Number | None, float | None]]:
    """(name, before, after, relative change in % of |before| or None) for each named objective."""
    if obj is None:
        return []
    before, after = obj.before, obj.after or {}
    names = list(obj.names) or list(dict.fromkeys([*before, *after]))
    out: list[tuple[str, Number | None, Number | None, float | None]] = []
    for name in names:
        b, a = before.get(name), after.get(name)
        ok = all(isinstance(x, int | float) and not isinstance(x, bool) for x in (a, b))
        out.append((str(name), b, a, 100.0 * (a - b) / abs(b) if ok and b != 0 else None))
    return out


def objectives_table(results: Results) -> str:
    """Each objective before and after, with the change (objectives are margins: larger is better)."""
    changes = objective_changes(section(results, "objectives", Objectives))
    if not changes:
        return ""
    rows: list[str] = []
    for name, b, a, rel in changes:
        ok = all(isinstance(x, int | float) and not isinstance(x, bool) for x in (a, b))
        change = a - b if ok else None
        rows.append("".join([text(name), num(b), num(a), num(change, _change_css(b, a)), num(rel, digits=3)]))
    return table(["objective", "before", "after", "change", "change (%)"], rows, "objectives")


# ------------------------------------------------------------------------------------------------ features
def feature_table(results: Results) -> str:
    """Per-hole worst margins before/after (like thesis Table 5.1) from ``measures.*.per_feature``."""
    m = section(results, "measures", Measures)
    before = _by_index(m.before.per_feature if m else None)
    after = _by_index(m.after.per_feature if m and m.after else None)
    if not before and not after:
        return ""
    designs = [(w, d) for w, d in (("before", before), ("after", after)) if d]
    labels = ["current"] if is_evaluation(results) and len(designs) == 1 else [w for w, _ in designs]
    width = len(designs)
    header: list[str | tuple[str, int]] = ["hole", *((h, width) for _, h in FEATURE_COLUMNS)]
    header2 = [""] + labels * len(FEATURE_COLUMNS)
    rows: list[str] = []
    for index in dict.fromkeys([*before, *after]):
        fb, fa = before.get(index), after.get(index)
        cells = [text(_label(fa or fb, index))]
        for key, _ in FEATURE_COLUMNS:
            b, a = getattr(fb, key, None), getattr(fa, key, None)
            if before:
                cells.append(num(b))
            if after:
                cells.append(num(a, "" if key == "worst_pose" or not before else _change_css(b, a)))
        rows.append("".join(cells))
    return table(header, rows, "features", header2=header2)


# ------------------------------------------------------------------------------------------------ requirements
def constraints_table(results: Results) -> str:
    """Kept requirements with their margins on the real geometry; violated rows highlighted."""
    checks: list[RequirementCheck] = _records(results, "constraints", RequirementCheck)
    if not checks:
        return ""
    holes = section(results, "holes", Holes)
    names = {h.index: h.name for h in (holes.after or holes.before if holes else [])}
    rows: list[str] = []
    classes: list[str] = []
    for c in checks:
        ok = bool(c.ok)
        on = ", ".join(f"{names[h]} ({h})" if isinstance(h, int) and names.get(h) else str(h) for h in c.holes)
        rows.append("".join([text(c.name), text(on), num(c.required),
                             num(c.value), num(c.margin), text(c.unit),
                             text(_given(c, "checked_on", "")), text("ok" if ok else "VIOLATED", "text status")]))
        classes.append("ok" if ok else "violated")
    n_bad = classes.count("violated")
    head = note(f"{n_bad} of {len(checks)} kept requirements are violated.", "warning") if n_bad else \
        f"<p>All {len(checks)} kept requirements hold on the rebuilt geometry.</p>"
    return head + table(["requirement", "holes", "required", "value", "margin", "unit", "checked on", "status"],
                        rows, "constraints", row_classes=classes)


def _given(record: Record, name: str, absent: object) -> object:
    """``record.name`` when the data gave it (None included), else ``absent`` (the model's default may differ)."""
    return getattr(record, name) if name in record.model_fields_set else absent


def design_matrix_table(results: Results) -> str:
    """The axiomatic design matrix (§2.2.4) with its coupling verdict; non-zero entries highlighted."""
    dm = section(results, "design_matrix", DesignMatrix)
    if dm is None:
        return ""
    matrix = np.atleast_2d(np.asarray(dm.matrix, dtype=float))
    rows_l = [str(r) for r in dm.rows] or [f"F{i + 1}" for i in range(matrix.shape[0])]
    cols_l = [str(c) for c in dm.cols] or [f"P{j + 1}" for j in range(matrix.shape[1])]
    scale = float(np.max(np.abs(matrix))) if matrix.size else 0.0
    rows = ["".join([text(r)] + [num(float(v), "nz" if abs(v) > 1e-9 * max(scale, 1.0) else "")
                                 for v in matrix[i]]) for i, r in enumerate(rows_l)]
    out = (f'<p>Verdict: <span class="verdict" id="coupling-verdict">{esc(dm.verdict)}</span></p>'
           + table(["requirement \\ parameter", *cols_l], rows, "design-matrix"))
    if dm.note:
        out += note(str(dm.note))
    return out


# ------------------------------------------------------------------------------------------------ provenance
def files_table(results: Results) -> str:
    """Exported files with size and SHA-256."""
    files: list[FileEntry] = _records(results, "files", FileEntry)
    if not files:
        return ""
    rows = ["".join([text(f.name), num(f.bytes), text(f.sha256, "mono")]) for f in files]
    return table(["file", "bytes", "SHA-256"], rows, "files")


def verification_table(results: Results) -> str:
    """Round-trip and validity checks of the exported geometry (in the order results.json gives them)."""
    ver = section(results, "verification", Verification)
    given = ver.to_data() if ver is not None else {}
    raw = value(results, "verification")
    checks = {k: given[k] for k in raw} if isinstance(raw, Mapping) else given  # in results.json's order
    if not checks:
        return ""
    rows = ["".join([text(k), num(v) if isinstance(v, int | float) and not isinstance(v, bool) else text(fmt(v))])
            for k, v in checks.items()]
    return table(["check", "result"], rows, "verification")


def key_value_table(data: Mapping[str, object] | None, table_id: str, header: tuple[str, str]) -> str:
    """A two-column table of a flat dict (versions, timings)."""
    if not isinstance(data, dict) or not data:
        return ""
    rows = ["".join([text(k), num(v) if isinstance(v, int | float) and not isinstance(v, bool) else text(v)])
            for k, v in data.items()]
    return table(list(header), rows, table_id)


def normalisation_note(results: Results) -> str:
    """How the objectives were made comparable (method, reference values, note)."""
    obj = section(results, "objectives", Objectives)
    norm = obj.normalisation if obj else None
    if norm is None or not present(norm):
        return ""
    out = f"<p>Method: <b>{esc(_given(norm, 'method', '?'))}</b>.</p>"
    if norm.reference:
        out += key_value_table(norm.reference, "normalisation-reference", ("objective", "reference value"))
    if norm.note:
        out += note(str(norm.note))
    return out


def setup_table(results: Results) -> str:
    """Study, part, camera and trajectory in one short table."""
    study = section(results, "study", StudyRecord, partial=True)
    cam, traj = value(results, "camera") or {}, section(results, "trajectory", TrajectoryRecord, partial=True)
    items: list[tuple[str, object]] = [
        ("study", study.name if study else None), ("study file", study.file if study else None),
        ("part", study.part if study else None), ("part kind", study.part_kind if study else None),
        ("seed", study.seed if study else None),
        ("camera", cam.get("name")),
        ("image", f"{cam.get('width')} × {cam.get('height')} px" if cam.get("width") else None),
        ("fx, fy (px)", f"{fmt(cam.get('fx'))}, {fmt(cam.get('fy'))}" if cam.get("fx") else None),
        ("lens", f"{fmt(cam.get('focal_length_mm'))} mm f/{fmt(cam.get('f_number'))}, focus "
                 f"{fmt(cam.get('focus_distance_mm'))} mm" if cam.get("focal_length_mm") else None),
        ("trajectory", traj.kind if traj else None), ("samples", traj.n_samples if traj else None),
        ("duration (s)", traj.duration_s if traj else None), ("cadfeat", value(results, "cadfeat_version")),
        ("created", value(results, "created"))]
    rows = ["".join([text(k), text(v)]) for k, v in items if v is not None]
    return table(["", ""], rows, "setup") if rows else ""
