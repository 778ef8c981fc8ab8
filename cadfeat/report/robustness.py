"""The report's robustness table: each objective's nominal value and its 5th percentile and minimum under the
shop tolerance and the camera mounting error (results.json ``robustness``, ``cadfeat.design.robustness``)."""

from __future__ import annotations

from typing import Any

from cadfeat.report.html import esc, fmt, note, num, table, text


def _drop(nominal: Any, value: Any) -> float | None:
    ok = all(isinstance(v, int | float) and not isinstance(v, bool) for v in (nominal, value))
    return 100.0 * (value - nominal) / abs(nominal) if ok and nominal else None


def robustness_section(results: dict) -> str:
    """Table (id ``robustness``); a warning when the optimum is a razor edge."""
    rb = results.get("robustness")
    if not isinstance(rb, dict) or not any(k in rb for k in ("manufacturing", "camera")):
        return ""
    names = [*(rb.get("names") or []), *(["combined"] if "combined" in (rb.get("manufacturing") or {}) else [])]
    rows = []
    for n in names:
        m, c = (rb.get("manufacturing") or {}).get(n) or {}, (rb.get("camera") or {}).get(n) or {}
        nominal = m.get("nominal", c.get("nominal"))
        cells = [text(n), num(nominal)]
        for block in (m, c):
            d = _drop(nominal, block.get("p05"))
            cells += [num(block.get("p05")), num(block.get("min")),
                      num(d, "worse" if d is not None and d < -10 else "", digits=3)]
        rows.append("".join(cells))
    head = (f"<p>{esc(rb.get('samples'))} draws each. Shop: moved or resized holes within "
            f"±{esc(fmt(rb.get('position_tol_mm')))} mm across their axis and ±{esc(rb.get('size_steps'))} size "
            f"step(s) of the hole table. Camera mount: ±{esc(fmt(rb.get('camera_position_mm')))} mm and "
            f"±{esc(fmt(rb.get('camera_angle_deg')))}° per axis, the same for every pose. Set in the study's "
            "[robustness] table.</p>")
    if rb.get("razor_edge"):
        head = note("Razor-edge optimum: under " + " and ".join(map(str, rb["razor_edge"])) + " the combined "
                    "objective's 5th percentile keeps less than half of the gain.", "warning") + head
    return head + table(["objective", "nominal", ("shop tolerance", 3), ("camera mount", 3)], rows, "robustness",
                        header2=["", "", "p05", "min", "p05 change (%)", "p05", "min", "p05 change (%)"])
