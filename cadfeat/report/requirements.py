"""Kept requirements, one row each with the B-rep and re-imported STEP checks side by side; active ones first.

``results["constraints"]`` holds one entry per requirement and per check (``checked_on`` "brep" or "step");
``requirement_rows`` merges them by (name, holes). A requirement is *active* when its smallest margin is
below ``ACTIVE_MARGIN_MM`` (mm; "fraction" requirements: ``ACTIVE_MARGIN_FRAC`` of the required value):
the optimum sits on it and a shop tolerance of that size could break it. Every requirement the optimiser
used (``results["requirements_used"]``, the 2-D model's rows) must appear among the verified rows; any that
does not is listed as "not verified" (a verification gap, shown on top).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from cadfeat.report.html import esc, fmt, note, num, table, text

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
    checks: dict[str, dict] = field(default_factory=dict)

    @property
    def margin(self) -> float:
        """Smallest margin over the checks (mm or the requirement's unit); +inf without checks."""
        ms = [c.get("margin") for c in self.checks.values() if isinstance(c.get("margin"), int | float)]
        return min(ms) if ms else float("inf")

    @property
    def ok(self) -> bool:
        return all(bool(c.get("ok", True)) for c in self.checks.values())

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


def _key(name: Any, holes: Any) -> tuple[str, tuple[str, ...]]:
    hs = holes if isinstance(holes, list | tuple) else ([] if holes is None else [holes])
    return str(name), tuple(sorted(str(h) for h in hs))


def requirement_rows(results: dict) -> list[Requirement]:
    """Requirements merged by (name, holes), sorted: violated, unverified, active (smallest margin first),
    then the rest by margin."""
    reqs: dict[tuple[str, tuple[str, ...]], Requirement] = {}
    names = _hole_names(results)
    for c in results.get("constraints") or []:
        if not isinstance(c, dict):
            continue
        holes = [names.get(h, h) if isinstance(h, int) else h for h in c.get("holes") or []]
        key = _key(c.get("name"), holes)
        req = reqs.setdefault(key, Requirement(key[0], key[1], c.get("required"), str(c.get("unit", ""))))
        req.checks[str(c.get("checked_on") or "brep")] = c
    for u in results.get("requirements_used") or []:
        if not isinstance(u, dict) or str(u.get("name", "")).startswith("threshold:"):
            continue
        key = _key(u.get("name"), u.get("holes"))
        req = reqs.setdefault(key, Requirement(key[0], key[1], u.get("required"), str(u.get("unit", "mm"))))
        req.checks.setdefault("model", {"margin": u.get("margin"), "ok": True, "value": None})
    rank = {"VIOLATED": 0, "not verified": 1, "active": 2, "ok": 3}
    return sorted(reqs.values(), key=lambda r: (rank[r.status], r.margin))


def _hole_names(results: dict) -> dict[int, str]:
    holes = results.get("holes") or {}
    return {h.get("index", i): str(h.get("name")) for i, h in enumerate(holes.get("after") or holes.get("before")
                                                                         or []) if h.get("name")}


def _row(r: Requirement, places: list[str]) -> str:
    cells = [text(r.name), text(", ".join(r.holes)), num(r.required), text(r.unit)]
    for p in places:
        c = r.checks.get(p) or {}
        cells += [num(c.get("value")), num(c.get("margin"))]
    return "".join(cells) + text(r.status, "text status")


def requirements_table(results: dict) -> str:
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
