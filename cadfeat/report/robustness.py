"""The report's robustness table: each objective's nominal value and its 5th percentile and minimum under the
shop tolerance and the camera mounting error (results.json ``robustness``, ``cadfeat.design.robustness``; the typed
section ``results.Robustness``)."""

from __future__ import annotations

from cadfeat.report.html import esc, fmt, note, num, table, text
from cadfeat.results import Results, Robustness, Spread, section


def _given(rb: Robustness, name: str) -> object:
    """A key as results.json gives it (None when absent, not the model's default)."""
    return getattr(rb, name) if name in rb.model_fields_set else None


def _drop(nominal: float | None, value: float | None) -> float | None:
    ok = all(isinstance(v, int | float) and not isinstance(v, bool) for v in (nominal, value))
    return 100.0 * (value - nominal) / abs(nominal) if ok and nominal else None


def robustness_section(results: Results) -> str:
    """Table (id ``robustness``); a warning when the optimum is a razor edge."""
    rb = section(results, "robustness", Robustness)
    if rb is None or not {"manufacturing", "camera"} & rb.model_fields_set:
        return ""
    manufacturing, camera = rb.manufacturing or {}, rb.camera or {}
    names = [*rb.names, *(["combined"] if "combined" in manufacturing else [])]
    rows: list[str] = []
    for n in names:
        m, c = manufacturing.get(n), camera.get(n)
        nominal = m.nominal if m is not None and "nominal" in m.model_fields_set else c.nominal if c else None
        cells = [text(n), num(nominal)]
        for block in (m or Spread(), c or Spread()):
            d = _drop(nominal, block.p05)
            cells += [num(block.p05), num(block.min),
                      num(d, "worse" if d is not None and d < -10 else "", digits=3)]
        rows.append("".join(cells))
    head = (f"<p>{esc(_given(rb, 'samples'))} draws each. Shop: moved or resized holes within "
            f"±{esc(fmt(rb.position_tol_mm))} mm across their axis and ±{esc(rb.size_steps)} size "
            f"step(s) of the hole table. Camera mount: ±{esc(fmt(rb.camera_position_mm))} mm and "
            f"±{esc(fmt(rb.camera_angle_deg))}° per axis, the same for every pose. Set in the study's "
            "[robustness] table.</p>")
    if rb.razor_edge:
        head = note("Razor-edge optimum: under " + " and ".join(map(str, rb.razor_edge)) + " the combined "
                    "objective's 5th percentile keeps less than half of the gain.", "warning") + head
    return head + table(["objective", "nominal", ("shop tolerance", 3), ("camera mount", 3)], rows, "robustness",
                        header2=["", "", "p05", "min", "p05 change (%)", "p05", "min", "p05 change (%)"])
