"""The report's decision: adopt / adopt with care / do not adopt, from rules stated in the report.

``decide(results)`` applies the rules of ``RULES`` to the results dict (keys of results.json) and returns a
``Verdict``: the decision (the most severe outcome over the rules), one ``Finding`` per rule that applied,
and the per-hole gains and losses in each measure's own unit (``hole_changes``). Nothing here computes a
measure: it reads what the study computed and verified.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, TypeGuard

from cadfeat.report.html import esc, fmt, num, table, text
from cadfeat.report.patterns import patterns
from cadfeat.report.requirements import ACTIVE_MARGIN_MM, requirement_rows
from cadfeat.results import AddedTargets, Measures, Objectives, Results, Robustness, Tracking, section, value

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import VerdictData

ADOPT, CARE, REJECT = "adopt", "adopt with care", "do not adopt"
_SEVERITY = {ADOPT: 0, CARE: 1, REJECT: 2}

#: Relative gain of the combined objective below which the new design is "no better" (fraction of |before|).
MIN_GAIN_FRAC = 0.01

#: The rules, as printed in the report (the order of ``decide``'s checks).
RULES = (
    ("combined", f"The combined objective must improve by at least {100 * MIN_GAIN_FRAC:g} % of its original "
                 "value (a robust study: its robust statistic on held-out draws; a delivered design with added target "
                 "holes: its nominal value, the robust draws holding the move-only optimum); otherwise: do not "
                 "adopt."),
    ("requirements", "Every kept requirement must hold on the rebuilt B-rep and the re-imported STEP; a violated "
                     "or unverified one: do not adopt. An active one (margin below "
                     f"{ACTIVE_MARGIN_MM:g} mm, the position tolerance): adopt with care."),
    ("limiting", "The limiting objective (the smallest normalised objective after, the one that decides a max-min "
                 "design) and every other objective must not get worse; one that does: adopt with care."),
    ("holes", "No hole may newly fail a measure (a margin ≥ 0 before that is < 0 after); one that does: adopt "
              "with care. Losses elsewhere are listed below."),
    ("tracking", "When the pose-tracking validation ran (cadfeat track, [tracking]), it is decisive: an estimator "
                 "that tracks the new design significantly worse (translation and rotation), whatever the "
                 "objectives say: do not adopt. Mixed (better in one of translation/rotation, worse in the "
                 "other): adopt with care."),
    ("robustness", "When the robustness study ran: a delivered design whose combined objective's 5th percentile "
                   "under the whole cell, the camera mounting error or the shop's tolerances is below the "
                   "original's (held-out draws): do not adopt, keep the original. Without the robust comparison: if "
                   "the 5th percentile under the shop tolerance or the camera mounting error keeps less than half "
                   "of the gain (razor-edge optimum): adopt with care."),
    ("patterns", "A hole pattern of the original (bolt circle, grid, mirror pair) broken by the design: adopt "
                 "with care."),
    ("interrupted", "An interrupted optimisation (best design so far, not converged): adopt with care."),
)

#: Per-hole measures compared (key in per_feature, label, unit), larger = better.
HOLE_MEASURES = (("fov_min", "FOV cone margin", ""), ("fov_px_min", "FOV image margin", "px"),
                 ("focus_min", "focus margin", "× half DOF"), ("resolution_px_min", "resolution margin", "px"),
                 ("visible_frac", "visible fraction", ""))
#: Changes smaller than this (absolute, in the measure's unit) are "unchanged".
CHANGE_TOL = 1e-6


@dataclass(frozen=True)
class Finding:
    """One rule's outcome: its key, the decision it asks for, and what was seen."""

    rule: str
    outcome: str
    detail: str


@dataclass(frozen=True)
class HoleChange:
    hole: str
    measure: str
    unit: str
    before: float
    after: float

    @property
    def change(self) -> float:
        return self.after - self.before

    @property
    def newly_failing(self) -> bool:
        return self.before >= 0.0 > self.after and self.measure != "visible fraction"


@dataclass
class Verdict:
    decision: str
    findings: list[Finding] = field(default_factory=list)
    changes: list[HoleChange] = field(default_factory=list)
    limiting: str | None = None


def _is_num(x: object) -> TypeGuard[int | float]:
    return isinstance(x, int | float) and not isinstance(x, bool)


def hole_changes(results: Results) -> list[HoleChange]:
    """Per hole and measure: worst value over the trajectory before and after (own units), changed ones only."""
    m = section(results, "measures", Measures)
    if m is None or m.after is None:
        return []
    before = {f.index: f for f in m.before.per_feature}
    out = []
    for fa in {f.index: f for f in m.after.per_feature}.values():
        fb = before.get(fa.index)
        if fb is None:
            continue
        for key, label, unit in HOLE_MEASURES:
            b, a = getattr(fb, key), getattr(fa, key)
            if b is not None and a is not None and abs(a - b) > CHANGE_TOL:
                out.append(HoleChange(fa.name or f"#{fa.index}", label, unit, float(b), float(a)))
    return out


def limiting_objective(obj: Objectives | None) -> str | None:
    """The objective with the smallest normalised value after (``objectives.limiting`` when the study gives it)."""
    if obj is None:
        return None
    if obj.limiting:
        return obj.limiting
    after = obj.after or {}
    ref = (obj.normalisation.reference if obj.normalisation is not None else None) or {}
    vals = {k: v / (abs(r) if _is_num(r := ref.get(k)) and r else 1.0) for k, v in after.items() if _is_num(v)}
    return min(vals, key=lambda k: vals[k]) if vals else None


def decide(results: Results) -> Verdict:
    """Apply ``RULES`` to the results (typed, or plain data as read); the decision is the most severe outcome."""
    findings: list[Finding] = []
    obj = section(results, "objectives", Objectives)
    cb, ca = (obj.combined_before, obj.combined_after) if obj is not None else (None, None)
    robust = _robust_combined(results)
    k = _added(results)
    if robust is not None and not k:  # a robust study: its statistic out of sample (issue 18), not the nominal value
        nb, na = cb, ca
        cb, ca, what = robust
        gain = ca - cb
        rel = gain / abs(cb) if cb else float("inf") if gain > 0 else 0.0
        findings.append(Finding("combined", ADOPT if rel >= MIN_GAIN_FRAC else REJECT,
                                f"{what} of the combined objective {fmt(cb)} → {fmt(ca)} "
                                f"({'+' if gain >= 0 else '−'}{fmt(abs(100 * rel), 3)} %; nominal "
                                f"{fmt(nb)} → {fmt(na)})"))
    elif cb is not None and ca is not None:
        gain = ca - cb
        rel = gain / abs(cb) if cb else float("inf") if gain > 0 else 0.0
        ok = rel >= MIN_GAIN_FRAC
        detail = f"combined objective {fmt(cb)} → {fmt(ca)} ({'+' if gain >= 0 else '−'}{fmt(abs(100 * rel), 3)} %)"
        if k:  # the delivered design has added holes: its nominal value (the robust draws hold the move-only optimum)
            detail += f", the delivered design with {k} added target holes"
            if robust is not None:
                detail += (f"; {robust[2]} of the move-only optimum {fmt(robust[0])} → {fmt(robust[1])} (the added "
                           "holes are not in the robust draws)")
        findings.append(Finding("combined", ADOPT if ok else REJECT, detail))
    reqs = requirement_rows(results)
    bad = [r for r in reqs if r.status in ("VIOLATED", "not verified")]
    active = [r for r in reqs if r.status == "active"]
    if bad:
        findings.append(Finding("requirements", REJECT, "; ".join(f"{r.name} {'/'.join(r.holes)}: {r.status}"
                                                                   for r in bad[:4])))
    elif active:
        findings.append(Finding("requirements", CARE, "active: " + "; ".join(
            f"{r.name} {'/'.join(r.holes)} margin {fmt(r.margin)} {r.unit}" for r in active[:4])))
    elif reqs:
        findings.append(Finding("requirements", ADOPT, f"all {len(reqs)} hold with margin ≥ {fmt(ACTIVE_MARGIN_MM)}"))
    limiting = limiting_objective(obj)
    before, after = (obj.before, obj.after or {}) if obj is not None else ({}, {})
    worse = [k for k, a in after.items() if a is not None and (b := before.get(k)) is not None and a < b]
    if limiting is not None:
        lb, la = before.get(limiting), after.get(limiting)
        detail = f"limiting objective {limiting}: {fmt(lb)} → {fmt(la)}"
        if worse:
            detail += "; worse: " + ", ".join(f"{k} {fmt(before[k])} → {fmt(after[k])}" for k in worse)
        findings.append(Finding("limiting", CARE if worse else ADOPT, detail))
    changes = hole_changes(results)
    failing = [c for c in changes if c.newly_failing]
    n_gain, n_loss = sum(c.change > 0 for c in changes), sum(c.change < 0 for c in changes)
    still = _failing_after(results)
    if changes or still:
        detail = f"{n_gain} hole measures better, {n_loss} worse"
        if failing:
            detail += "; newly failing: " + ", ".join(f"{c.hole} {c.measure}" for c in failing[:6])
        if still:
            detail += "; failing at the worst pose after: " + ", ".join(f"{label} ({k} of {n} holes)"
                                                                        for label, k, n in still)
        findings.append(Finding("holes", CARE if failing else ADOPT, detail))
    findings += _tracking(results) + _robustness(results) + _patterns(results)
    if value(results, "interrupted"):
        findings.append(Finding("interrupted", CARE, "the optimisation was interrupted"))
    decision = max((f.outcome for f in findings), key=_SEVERITY.get, default=CARE)
    return Verdict(decision, findings, changes, limiting)


def verdict_json(results: Results) -> VerdictData:
    """results.json ``verdict`` (``cadfeat.results.Verdict``): the decision (one of ``adopt``, ``adopt with
    care``, ``do not adopt``), the limiting objective and each applied rule's outcome, so that a pipeline can
    gate on the run's outcome."""
    v = decide(results)
    return {"decision": v.decision, "limiting": v.limiting,
            "findings": [{"rule": f.rule, "outcome": f.outcome, "detail": f.detail} for f in v.findings]}


def _failing_after(results: Results) -> list[tuple[str, int, int]]:
    """(measure, holes with a negative worst margin, holes) of the design after, for each margin measure."""
    m = section(results, "measures", Measures)
    feats = m.after.per_feature if m is not None and m.after is not None else []
    out = []
    for key, label, _ in HOLE_MEASURES[:4]:
        vals = [v for f in feats if (v := getattr(f, key)) is not None]
        k = sum(v < 0 for v in vals)
        if k:
            out.append((label, k, len(vals)))
    return out


def _tracking(results: Results) -> list[Finding]:
    """The closed-loop pose-tracking verdicts (results.json ``tracking.verdicts``: per estimator "better",
    "worse", "mixed" or "no significant difference", ``cadfeat.vision.closed_loop.compare``).

    The closed loop measures what the objectives only predict, so its rule is decisive: one estimator "worse"
    makes the decision "do not adopt" whatever the other rules say; "mixed" asks for care (issue 17)."""
    tr = section(results, "tracking", Tracking)
    if tr is None or not tr.verdicts:
        return []
    per = {str(m): v.verdict for m, v in tr.verdicts.items()}
    k = _added(results)
    what = f"the delivered design (with {k} added target holes) vs the original" if k else "after vs before"
    text = f"pose tracking, {what}: " + ", ".join(f"{m.upper()} {v}" for m, v in per.items())
    outcome = REJECT if "worse" in per.values() else CARE if "mixed" in per.values() else ADOPT
    return [Finding("tracking", outcome, text)]


def _added(results: Results) -> int:
    """The number of added target holes of the delivered design (``added_targets.delivered``), 0 without."""
    block = section(results, "added_targets", AddedTargets)
    if block is None or not block.delivered:
        return 0
    return int(block.recommended)


def _robust_combined(results: Results) -> tuple[float, float, str] | None:
    """(original, delivered, label) of the robust statistic out of sample when the delivered design is the robust
    optimum of a robust study (results.json ``robustness.out_of_sample``), else None."""
    rb = section(results, "robustness", Robustness)
    if rb is None or rb.delivered != "robust":
        return None
    oos = rb.out_of_sample
    per = oos.designs if oos is not None else {}
    a, b = (per[k].out_of_sample if k in per else None for k in ("original", "robust"))
    if a is None or b is None or oos is None:
        return None
    return float(a), float(b), f"robust {oos.statistic} (held-out draws)"


def _robustness(results: Results) -> list[Finding]:
    rb = section(results, "robustness", Robustness)
    if rb is not None and rb.recommended:  # the robust comparison (issue 18) decides
        rec, delivered = rb.recommended, str(rb.delivered)
        flagged = [f for f in rb.flagged if f != rec]
        detail = f"recommended: {rec} ({rb.reason})"
        if flagged:
            detail += "; flagged as more fragile than the original: " + ", ".join(map(str, flagged))
        outcome = REJECT if rec == "original" else ADOPT if rec == delivered else CARE
        if rec not in ("original", delivered):
            detail += f"; the exported files hold the {delivered} optimum"
        if _added(results):
            detail += "; of the move-only optimum (the added target holes are not in the robust draws)"
        return [Finding("robustness", outcome, detail)]
    if rb is None or "razor_edge" not in rb.model_fields_set:
        return []
    edges = rb.razor_edge
    of = " (the move-only optimum; the added target holes are not in the robust draws)" if _added(results) else ""
    return [Finding("robustness", CARE if edges else ADOPT,
                    (("razor-edge: " + ", ".join(map(str, edges))) if edges
                     else "the combined objective keeps at least half of its gain under the tolerances") + of)]


def _patterns(results: Results) -> list[Finding]:
    pats = patterns(results)
    if not pats:
        return []
    broken = [p for p in pats if p.broken]
    return [Finding("patterns", CARE if broken else ADOPT,
                    ("broken: " + ", ".join(f"{p.kind} {'/'.join(map(str, p.holes))}"
                                            for p in broken)) if broken
                    else f"all {len(pats)} patterns of the original kept")]


# ------------------------------------------------------------------------------------------------ HTML
_CSS = {ADOPT: "adopt", CARE: "care", REJECT: "reject"}


def verdict_section(results: Results) -> str:
    """The decision banner, the rules with what each saw, and the per-hole gains and losses."""
    v = decide(results)
    rows = []
    classes = []
    seen = {f.rule: f for f in v.findings}
    for key, rule in RULES:
        f = seen.get(key)
        rows.append("".join([text(rule), text(f.outcome if f else "n/a"), text(f.detail if f else "did not apply")]))
        classes.append(_CSS[f.outcome] if f else "")
    out = (f'<div class="verdict-box {_CSS[v.decision]}"><span class="big">Verdict: '
           f'<span id="verdict">{esc(v.decision)}</span></span>'
           + (f' — limiting objective <span id="limiting-objective">{esc(v.limiting)}</span>' if v.limiting else "")
           + "</div>"
           + "<p>The decision is the most severe outcome over these rules:</p>"
           + table(["rule", "outcome", "what the study shows"], rows, "verdict-rules", row_classes=classes))
    out += changes_table(v.changes)
    return out


def changes_table(changes: list[HoleChange]) -> str:
    """What got better and what got worse, per hole and measure (worst over the trajectory, own units)."""
    if not changes:
        return ""
    ordered = sorted(changes, key=lambda c: (c.change > 0, c.hole, c.measure))  # losses first
    rows = ["".join([text(c.hole), text(c.measure), text(c.unit), num(c.before), num(c.after),
                     num(c.change, "better" if c.change > 0 else "worse"),
                     text("newly failing" if c.newly_failing else "")]) for c in ordered]
    n_loss = sum(c.change < 0 for c in changes)
    return (f"<h3>What got better and what got worse</h3><p>{len(changes) - n_loss} better, {n_loss} worse "
            "(each hole's worst value over the trajectory; margins: positive = satisfied).</p>"
            + table(["hole", "measure", "unit", "before", "after", "change", ""], rows, "hole-changes"))
