"""The report's "What limits the answer" section: the limiting objective, each objective's change in its own
units, objectives that do not depend on the design, the scored holes, hidden fractions, pre-flight
assumptions and warnings (results.json ``objectives``, ``measures``, ``preflight``, ``warnings``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from cadfeat.report.html import esc, note, num, table, text
from cadfeat.results import Measures, Objectives, StudyResults, value
from cadfeat.results import section as typed_section

__all__ = ["section"]


def _objective_parts(obj: Objectives) -> list[str]:
    parts = []
    if obj.limiting or obj.limiting_before:
        after = f" → after: <b>{esc(obj.limiting)}</b>" if obj.limiting else ""
        parts.append(f"<p>Limiting objective (smallest normalised value in the max-min): before: "
                     f"<b>{esc(obj.limiting_before)}</b>{after}.</p>")
    rows = ["".join([text(c.name), text(c.unit), num(c.before), num(c.after), num(c.change),
                     num(c.normalised_after if "normalised_after" in c.model_fields_set else c.normalised_before),
                     text("yes" if c.in_combination else "no")]) for c in obj.changes]
    if rows:
        parts.append(table(["objective", "unit", "before", "after", "change", "normalised", "in combination"],
                           rows, "objective-changes"))
    if obj.score:
        parts.append(f"<p>Scored holes: {esc(obj.score)}; occlusion by the part "
                     f"{'counted' if obj.occlusion else 'NOT counted'}.</p>")
    return parts


def section(results: StudyResults | Mapping[str, Any]) -> str:
    """HTML of the section, or "" when the results carry none of it."""
    obj = typed_section(results, "objectives", Objectives)
    parts = _objective_parts(obj) if obj is not None else []
    measures = typed_section(results, "measures", Measures)
    hidden_rows: list[str] = []
    after = {f.name: f for f in (measures.after.per_feature if measures and measures.after else [])}
    for f in measures.before.per_feature if measures else []:
        g = after.get(f.name)
        hidden_rows.append("".join([text(f.name), num(f.hidden_frac), num(g.hidden_frac if g else None),
                                    text(f.hidden_worst_pose if f.hidden_worst_pose is not None else "-"),
                                    num(f.folded_frac)]))
    if hidden_rows:
        parts.append(table(["hole", "hidden fraction before", "hidden fraction after", "first hidden pose",
                            "past lens fold (fraction)"], hidden_rows, "hidden-holes"))
    pre = value(results, "preflight") or {}
    for a in pre.get("assumptions") or []:
        parts.append(note(f"Assumed: {a}", "warning"))
    for w in list(obj.warnings if obj else []) + list(value(results, "warnings") or []):
        parts.append(note(f"Warning: {w}", "warning"))
    return "".join(parts)
