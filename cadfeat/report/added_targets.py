"""Report section "Where would new target holes help?" from results.json's ``added_targets`` (issue 31).

The diminishing-returns curve (the predicted RMS pose error against the number of added holes, the recommended
number marked), the recommendation and its reason, the added holes (status "added"), the predicted error of the
original, the move-only optimum and the added design, the requirement checks on the B-rep and the re-imported
STEP, and the closed loop of the three designs (the delivered added design against the original and the move-only
optimum, the move-only optimum against the original). Empty without the section.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from cadfeat.report.html import Relative, esc, figure, fmt, note, num, table, text
from cadfeat.results import AddedTargets, Results, section

__all__ = ["added_targets_section", "curve_plot"]


def curve_plot(block: AddedTargets, path: Path) -> Path:
    """The predicted RMS pose error (mm) against the number of added holes, the recommended number marked."""
    from matplotlib.figure import Figure

    curve = block.curve
    assert curve is not None
    fig = Figure(figsize=(5.6, 3.4), dpi=110)
    ax = fig.subplots()
    k, e = list(curve.added), [float(v) for v in curve.error_mm]
    ax.plot(k, e, "o-", color="#1b9e77", lw=1.6, label="lazy greedy (move-only optimum + k holes)")
    r = block.recommended
    ax.plot([r], [e[r]], "s", color="#d95f02", ms=9, label=f"recommended: {r}")
    added = block.predicted.get("added")
    if added is not None and r:
        ax.plot([r], [float(added["error_mm"])], "*", color="#7570b3", ms=11, label="refined, drilled in CAD")
    ax.set_xlabel("added target holes")
    what = {"rms": "RMS", "worst": "worst"}.get(curve.aggregate, curve.aggregate)
    ax.set_ylabel(f"predicted {what} pose error (mm)")
    ax.set_xticks(k)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    return path


def _holes(block: AddedTargets) -> str:
    rows = [f"<tr>{text(h.name)}{num(h.centre[0], digits=4)}{num(h.centre[1], digits=4)}{num(h.centre[2], digits=4)}"
            f"{num(h.diameter_mm)}{num(h.depth_mm)}{num(h.chamfer_mm)}{text(h.face)}{text(h.status)}</tr>"
            for h in block.holes]
    return table(["hole", "x (mm)", "y (mm)", "z (mm)", "Ø (mm)", "depth (mm)", "chamfer (mm)", "face", "status"],
                 rows, "added-holes")


def _predicted(block: AddedTargets) -> str:
    names = {"original": "original", "move_only": "move-only optimum", "added": "with the added holes"}
    rows = [f"<tr>{text(label)}{num(block.predicted[key]['error_mm'])}{num(block.predicted[key]['translation_mm'])}"
            f"{num(block.predicted[key]['rotation_deg'])}</tr>" for key, label in names.items() if key in
            block.predicted]
    return table(["design", "RMS error (mm, rotation at ℓ)", "translation (mm)", "rotation (deg)"], rows,
                 "added-predicted")


def _checks(block: AddedTargets) -> str:
    bad = [c for c in block.constraints if not c.get("ok")]
    where = sorted({str(c.get("checked_on")) for c in block.constraints})
    if bad:
        return note(f"{len(bad)} requirement(s) broken: " + "; ".join(f"{c.get('name')} {c.get('holes')}"
                                                                       for c in bad), "warning")
    return (f"<p>All {len(block.constraints)} kept requirements of the added holes hold, measured on "
            f"{esc(' and '.join(where))} (edge distance, keep-outs, ligaments: OCCT distances on the solid).</p>")


def _mean(v: Any) -> Any:
    return v.get("mean") if isinstance(v, dict) else None


_COMPARED = {"added_vs_original": ("original", "added", "the delivered design (added holes) vs the original"),
             "move_only_vs_original": ("original", "move_only", "the move-only optimum vs the original"),
             "added_vs_move_only": ("move_only", "added", "the delivered design vs the move-only optimum")}


def _tracking(block: AddedTargets) -> str:
    tr: Any = block.tracking
    if not tr:
        return note("closed loop of the three designs: not run (the study's check is off)")
    if tr.get("skipped"):
        return note(f"closed loop of the three designs: skipped ({tr['skipped']})", "warning")
    designs = tr.get("designs", {})
    rows = []
    for label, (a, b, what) in _COMPARED.items():
        for m, verdict in (tr.get("verdicts", {}).get(label) or {}).items():
            x, y = designs.get(a, {}).get(m, {}), designs.get(b, {}).get(m, {})
            rows.append(f"<tr>{text(what)}{text(m)}{num(_mean(x.get('trans_mm_rms')))}"
                        f"{num(_mean(y.get('trans_mm_rms')))}{num(_mean(x.get('rot_deg_rms')))}"
                        f"{num(_mean(y.get('rot_deg_rms')))}{text(verdict)}</tr>")
    return ("<p>Closed loop (the study's check, mode " + esc(tr.get("mode")) + f", {esc(tr.get('runs'))} paired runs: "
            "the original, the move-only optimum and the delivered design tracked with the same noise, initial "
            "errors, placements and light; mean RMS error over the runs; verdicts by the paired Wilcoxon "
            "signed-rank test of the section below). The first comparison is the verdict's tracking rule.</p>"
            + table(["comparison", "estimator", "first: translation (mm)", "second: translation (mm)",
                     "first: rotation (deg)", "second: rotation (deg)", "verdict (second vs first)"], rows,
                    "added-tracking"))


def added_targets_section(results: Results, out_dir: Path, rel: Relative) -> str:
    """The section's HTML ('' when the results have no ``added_targets``)."""
    block = section(results, "added_targets", AddedTargets)
    if block is None or block.curve is None:
        return ""
    drop = block.drop_vs_move_only
    parts = [f"<p>cadfeat proposed new blind target holes on {esc(', '.join(block.faces))} "
             f"({block.candidate_sites} candidate sites keeping every requirement), chose them one at a time by the "
             "predicted pose error (lazy greedy with occlusion), refined their places and drilled them into the "
             f"move-only optimum. <b>Recommended: {block.recommended} added hole(s)</b> — {esc(block.reason)}."
             + (f" The predicted error falls {fmt(100 * float(drop), 3)} % below the move-only optimum."
                if drop is not None and block.recommended else "")
             + (" <b>This is the delivered design</b>: <code>optimised.step</code> / <code>.stl</code>, the hole "
                "table, the measures, objectives, requirements, closed loop and verdict of this report are its; "
                "<code>move_only.step</code> holds the move-only optimum." if block.delivered else "") + "</p>"]
    try:
        path = curve_plot(block, Path(out_dir) / "img" / "added_targets.png")
        parts.append(figure(rel(path), "Predicted RMS pose error against the number of added target holes "
                                       "(diminishing returns); the square marks the recommended number.",
                            "added targets curve"))
    except ImportError as exc:  # matplotlib missing
        parts.append(note(f"no curve: {exc}"))
    parts += [_predicted(block), _holes(block), _checks(block), _tracking(block)]
    if block.step:
        parts.append(f"<p>STEP: {esc(block.step.get('file'))} re-imported, every hole found where it was put "
                     f"(largest error {fmt(block.step.get('max_error_mm'))} mm).</p>")
    move = block.move_only or {}
    step = move.get("step")
    if isinstance(step, dict):
        parts.append(f"<p>The move-only optimum: {esc(step.get('file'))}, re-imported with every hole where it was "
                     f"put (largest error {fmt(step.get('max_error_mm'))} mm).</p>")
    return "".join(parts)
