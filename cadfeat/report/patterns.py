"""The report's pattern section: hole patterns of the original (bolt circles, grids, mirror pairs) and whether
the new design keeps them (results.json ``patterns``, from ``cadfeat.design.patterns``; typed ``results.Pattern``)."""

from __future__ import annotations

from cadfeat.report.html import esc, fmt, note, table, text
from cadfeat.results import Pattern, Results, value

_KIND = {"bolt_circle": "bolt circle", "grid": "grid", "opposite": "opposite pair", "mirror": "mirror pair"}


def _describe(p: Pattern) -> str:
    if p.kind == "bolt_circle":
        count = p.count if "count" in p.model_fields_set else len(p.holes)
        return f"{count} holes on Ø{fmt(2 * float(p.radius_mm or 0))} mm"
    if p.kind == "grid":
        shape, pitch = p.shape or [], p.pitch_mm or []
        return f"{' × '.join(map(str, shape))}, pitch {' × '.join(fmt(float(v)) for v in pitch)} mm"
    if p.kind == "opposite":
        return "diametrically opposite about the centre axis"
    if p.kind == "mirror":
        normal = p.normal
        return "mirrored in the plane normal to " + "xyz"[int(max(range(3), key=lambda k: abs(normal[k])))] \
            if normal else "mirror pair"
    return ""


def patterns(results: Results) -> list[Pattern]:
    """results.json ``patterns`` as typed records ([] when absent)."""
    return [p if isinstance(p, Pattern) else Pattern.model_validate(p) for p in value(results, "patterns") or []]


def patterns_section(results: Results) -> str:
    """Table (id ``patterns``) of the patterns with a movable hole; broken ones first and flagged."""
    pats = patterns(results)
    if not pats:
        return ""
    pats = sorted(pats, key=lambda p: not p.broken)
    rows = ["".join([text(_KIND.get(p.kind, p.kind)), text(", ".join(map(str, p.holes))),
                     text(_describe(p)), text("BROKEN" if p.broken else "kept", "text status"),
                     text(p.why or "")]) for p in pats]
    broken = sum(bool(p.broken) for p in pats)
    head = note(f"The design breaks {broken} pattern(s) of the original.", "warning") if broken else \
        f"<p>All {len(pats)} patterns of the original that involve a movable hole are kept.</p>"
    keep = ((value(results, "inputs") or {}).get("shop") or {}).get("keep_patterns")
    if keep is not None:
        head += f"<p>[shop] keep_patterns = {esc(str(bool(keep)).lower())}.</p>"
    return head + table(["pattern", "holes", "in the original", "design", "why"], rows, "patterns",
                        row_classes=["violated" if p.broken else "ok" for p in pats])
