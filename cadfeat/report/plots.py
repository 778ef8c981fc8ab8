"""Matplotlib plots of a study's results (PNG, Agg, deterministic file names in ``img/``).

Each ``plot_*`` function reads only the results (results.json's typed sections, ``cadfeat.results``; the
per-pose series ``measures.*.per_pose``, ``history``, ``sweep`` and ``pareto`` are still plain JSON), writes
one PNG and returns a ``Plot``, or returns None when its data is absent (a study without a sweep has no
sweep plot). ``make_plots`` runs them all; a plot that fails on malformed data is skipped with a logged
warning, it never stops the report.
"""

from __future__ import annotations

import json
import logging
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cadfeat.results import (
    HistoryPoint,
    Measures,
    MeasureSummary,
    Objectives,
    Pareto,
    Results,
    StudyResults,
    Sweep,
    Variable,
    present,
    section,
    value,
)

log = logging.getLogger(__name__)

#: Colours of the two designs in every plot.
BEFORE, AFTER = "#7f7f7f", "#d62728"
DPI = 110


@dataclass(frozen=True)
class Plot:
    """A written plot: ``key`` (also the file stem), a title and caption for the report, the PNG path."""

    key: str
    title: str
    caption: str
    path: Path


def _figure(ncols: int = 1, nrows: int = 1, size: tuple[float, float] = (7.0, 4.2)) -> tuple[Any, Any]:
    """A pyplot-free Figure (no global state) with its axes.

    Fixed margins in inches instead of constrained/tight layout: the layout engines cost about half of
    the plotting time (they draw every figure twice)."""
    from matplotlib.figure import Figure

    width, height = size
    fig = Figure(figsize=size, dpi=DPI)
    axes = fig.subplots(nrows, ncols, squeeze=False, sharex=ncols == 1 and nrows > 1)
    fig.subplots_adjust(left=0.85 / width, right=1 - 0.25 / width, bottom=0.6 / height, top=1 - 0.4 / height,
                        wspace=0.75 / (width / ncols), hspace=0.35 / (height / nrows) if nrows > 1 else 0.2)
    return fig, axes


def _save(fig: Any, img_dir: Path, key: str) -> Path:
    path = Path(img_dir) / f"{key}.png"
    fig.savefig(path, format="png", metadata={"Software": None})  # no version stamp: identical bytes per run
    return path


def _measures(results: Results, which: str) -> MeasureSummary | None:
    m = section(results, "measures", Measures)
    return None if m is None else m.before if which == "before" else m.after


def _per_pose(results: Results, which: str, key: str) -> np.ndarray | None:
    m = _measures(results, which)
    per_pose = m.per_pose if m is not None else None
    values = per_pose.get(key) if isinstance(per_pose, dict) else None
    if values is None:
        return None
    a = np.asarray(values, dtype=float)
    return a if a.size else None


def _times(results: Results, which: str, n: int) -> np.ndarray:
    t = _per_pose(results, which, "time_s")
    return t if t is not None and t.shape == (n,) else np.arange(n, dtype=float)


def _design_label(results: Results, which: str) -> str:
    """ "current" for an evaluation-only result (one design), else before/after."""
    return "current" if which == "before" and not present(_measures(results, "after")) else which


def _feature_names(results: Results, which: str, n: int) -> list[str]:
    m = _measures(results, which)
    names = [str(f.name or f"H{f.index + 1}") for f in (m.per_feature if m is not None else [])]
    return names if len(names) == n else [f"H{i + 1}" for i in range(n)]


# ------------------------------------------------------------------------------------------------ the plots
def plot_feature_tracks(results: Results, img_dir: Path) -> Plot | None:
    """Image-plane tracks of the hole centres along the trajectory, before | after, with the image border
    (thesis Fig. 5.7). From ``measures.{before,after}.per_pose.centre_px`` (L, N, 2) and ``camera``."""
    tracks = {w: _per_pose(results, w, "centre_px") for w in ("before", "after")}
    tracks = {w: a for w, a in tracks.items() if a is not None and a.ndim == 3 and a.shape[-1] == 2}
    if not tracks:
        return None
    cam = value(results, "camera") or {}
    width, height = cam.get("width"), cam.get("height")
    fig, axes = _figure(len(tracks), 1, (5.2 * len(tracks), 4.6))
    cmap = _colours(max(a.shape[1] for a in tracks.values()))
    for ax, (which, a) in zip(axes[0], tracks.items(), strict=True):
        if width and height:
            ax.add_patch(_rectangle(width, height))
        if which == "after" and "before" in tracks and tracks["before"].shape == a.shape:
            for j in range(a.shape[1]):  # the original tracks, faint, for comparison
                ax.plot(tracks["before"][:, j, 0], tracks["before"][:, j, 1], ":", color=cmap[j], lw=1.0, alpha=0.6)
        for j, name in enumerate(_feature_names(results, which, a.shape[1])):
            ax.plot(a[:, j, 0], a[:, j, 1], "-", color=cmap[j], lw=1.4, label=name)
            ax.plot(a[0, j, 0], a[0, j, 1], "o", color=cmap[j], ms=4)
            ax.plot(a[-1, j, 0], a[-1, j, 1], "s", color=cmap[j], ms=4)
        if width and height:  # the image plus a border: far-off projections (behind the camera) stay off-plot
            pad = 0.15 * max(width, height)
            ax.set_xlim(-pad, width + pad)
            ax.set_ylim(height + pad, -pad)
        else:
            ax.invert_yaxis()
        ax.set_aspect("equal")
        ax.set_title(f"{_design_label(results, which)}: hole centres in the image")
        ax.set_xlabel("u (px)")
        ax.set_ylabel("v (px)")
    axes[0][-1].legend(fontsize=7, loc="best")
    return Plot("tracks", "Feature tracks in the image",
                "Projected hole centres along the trajectory (circle = first sample, square = last; dotted "
                "in the after panel: before); the box is the image border (cf. thesis Fig. 5.7).",
                _save(fig, img_dir, "tracks"))


def plot_pose_measures(results: Results, img_dir: Path) -> Plot | None:
    """Worst-feature FOV, focus and resolution margins per pose (and the number of visible holes when the
    results have it), before vs after."""
    rows = [("fov_min", "FOV cone margin"), ("focus_min", "focus margin"), ("resolution_px_min", "resolution (px)"),
            ("visible", "visible holes")]
    present = [(k, label) for k, label in rows
               if any(_per_pose(results, w, k) is not None for w in ("before", "after"))]
    if not present:
        return None
    fig, axes = _figure(1, len(present), (7.0, 2.2 * len(present) + 0.6))
    for ax, (key, label) in zip(axes[:, 0], present, strict=True):
        _before_after(ax, results, key)
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set_ylabel(label)
    axes[-1, 0].set_xlabel("time (s)")
    axes[0, 0].legend(fontsize=8)
    return Plot("pose_measures", "Measures along the trajectory",
                "Worst margin over the holes at each pose (positive = satisfied), before vs after.",
                _save(fig, img_dir, "pose_measures"))


def plot_motion(results: Results, img_dir: Path) -> Plot | None:
    """Directional motion resolvability Λ (eq. 4.32) and σ_min of the stacked Jacobian per pose."""
    present = [(k, label) for k, label in (("resolvability", "Λ (px per unit motion)"), ("sigma_min", "σ_min (px)"))
               if any(_per_pose(results, w, k) is not None for w in ("before", "after"))]
    if not present:
        return None
    fig, axes = _figure(1, len(present), (7.0, 2.4 * len(present) + 0.6))
    for ax, (key, label) in zip(axes[:, 0], present, strict=True):
        _before_after(ax, results, key)
        ax.set_ylabel(label)
    axes[-1, 0].set_xlabel("time (s)")
    axes[0, 0].legend(fontsize=8)
    return Plot("motion", "Motion resolvability along the trajectory",
                "Λ (eq. 4.27-4.32) and the smallest singular value of the stacked image Jacobian "
                "(eq. 4.20), before vs after.", _save(fig, img_dir, "motion"))


def plot_convergence(results: Results, img_dir: Path) -> Plot | None:
    """Combined objective per optimiser iteration, larger is better like everything else in the report
    (``combined`` of the history, else −f of the minimiser); feasible points filled, infeasible hollow; the
    original design's value as a dashed line."""
    points = [h if isinstance(h, HistoryPoint) else HistoryPoint.model_validate(h)
              for h in value(results, "history") or []]
    history = [h for h in points if h.combined is not None or h.f is not None]
    if len(history) < 1:
        return None
    it = np.array([h.iteration if "iteration" in h.model_fields_set else i for i, h in enumerate(history)],
                  dtype=float)
    f = np.array([h.combined if h.combined is not None else -(h.f or 0.0) for h in history], dtype=float)
    feasible = np.array([bool(h.feasible) for h in history])
    fig, axes = _figure(1, 1, (7.0, 3.6))
    ax = axes[0, 0]
    ax.plot(it, f, "-", color="#1f77b4", lw=1.0, alpha=0.6)
    ax.plot(it[feasible], f[feasible], "o", color="#1f77b4", ms=3.5, label="feasible")
    if (~feasible).any():
        ax.plot(it[~feasible], f[~feasible], "o", mfc="none", color="#1f77b4", ms=3.5, label="infeasible")
    best = np.maximum.accumulate(np.where(feasible, f, -np.inf))
    if np.isfinite(best).any():
        ax.step(it, best, where="post", color=AFTER, lw=1.5, label="best feasible so far")
    objectives = section(results, "objectives", Objectives)
    before = objectives.combined_before if objectives is not None else None
    if isinstance(before, int | float) and not isinstance(before, bool):
        ax.axhline(before, color=BEFORE, ls="--", lw=1.2, label="original design")
    ax.set_xlabel("iteration")
    ax.set_ylabel("combined objective (larger is better)")
    ax.legend(fontsize=8)
    return Plot("convergence", "Convergence", "Combined objective per evaluation of the optimiser (larger is "
                "better) and the best feasible value so far; dashed: the original design.",
                _save(fig, img_dir, "convergence"))


def plot_sweep(results: Results, img_dir: Path) -> Plot | None:
    """Objectives vs the one design variable of a one-variable study (thesis Figs. 5.10, 5.11)."""
    sweep = section(results, "sweep", Sweep)
    if sweep is None or not sweep.values or not sweep.objectives:
        return None
    x = np.asarray(sweep.values, dtype=float)
    curves = {str(k): np.asarray(v, dtype=float) for k, v in sweep.objectives.items() if len(v) == len(x)}
    if not curves:
        return None
    name = str(sweep.variable)
    variables = [v if isinstance(v, Variable) else Variable.model_validate(v)
                 for v in value(results, "variables") or []]
    var = next((v for v in variables if v.name == name), None)
    fig, axes = _figure(1, len(curves), (7.0, 2.0 * len(curves) + 0.8))
    for ax, (obj, y) in zip(axes[:, 0], curves.items(), strict=True):
        ax.plot(x, y, "-", color="#1f77b4", lw=1.5)
        for key, colour, at in (("before", BEFORE, var.before if var else None),
                                ("after", AFTER, var.after if var else None)):
            if at is not None:
                ax.axvline(at, color=colour, ls="--", lw=1.2, label=key)
        ax.set_ylabel(obj)
    unit = f" ({var.unit})" if var is not None and var.unit else ""
    axes[-1, 0].set_xlabel(f"{name}{unit}")
    if var is not None and present(var):
        axes[0, 0].legend(fontsize=8)
    return Plot("sweep", f"Objectives vs {name}", "Each objective over the range of the design variable "
                "(cf. thesis Figs. 5.10, 5.11); dashed lines: the original and the chosen value.",
                _save(fig, img_dir, "sweep"))


def plot_pareto(results: Results, img_dir: Path) -> Plot | None:
    """The Pareto front (first two objectives on the axes, a third as colour) with the chosen point."""
    pareto = section(results, "pareto", Pareto)
    if pareto is None or not pareto.points:
        return None
    pts = np.asarray(pareto.points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] < 2:
        return None
    names = [str(n) for n in pareto.names] or [f"f{i}" for i in range(pts.shape[1])]
    fig, axes = _figure(1, 1, (6.0, 4.6))
    ax = axes[0, 0]
    if pts.shape[1] > 2:
        sc = ax.scatter(pts[:, 0], pts[:, 1], c=pts[:, 2], s=18, cmap="viridis")
        fig.colorbar(sc, ax=ax, label=names[2])
    else:
        ax.scatter(pts[:, 0], pts[:, 1], color="#1f77b4", s=18)
    chosen = pareto.chosen
    if isinstance(chosen, int) and 0 <= chosen < len(pts):
        ax.plot(pts[chosen, 0], pts[chosen, 1], "*", color=AFTER, ms=16, mec="k", label="chosen")
        ax.legend(fontsize=8)
    ax.set_xlabel(names[0])
    ax.set_ylabel(names[1])
    return Plot("pareto", "Pareto front", f"Non-dominated designs ({len(pts)} points); the star is the "
                "chosen design.", _save(fig, img_dir, "pareto"))


PLOTTERS: tuple[Callable[[Results, Path], Plot | None], ...] = (
    plot_feature_tracks, plot_pose_measures, plot_motion, plot_convergence, plot_sweep, plot_pareto)


def make_plots(results: Results, img_dir: str | Path) -> tuple[list[Plot], list[str]]:
    """Write every plot whose data is present; returns the plots and notes about plots that failed."""
    if not isinstance(results, StudyResults):
        try:  # the per-pose series checked once, not by every plot
            results = {**results, "measures": section(results, "measures", Measures)}
        except ValueError:
            pass  # each plot that reads them says so
    img_dir = Path(img_dir)
    img_dir.mkdir(parents=True, exist_ok=True)
    plots, notes = [], []
    for plotter in PLOTTERS:
        try:
            plot = plotter(results, img_dir)
        except Exception as exc:  # a malformed field must not stop the report
            log.warning("report: %s skipped: %s", plotter.__name__, exc)
            notes.append(f"{plotter.__name__} skipped: {exc}")
            continue
        if plot is not None:
            plots.append(plot)
    return plots, notes


# ------------------------------------------------------------------------------------------------ helpers
def _before_after(ax: Any, results: Results, key: str) -> None:
    for which, colour, style in (("before", BEFORE, "--"), ("after", AFTER, "-")):
        y = _per_pose(results, which, key)
        if y is not None and y.ndim == 1:
            ax.plot(_times(results, which, len(y)), y, style, color=colour, lw=1.5,
                    label=_design_label(results, which))


def _rectangle(width: float, height: float) -> Any:
    from matplotlib.patches import Rectangle

    return Rectangle((0, 0), width, height, fill=False, ec="k", lw=1.2)


def _colours(n: int) -> Sequence[Any]:
    from matplotlib import colormaps

    cmap = colormaps["tab10" if n <= 10 else "tab20"]
    return [cmap(i % cmap.N) for i in range(max(n, 1))]


# ------------------------------------------------------------------------------------------------ child process
def main(argv: Sequence[str] | None = None) -> int:
    """``python -m cadfeat.report.plots RESULTS_JSON IMG_DIR``: write the plots, print them as one JSON line.

    Used by ``build_report`` to draw the plots in a separate process while the renders run."""
    args = list(sys.argv[1:] if argv is None else argv)
    start = time.perf_counter()
    results = json.loads(Path(args[0]).read_text(encoding="utf-8"))
    plots, notes = make_plots(results, args[1])
    print(json.dumps({"plots": [dict(key=p.key, title=p.title, caption=p.caption, path=str(p.path)) for p in plots],
                      "notes": notes, "time_s": time.perf_counter() - start}))
    return 0


if __name__ == "__main__":  # pragma: no cover - run as a child process by cadfeat.report.write
    raise SystemExit(main())
