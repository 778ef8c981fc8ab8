"""Report section "Does the new design track better?" from results.json's ``tracking`` (``cadfeat.vision``).

Error against time before and after per estimator (median over the Monte-Carlo runs with a 10–90 % band,
thesis Fig. 6.7 style), a few camera frames with the detected ellipses over the predicted ones, the table of
errors with bootstrap intervals, and one verdict line per estimator with the paired test used. Also the plot of
a ``cadfeat track --sweep`` (thesis Figs. 6.3–6.11). Empty when the results have no tracking section. Reads the
typed section ``results.Tracking``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, cast

from cadfeat.report.html import Relative, esc, figure, fmt, note, table
from cadfeat.results import Interval, PhysicalViews, Results, Tracking, TrackingComparison, present, section

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np
    from matplotlib.figure import Figure

    from cadfeat.results import SweepData

COLOURS = {"before": "#d95f02", "after": "#1b9e77", "move_only": "#7570b3"}
VERDICT_TEXT = {"better": "tracks better after the redesign", "worse": "tracks WORSE after the redesign",
                "no significant difference": "shows no significant difference",
                "mixed": "is significantly better in one of translation / rotation and worse in the other"}


def _table(value: object) -> Mapping[str, object]:
    """A JSON object of the section (an empty one for anything else)."""
    return cast("Mapping[str, object]", value) if isinstance(value, Mapping) else {}


def _series(value: object) -> list[float]:
    """A JSON list of numbers as floats (None, a number JSON could not hold, as NaN)."""
    items = cast("list[object]", value) if isinstance(value, list) else []
    return [float(v) if isinstance(v, int | float) else math.nan for v in items]


def _figure(ncols: int, nrows: int, size: tuple[float, float]) -> tuple[Figure, np.ndarray]:
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=110)
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes


def error_plot(tracking: Tracking, path: Path) -> Path:
    """Translation (mm) and rotation (deg) error against time, one column per estimator, both designs."""
    curves = tracking.curves
    if tracking.settings is None:
        raise KeyError("tracking.settings")
    estimators = list(tracking.settings.estimators)
    fig, axes = _figure(len(estimators), 2, (3.6 * len(estimators), 5.4))
    for col, m in enumerate(estimators):
        rows = (("trans_mm", "translation error (mm)"), ("rot_deg", "rotation error (deg)"))
        for row, (key, unit) in enumerate(rows):
            ax = axes[row][col]
            for name, curve in curves.items():
                c = _table(curve)
                if m not in c:
                    continue
                t, e = _series(c["times_s"]), _table(_table(c[m])[key])
                med, lo, hi = _series(e["median"]), _series(e["p10"]), _series(e["p90"])
                ax.plot(t, med, color=COLOURS.get(name, "k"), label=name, lw=1.5)
                ax.fill_between(t, lo, hi, color=COLOURS.get(name, "k"), alpha=0.2, lw=0)
            ax.set_yscale("log")
            ax.grid(True, which="both", alpha=0.3)
            if row == 0:
                ax.set_title(m.upper())
            if col == 0:
                ax.set_ylabel(unit)
            if row == 1:
                ax.set_xlabel("time (s)")
    axes[0][0].legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    return path


def sweep_plot(result: SweepData, path: Path) -> Path:
    """RMS translation error against the swept value, per design and estimator (``cadfeat track --sweep``)."""
    rows = result["rows"]
    x = [r["value"] for r in rows]
    fig, axes = _figure(2, 1, (9.0, 3.6))
    styles = {"ekf": "-o", "iekf": "-s", "pnp": "--^"}
    for col, key in enumerate(("trans_mm_rms", "rot_deg_rms")):
        ax = axes[0][col]
        for name in ("before", "after"):
            methods = _table(rows[0].get(name)) if rows else {}
            for m in methods:
                y = [_series([_table(_table(r[name])[m])[key]])[0] for r in rows]
                ax.plot(x, y, styles.get(m, "-"), color=COLOURS[name], label=f"{name} {m}", ms=4)
        ax.set_xlabel(result["kind"].replace("_", " "))
        ax.set_ylabel("RMS translation error (mm)" if col == 0 else "RMS rotation error (deg)")
        ax.set_yscale("log")
        if result["kind"] in ("q", "r", "initial_error"):
            ax.set_xscale("log")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    return path


def _stat(entry: Interval | None, name: str) -> Interval:
    """A statistic the table needs (KeyError naming it when absent: the section becomes a note)."""
    if entry is None:
        raise KeyError(name)
    return entry


def _interval(entry: Interval | None, name: str) -> str:
    e = _stat(entry, name)
    return f"{fmt(e.mean, 3)} [{fmt(e.ci_low, 3)}, {fmt(e.ci_high, 3)}]"


def report_note(tracking: Tracking) -> str:
    """One sentence for the section: which check of cadfeat run produced it and what it cost (results.json
    ``tracking.check``, ``study.closed_loop_check``; '' for ``cadfeat track``'s)."""
    check = tracking.check
    if check is None or not present(check):
        return ""
    if check.mode == "fast":
        return (f"This is cadfeat run's fast closed-loop check ({', '.join(m.upper() for m in check.estimators)}; "
                f"{check.runs} runs on {check.frames} frames; {check.seconds} s); `cadfeat track` runs the "
                "full check. Its verdict is decisive: an estimator significantly worse after the redesign means "
                "'do not adopt'.")
    return f"This is cadfeat run's full closed-loop check ({check.runs} runs, {check.seconds} s)."


#: The comparisons of a study with added target holes (``closed_loop_check.ADDED_PAIRS``), as the report says them.
COMPARISONS = {"move_only_vs_original": "The move-only optimum against the original",
               "added_vs_move_only": "The delivered design (with the added holes) against the move-only optimum"}


def _comparison(label: str, c: TrackingComparison) -> str:
    """One more paired comparison (``tracking.comparisons``): a line per estimator with its tests."""
    items = []
    for m, v in c.verdicts.items():
        t, r = v.translation, v.rotation
        tests = "" if t is None or r is None else (f" (median change of RMS translation error "
                                                   f"{fmt(t.median_change, 3)} mm, p = {fmt(t.p_value, 2)}; rotation "
                                                   f"p = {fmt(r.p_value, 2)})")
        items.append(f"<li><b>{esc(m.upper())}</b>: {esc(v.verdict)}{tests}</li>")
    head = COMPARISONS.get(label, f"{c.after} against {c.before}")
    return f"<p>{esc(head)}, same runs:</p><ul>{''.join(items)}</ul>" if items else ""


def tracking_section(results: Results, out_dir: Path, rel: Callable[[Path], str]) -> str:
    """The section's HTML ('' when there is no tracking section)."""
    tracking = section(results, "tracking", Tracking)
    if tracking is None or not present(tracking):
        return ""
    s = tracking.settings
    if s is None:
        raise KeyError("settings")
    parts = [f"<p>The part's pose is estimated from synthetic camera images along the trajectory "
             f"({s.frames} frames, grey-level noise σ = {fmt(s.noise_grey, 3)}, thin-lens defocus "
             f"{'on' if s.defocus else 'off'}, exposure {fmt(s.exposure_s, 3)} s): holes detected with OpenCV "
             f"(ellipse fits), associated to the model by prediction, and tracked by the EKF, IEKF (thesis §6.3) and "
             f"solvePnP from an initial error of {fmt(s.initial_error_mm, 3)} mm / "
             f"{fmt(s.initial_error_deg, 3)}°, over {s.runs} Monte-Carlo runs paired between the designs "
             f"(same noise seeds, initial errors, part placements and illumination; per run the part is placed "
             f"with σ {fmt(s.placement_mm, 3)} mm / {fmt(s.placement_deg, 3)}° per axis and "
             f"lit with a gain of σ {fmt(100 * s.gain_sigma, 2)} %). Errors are counted after the first "
             f"{s.settle_frames} "
             "frames; intervals are 95 % bootstrap intervals of the mean over runs.</p>"]
    parts += [note(w, "warning") for w in tracking.warnings]
    parts += [f"<p>{esc(t)}</p>" for t in [report_note(tracking)] if t]  # cadfeat run's check (issue 17)
    lines: list[str] = []
    for m, v in tracking.verdicts.items():
        t, r = v.translation, v.rotation
        if t is None or r is None:
            raise KeyError("translation" if t is None else "rotation")
        lines.append(f"<li><b>{esc(m.upper())}</b>: the new design {esc(VERDICT_TEXT.get(v.verdict, v.verdict))}"
                     f" (median change of RMS translation error {fmt(t.median_change, 3)} mm, p = "
                     f"{fmt(t.p_value, 2)}; rotation p = {fmt(r.p_value, 2)}; {esc(t.test)}, "
                     f"α = {fmt(t.alpha, 2)}; changes under {fmt(100 * t.min_change, 2)} % of the error "
                     "do not count).</li>")
    if lines:
        if tracking.comparisons:
            parts.append("<p>The design after is the delivered one: the move-only optimum with the added target "
                         "holes (<code>[add_targets]</code>); the move-only optimum (<i>move_only</i>) is tracked in "
                         "the same paired runs.</p>")
        parts.append(f'<ul class="verdict">{"".join(lines)}</ul>')
    parts += [_comparison(label, c) for label, c in tracking.comparisons.items()]
    rows: list[str] = []
    for name, d in tracking.designs.items():
        for m, e in d.estimators.items():
            conv, lost = _stat(e.convergence_s, "convergence_s"), e.lost_frac
            rows.append("<tr>" + "".join(f"<td>{x}</td>" for x in (
                esc(name), esc(m.upper()), _interval(e.trans_mm_rms, "trans_mm_rms"),
                fmt(_stat(e.trans_mm_p95, "trans_mm_p95").mean, 3), fmt(_stat(e.trans_mm_max, "trans_mm_max").mean, 3),
                _interval(e.rot_deg_rms, "rot_deg_rms"), fmt(_stat(e.rot_deg_p95, "rot_deg_p95").mean, 3),
                fmt(_stat(e.frames_lost, "frames_lost").mean, 3)
                + (f" ({fmt(100 * lost.mean, 2)} %)" if lost is not None and lost.mean else ""),
                fmt(conv.mean, 3) + (f" ({conv.runs_not_finite} never)" if conv.runs_not_finite else "")))
                + "</tr>")
    parts.append(table(["design", "estimator", "RMS translation (mm)", "p95 (mm)", "max (mm)", "RMS rotation (deg)",
                        "p95 (deg)", "lost frames", "convergence (s)"], rows, "tracking-errors"))
    rates: list[str] = []
    for name, d in tracking.designs.items():
        text = ", ".join(f"{esc(h)} {'—' if r is None else f'{100 * r:.0f} %'}" for h, r in d.detection_rate.items())
        rates.append(f"<li>{esc(name)}: {text}</li>")
    parts.append(f"<p>Detection rate per hole (detected / frames where the hole is in view and facing the camera):"
                 f"</p><ul>{''.join(rates)}</ul>")
    if tracking.curves:
        try:
            path = error_plot(tracking, Path(out_dir) / "img" / "tracking_errors.png")
            parts.append(figure(rel(path), "Pose error against time, median over the Monte-Carlo runs with the "
                                           "10–90 % band (thesis Fig. 6.7 style); log scale.", "tracking errors"))
        except ImportError as exc:  # matplotlib missing
            parts.append(note(f"no error plot: {exc}"))
    frames = [f for f in tracking.frames if (Path(out_dir) / f.path).is_file()]
    if frames:
        figs = "".join(figure(rel(Path(out_dir) / f.path), f"{f.design}, frame {f.frame} (t = {fmt(f.time_s, 3)} s): "
                                      f"{f.detected} of {f.holes} holes detected", f"{f.design} frame")
                       for f in frames)
        parts.append("<h3>Camera frames: detected ellipses (green) over the predicted rims (red), associated "
                     f"centres (yellow)</h3><div class=\"pair\">{figs}</div>")
    elif tracking.frames:
        parts.append(note("The tracking frames are in the study's output folder (tracking/), not beside this "
                          "report."))
    return "".join(parts)


def physical_views_section(results: Results, out_dir: Path, rel: Relative) -> str:
    """"What the robot's camera will see": results.json ``physical_views`` (both designs rendered physically at
    three poses, the cell's detector's detections drawn, the misses named); '' when absent."""
    views = section(results, "physical_views", PhysicalViews)
    if views is None or not views.frames:
        return ""
    parts = [f"<p>Both designs rendered physically (Mitsuba 3 path tracer, {esc(views.spp)} samples per pixel) in "
             f"the study's cell: {esc(views.light)} light, {esc(views.material)}, blind holes "
             f"{esc(views.hole_ends)}, sensor noise σ = {fmt(views.noise_grey, 3)} grey levels; holes found by the "
             f"{esc(views.detector)} detector. Predicted rims red, detections green, associated centres yellow; a "
             "hole the closed loop expects but the detector missed is named in red.</p>"]
    figs = []
    for f in views.frames:
        missed = f"; missed: {', '.join(f.missed)}" if f.missed else "; none missed"
        caption = (f"{f.design}, sample {f.frame} (t = {fmt(f.time_s, 3)} s): {len(f.detected)} of "
                   f"{len(f.expected)} expected holes found{missed}")
        if f.path and (Path(out_dir) / f.path).is_file():
            figs.append(figure(rel(Path(out_dir) / f.path), caption, f"{f.design} physical frame"))
        else:
            parts.append(f"<p>{esc(caption)}</p>")
    if figs:
        parts.append(f"<div class=\"pair\">{''.join(figs)}</div>")
    return "".join(parts)
