"""The report's "What limits the answer" section: the limiting objective, each objective's change in its own
units, objectives that do not depend on the design, the scored holes, hidden fractions, pre-flight
assumptions and warnings (results.json ``objectives``, ``measures``, ``preflight``, ``warnings``)."""

from __future__ import annotations

from cadfeat.report.html import esc, note, num, table, text

__all__ = ["section"]


def section(results: dict) -> str:
    """HTML of the section, or "" when the results carry none of it."""
    obj = results.get("objectives") or {}
    parts = []
    if obj.get("limiting") or obj.get("limiting_before"):
        after = f" → after: <b>{esc(obj['limiting'])}</b>" if obj.get("limiting") else ""
        parts.append(f"<p>Limiting objective (smallest normalised value in the max-min): before: "
                     f"<b>{esc(obj.get('limiting_before'))}</b>{after}.</p>")
    rows = ["".join([text(c["name"]), text(c.get("unit", "")), num(c.get("before")), num(c.get("after")),
                     num(c.get("change")), num(c.get("normalised_after", c.get("normalised_before"))),
                     text("yes" if c.get("in_combination") else "no")]) for c in obj.get("changes") or []]
    if rows:
        parts.append(table(["objective", "unit", "before", "after", "change", "normalised", "in combination"],
                           rows, "objective-changes"))
    if obj.get("score"):
        parts.append(f"<p>Scored holes: {esc(obj['score'])}; occlusion by the part "
                     f"{'counted' if obj.get('occlusion', True) else 'NOT counted'}.</p>")
    measures = results.get("measures") or {}
    hidden_rows = []
    after = {f.get("name"): f for f in (measures.get("after") or {}).get("per_feature") or []}
    for f in (measures.get("before") or {}).get("per_feature") or []:
        g = after.get(f.get("name"), {})
        hidden_rows.append("".join([text(f.get("name")), num(f.get("hidden_frac")), num(g.get("hidden_frac")),
                                    text(f.get("hidden_worst_pose") if f.get("hidden_worst_pose") is not None
                                         else "-"), num(f.get("folded_frac"))]))
    if hidden_rows:
        parts.append(table(["hole", "hidden fraction before", "hidden fraction after", "first hidden pose",
                            "past lens fold (fraction)"], hidden_rows, "hidden-holes"))
    pre = results.get("preflight") or {}
    for a in pre.get("assumptions") or []:
        parts.append(note(f"Assumed: {a}", "warning"))
    for w in list(obj.get("warnings") or []) + list(results.get("warnings") or []):
        parts.append(note(f"Warning: {w}", "warning"))
    return "".join(parts)
