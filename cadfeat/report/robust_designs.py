"""The report's robust redesign (issue 18): the original, the nominal optimum and the robust optimum side by side.

Reads results.json ``robustness`` (``cadfeat.study.robust_study.RobustDesigns``): per design and source of
uncertainty the nominal value and the distribution over the held-out draws (a box plot per objective and of the
combined value, matplotlib PNG), which design the rule recommends and why, the in-sample vs out-of-sample robust
statistic, and where the robustness comes from (one-at-a-time 5th-percentile drops) in words. Reads the typed
section ``results.Robustness``.
"""

from __future__ import annotations

from pathlib import Path

from cadfeat.report.html import Relative, esc, figure, note, num, table, text
from cadfeat.results import Results, Robustness, Spread, section

__all__ = ["box_plot", "robust_designs_section"]

COLOURS = {"original": "#7f7f7f", "nominal": "#d95f02", "robust": "#1b9e77"}
SOURCE_LABELS = {"cell": "whole cell", "camera": "camera mount", "placement": "part placement", "path": "path",
                 "pixel_noise": "pixel noise", "manufacturing": "shop"}


Stats = dict[str, dict[str, Spread]]
"""One design's statistics: source of uncertainty → objective (or "combined") → ``Spread``."""


def _order(rb: Robustness) -> list[str]:
    """The three designs in a fixed order: original, nominal optimum, robust optimum (those present)."""
    dists = rb.distributions or {}
    return [k for k in ("original", "nominal", "robust") if k in dists]


def box_plot(rb: Robustness, path: Path) -> Path:
    """Box plots over the held-out draws of the whole cell: one panel per objective and one of the combined value,
    a box per design (original, nominal optimum, robust optimum); the nominal value as a dot."""
    from matplotlib.figure import Figure

    dists = rb.distributions or {}
    designs = _order(rb)
    names = list(dists[designs[0]].objectives_cell) + ["combined"]
    fig = Figure(figsize=(2.3 * len(names) + 0.6, 3.2), dpi=110)
    axes = fig.subplots(1, len(names), squeeze=False)[0]
    stats = {k: _stats_of(rb, k) for k in designs}
    for ax, name in zip(axes, names, strict=True):
        data = [(dists[k].combined.get("cell") if name == "combined" else dists[k].objectives_cell.get(name))
                or [] for k in designs]
        bp = ax.boxplot(data, whis=(5, 95), showfliers=False, patch_artist=True, widths=0.6)
        for patch, k in zip(bp["boxes"], designs, strict=True):
            patch.set_facecolor(COLOURS[k])
            patch.set_alpha(0.55)
        for i, k in enumerate(designs):
            spread = ((stats[k] or {}).get("cell") or {}).get(name)
            nominal = spread.nominal if spread is not None else None
            if nominal is not None:
                ax.plot(i + 1, nominal, "o", color="black", ms=3)
        ax.set_xticks(range(1, len(designs) + 1), designs, fontsize=7)
        ax.set_title(name, fontsize=9)
        ax.tick_params(labelsize=7)
        ax.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, metadata={"Software": None})
    return path


def _stats_of(rb: Robustness, kind: str) -> Stats | None:
    """The per-source statistics of the design that is ``kind`` ("original", "nominal", "robust")."""
    designs = rb.designs or {}
    if kind in designs:
        return designs[kind]
    if kind == rb.recommended or (kind == rb.delivered and rb.recommended == kind):
        return designs.get("recommended")
    return None


def _side_by_side(rb: Robustness) -> str:
    """Combined value per design: nominal, then mean / 5th percentile / minimum under each source."""
    designs = _order(rb)
    sources = [s for s in SOURCE_LABELS if any(s in (_stats_of(rb, k) or {}) for k in designs)]
    rows: list[str] = []
    rec = rb.recommended
    for k in designs:
        st = _stats_of(rb, k) or {}
        comb = {s: (st.get(s) or {}).get("combined") or Spread() for s in sources}
        label = k + (" (recommended)" if k == rec else "") + (" (flagged)" if k in rb.flagged else "")
        cells = [text(label), num(comb[sources[0]].nominal if sources else None)]
        for s in sources:
            cells += [num(comb[s].mean), num(comb[s].p05, "worse" if k in rb.flagged
                                             and s in ("cell", "camera", "manufacturing") else "")]
        rows.append("".join(cells))
    head: list[str | tuple[str, int]] = ["design", "nominal", *[(SOURCE_LABELS[s], 2) for s in sources]]
    return table(head, rows, "robust-designs", header2=["", "", *["mean", "p05"] * len(sources)])


def _out_of_sample(rb: Robustness) -> str:
    oos = rb.out_of_sample
    if oos is None or not oos.designs:
        return ""
    rows = ["".join([text(k), num(v.in_sample), num(v.out_of_sample),
                     num(None if v.in_sample is None or v.out_of_sample is None
                         else v.out_of_sample - v.in_sample)]) for k, v in oos.designs.items()]
    return (f"<p>The robust statistic ({esc(oos.statistic)} of the combined objective, the smallest over "
            f"the whole cell, the camera mount and the shop) in sample — the {esc(oos.draws_in_sample)} "
            f"draws the optimiser saw (seed {esc(oos.seed_in_sample)}) — and out of sample — "
            f"{esc(oos.draws_out_of_sample)} fresh draws (seed {esc(oos.seed_out_of_sample)}). A robust "
            "optimum that lost much more than the others out of sample overfitted the draws.</p>"
            + table(["design", "in sample", "out of sample", "change"], rows, "robust-out-of-sample"))


def robust_designs_section(results: Results, out_dir: Path, rel: Relative) -> str:
    """The sub-section's HTML ('' when results.json has no ``robustness.designs``)."""
    rb = section(results, "robustness", Robustness)
    if rb is None or not rb.designs:
        return ""
    obj, unc = rb.objective, rb.uncertainty or {}
    rec = str(rb.recommended)
    words = {"robust": "the robust optimum", "nominal": "the nominal optimum", "original": "the original design"}
    parts = ["<h3>Original, nominal optimum and robust optimum</h3>",
             f"<p>The robust optimiser maximised the {esc(obj.label if obj else None)} of the combined objective "
             f"over {esc(obj.draws if obj else None)} fixed {esc(obj.sampling if obj else None)} draws of the cell "
             f"(seed {esc(obj.seed if obj else None)}): camera mount ±{esc(unc.get('camera_position_mm'))} mm and "
             f"±{esc(unc.get('camera_angle_deg'))}°, part placement ±{esc(unc.get('placement_position_mm'))} mm "
             f"and ±{esc(unc.get('placement_angle_deg'))}°, path offset ±{esc(unc.get('path_offset_mm'))} mm, speed "
             f"±{esc(unc.get('time_scale_percent'))} %, pixel noise ±{esc(unc.get('pixel_noise_grey'))} grey "
             f"levels, hole position ±{esc(unc.get('position_tol_mm'))} mm and diameter "
             f"±{esc(unc.get('diameter_tol_mm'))} mm ({esc(unc.get('distribution'))}). The statistics below are on "
             "held-out draws. Rule: a design whose combined 5th percentile under the whole cell, the camera mount "
             "or the shop is below the original's is never recommended.</p>"]
    flagged = [f for f in rb.flagged if f != rec]
    parts.append(note(f"Recommended: {words.get(rec, rec)} — {rb.reason}.",
                      "warning" if rec == "original" else "note"))
    if flagged:
        parts.append(note("Flagged (more fragile than the original): " + ", ".join(words.get(f, f) for f in flagged)
                          + ".", "warning"))
    parts.append(_side_by_side(rb))
    try:
        path = box_plot(rb, Path(out_dir) / "img" / "robust_designs.png")
        parts.append(figure(rel(path), "Distribution over the held-out draws of the whole cell, per objective and "
                                       "of the combined value (box: 25th–75th percentile, whiskers: 5th–95th; dot: "
                                       "the nominal value).", "robust designs box plot"))
    except (ImportError, KeyError, IndexError, TypeError) as exc:  # matplotlib missing or no distributions
        parts.append(note(f"no distribution plot: {exc}"))
    parts.append(_out_of_sample(rb))
    sens = rb.sensitivity.words if rb.sensitivity is not None else None
    if sens:
        parts.append(f"<p id=\"robust-sensitivity\">Where the robustness comes from ({esc(words.get(rec, rec))}): "
                     f"{esc(sens)}.</p>")
    return "".join(parts)
