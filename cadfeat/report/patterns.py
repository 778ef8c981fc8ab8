"""The report's pattern section: hole patterns of the original (bolt circles, grids, mirror pairs) and whether
the new design keeps them (results.json ``patterns``, from ``cadfeat.design.patterns``)."""

from __future__ import annotations

from cadfeat.report.html import esc, fmt, note, table, text

_KIND = {"bolt_circle": "bolt circle", "grid": "grid", "opposite": "opposite pair", "mirror": "mirror pair"}


def _describe(p: dict) -> str:
    if p.get("kind") == "bolt_circle":
        return f"{p.get('count', len(p.get('holes') or []))} holes on Ø{fmt(2 * float(p.get('radius_mm', 0)))} mm"
    if p.get("kind") == "grid":
        shape, pitch = p.get("shape") or [], p.get("pitch_mm") or []
        return f"{' × '.join(map(str, shape))}, pitch {' × '.join(fmt(float(v)) for v in pitch)} mm"
    if p.get("kind") == "opposite":
        return "diametrically opposite about the centre axis"
    if p.get("kind") == "mirror":
        return "mirrored in the plane normal to " + "xyz"[int(max(range(3), key=lambda k: abs(p["normal"][k])))] \
            if p.get("normal") else "mirror pair"
    return ""


def patterns_section(results: dict) -> str:
    """Table (id ``patterns``) of the patterns with a movable hole; broken ones first and flagged."""
    pats = [p for p in results.get("patterns") or [] if isinstance(p, dict)]
    if not pats:
        return ""
    pats = sorted(pats, key=lambda p: not p.get("broken"))
    rows = ["".join([text(_KIND.get(p.get("kind"), p.get("kind"))), text(", ".join(map(str, p.get("holes") or []))),
                     text(_describe(p)), text("BROKEN" if p.get("broken") else "kept", "text status"),
                     text(p.get("why") or "")]) for p in pats]
    broken = sum(bool(p.get("broken")) for p in pats)
    head = note(f"The design breaks {broken} pattern(s) of the original.", "warning") if broken else \
        f"<p>All {len(pats)} patterns of the original that involve a movable hole are kept.</p>"
    keep = ((results.get("inputs") or {}).get("shop") or {}).get("keep_patterns")
    if keep is not None:
        head += f"<p>[shop] keep_patterns = {esc(str(bool(keep)).lower())}.</p>"
    return head + table(["pattern", "holes", "in the original", "design", "why"], rows, "patterns",
                        row_classes=["violated" if p.get("broken") else "ok" for p in pats])
