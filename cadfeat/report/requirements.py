"""Kept requirements, one row each with the B-rep and re-imported STEP checks side by side; active ones first.

results.json ``constraints`` (``results.RequirementCheck``) holds one entry per requirement and per check
(``checked_on`` "brep" or "step"); ``requirement_rows`` merges them by (name, holes). A requirement is *active*
when its smallest margin is below ``ACTIVE_MARGIN_MM`` (mm; "fraction" requirements: ``ACTIVE_MARGIN_FRAC`` of
the required value): the optimum sits on it and a shop tolerance of that size could break it. Every requirement
the optimiser used (``requirements_used``, ``results.RequirementUsed``: the 2-D model's rows) must appear among
the verified rows; any that does not is listed as "not verified" (a verification gap, shown on top).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TypeVar

from cadfeat.report.html import esc, fmt, note, num, table, text
from cadfeat.results import Holes, Record, RequirementCheck, RequirementUsed, Results, section, value

R = TypeVar("R", bound=Record)

#: Margin (mm) below which a kept requirement counts as active (= the default position tolerance).
ACTIVE_MARGIN_MM = 0.1
#: For requirements in other units (fraction, mm³): active below this share of the required value.
ACTIVE_MARGIN_FRAC = 0.01
#: Checks whose margin is a tolerance by construction (holes match the design, fixed holes unchanged, mirror
#: pairs exact): never "active", shown among the rows with room to spare while they hold.
_BOOKKEEPING = ("holes_match", "fixed", "symmetry")


@dataclass
class Requirement:
    """One kept requirement with its checks by place ("brep", "step", "model")."""

    name: str
    holes: tuple[str, ...]
    required: float | None
    unit: str
    checks: dict[str, RequirementCheck] = field(default_factory=dict[str, RequirementCheck])

    @property
    def margin(self) -> float:
        """Smallest margin over the checks (mm or the requirement's unit); +inf without checks."""
        ms = [c.margin for c in self.checks.values() if c.margin is not None]
        return min(ms) if ms else float("inf")

    @property
    def ok(self) -> bool:
        """No check failed (a check that does not say counts as passed)."""
        return all("ok" not in c.model_fields_set or bool(c.ok) for c in self.checks.values())

    @property
    def verified(self) -> bool:
        return any(k in self.checks for k in ("brep", "step"))

    def active(self) -> bool:
        if self.name in _BOOKKEEPING:
            return False
        tol = ACTIVE_MARGIN_MM if self.unit == "mm" else ACTIVE_MARGIN_FRAC * abs(self.required or 1.0)
        return self.margin < tol

    @property
    def status(self) -> str:
        if not self.ok:
            return "VIOLATED"
        if not self.verified:
            return "not verified"
        return "active" if self.active() else "ok"


def _key(name: object, holes: object) -> tuple[str, tuple[str, ...]]:
    hs: list[object] | tuple[object, ...] = holes if isinstance(holes, list | tuple) else \
        ([] if holes is None else [holes])
    return str(name), tuple(sorted(str(h) for h in hs))


def _records(results: Results, name: str, model: type[R]) -> list[R]:
    return [it if isinstance(it, model) else model.model_validate(it) for it in value(results, name) or []]


def requirement_rows(results: Results) -> list[Requirement]:
    """Requirements merged by (name, holes), sorted: violated, unverified, active (smallest margin first),
    then the rest by margin."""
    reqs: dict[tuple[str, tuple[str, ...]], Requirement] = {}
    names = _hole_names(results)
    checks: list[RequirementCheck] = _records(results, "constraints", RequirementCheck)
    for c in checks:
        holes = [names.get(h, h) if isinstance(h, int) else h for h in c.holes]
        key = _key(c.name, holes)
        req = reqs.setdefault(key, Requirement(key[0], key[1], c.required, c.unit))
        req.checks[str(c.checked_on or "brep")] = c
    used: list[RequirementUsed] = _records(results, "requirements_used", RequirementUsed)
    for u in used:
        if u.name.startswith("threshold:"):
            continue
        key = _key(u.name, u.holes)
        req = reqs.setdefault(key, Requirement(key[0], key[1], u.required, u.unit))
        req.checks.setdefault("model", RequirementCheck(name=u.name, margin=u.margin, ok=True, value=None))
    rank = {"VIOLATED": 0, "not verified": 1, "active": 2, "ok": 3}
    return sorted(reqs.values(), key=lambda r: (rank[r.status], r.margin))


def _hole_names(results: Results) -> dict[int, str]:
    holes = section(results, "holes", Holes)
    return {h.index: h.name for h in (holes.after or holes.before if holes else []) if h.name}


def _row(r: Requirement, places: list[str]) -> str:
    cells = [text(r.name), text(", ".join(r.holes)), num(r.required), text(r.unit)]
    for p in places:
        c = r.checks.get(p)
        cells += [num(c.value if c else None), num(c.margin if c else None)]
    return "".join(cells) + text(r.status, "text status")


def requirements_table(results: Results) -> str:
    """The requirement table (id ``constraints``: active/violated/unverified rows; id ``constraints-trivial``:
    the others inside a closed ``<details>``), with a one-line summary on top."""
    reqs = requirement_rows(results)
    if not reqs:
        return ""
    places = [p for p in ("brep", "step") if any(p in r.checks for r in reqs)] or ["brep"]
    header: list[str | tuple[str, int]] = ["requirement", "holes", "required", "unit",
                                           *((_PLACE[p], 2) for p in places), "status"]
    header2 = ["", "", "", "", *(["value", "margin"] * len(places)), ""]
    top = [r for r in reqs if r.status != "ok"]
    rest = [r for r in reqs if r.status == "ok"]
    css = {"VIOLATED": "violated", "not verified": "violated", "active": "active", "ok": "ok"}
    n_bad = sum(r.status == "VIOLATED" for r in reqs)
    n_gap = sum(r.status == "not verified" for r in reqs)
    n_active = sum(r.status == "active" for r in reqs)
    parts = []
    if n_bad:
        parts.append(note(f"{n_bad} of {len(reqs)} kept requirements are violated.", "warning"))
    if n_gap:
        parts.append(note(f"{n_gap} requirement(s) used by the optimiser have no check on the rebuilt geometry.",
                          "warning"))
    parts.append(f'<p id="requirements-summary">{len(reqs)} kept requirements, checked on '
                 f'{esc(" and ".join(_PLACE[p] for p in places))}: <b>{n_active}</b> active (margin &lt; '
                 f'{esc(fmt(ACTIVE_MARGIN_MM))} mm: the design sits on them), {n_bad} violated, '
                 f'{len(rest)} with room to spare (folded below).</p>')
    if top:
        parts.append(table(header, [_row(r, places) for r in top], "constraints", header2=header2,
                           row_classes=[css[r.status] for r in top]))
    if rest:
        parts.append(f"<details><summary>{len(rest)} requirements with room to spare</summary>"
                     + table(header, [_row(r, places) for r in rest], "constraints-trivial", header2=header2,
                             row_classes=["ok"] * len(rest)) + "</details>")
    return "".join(parts)


_PLACE = {"brep": "B-rep", "step": "re-imported STEP", "model": "optimiser model"}
