"""Report section "How well will the robot know the part's pose?" from results.json's ``pose_accuracy``
(``cadfeat.study.pose_accuracy``; issue 17).

The predicted pose error along the trajectory before and after (translation mm, rotation deg: single-frame
prediction with its bias part, and the IEKF's posterior bound), the table of its RMS/worst, each hole's share of
the information, the weakest direction per phase of the path in words, the "what would help most" sentence,
and — when the results have a ``tracking`` section — the closed-loop measurements beside the prediction with
their ratio (PnP against the single-frame prediction, the filters against the posterior bound). Empty when the
results have no ``pose_accuracy``. Reads the typed sections ``results.PoseAccuracy`` and ``results.Tracking``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from cadfeat.report.html import Relative, esc, figure, fmt, note, num, table, text
from cadfeat.results import PoseAccuracy, PoseDesign, Results, Tracking, present, section

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import JsonDict

COLOURS = {"before": "#d95f02", "after": "#1b9e77"}
DESIGNS = ("before", "after")


def _nan(values: list[Any]) -> list[float]:
    return [float("nan") if v is None else float(v) for v in values]


def _design(pose: PoseAccuracy, name: str) -> PoseDesign | None:
    """``pose.before`` / ``pose.after`` by name (DESIGNS)."""
    return pose.before if name == "before" else pose.after


def error_plot(pose: PoseAccuracy, path: Path) -> Path:
    """Predicted translation (mm) and rotation (deg) error against time, before and after: the single-frame
    prediction (solid), its bias part (dotted) and the IEKF posterior bound (dashed)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.0, 3.6), dpi=110)
    axes = fig.subplots(1, 2, squeeze=False)[0]
    t = pose.times_s
    for ax, (kind, unit) in zip(axes, (("translation", "mm"), ("rotation", "deg")), strict=True):
        for name in DESIGNS:
            d = _design(pose, name)
            pp = d.per_pose if d is not None else None
            if not pp:
                continue
            c = COLOURS[name]
            ax.plot(t, _nan(pp[f"error_{kind}_{unit}"]), "-", color=c, lw=1.6, label=f"{name}: predicted")
            ax.plot(t, _nan(pp[f"bias_{kind}_{unit}"]), ":", color=c, lw=1.2, label=f"{name}: bias part")
            ax.plot(t, _nan(pp[f"iekf_{kind}_{unit}"]), "--", color=c, lw=1.2, label=f"{name}: IEKF bound")
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"predicted {kind} error ({unit})")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    return path


def _summary_table(pose: PoseAccuracy) -> str:
    rows: list[str] = []
    for name in DESIGNS:
        d = _design(pose, name)
        if d is None or not present(d):
            continue
        r, w = d.rms, d.worst
        if r is None or w is None:
            raise KeyError(f"pose_accuracy.{name}: no rms/worst")
        rows.append(text(name) + "".join(num(v) for v in (
            r.error_translation_mm, w.error_translation_mm, r.bias_translation_mm, r.noise_translation_mm,
            r.error_rotation_deg, w.error_rotation_deg, r.bias_rotation_deg, r.noise_rotation_deg,
            r.iekf_translation_mm, r.iekf_rotation_deg, d.holes_detected_mean)))
    return table([("", 1), ("single frame, translation (mm)", 4), ("single frame, rotation (deg)", 4),
                  ("IEKF bound", 2), ("", 1)], rows, "pose-accuracy",
                 header2=["design", "RMS", "worst", "bias", "noise", "RMS", "worst", "bias", "noise",
                          "RMS (mm)", "RMS (deg)", "holes detected"])


def _shares(pose: PoseAccuracy, name: str) -> JsonDict:
    d = _design(pose, name)
    return d.share if d is not None else {}


def _share_table(pose: PoseAccuracy) -> str:
    names = list(dict.fromkeys([*_shares(pose, "before"), *_shares(pose, "after")]))
    rows: list[str] = []
    for h in names:
        cells = [_shares(pose, d).get(h) for d in DESIGNS]
        rows.append(text(h) + "".join(num(100.0 * c if c is not None else None, digits=3) for c in cells))
    return table(["hole", "share before (%)", "share after (%)"], rows, "pose-shares")


def _weakest(pose: PoseAccuracy) -> str:
    items: list[str] = []
    for name in DESIGNS:
        d = _design(pose, name)
        phases = d.weakest if d is not None else []
        words = "; ".join(f"{esc(p.phase)}: {esc(p.weakest)} (σ ≈ {fmt(p.sigma_mm, 3)} mm)" for p in phases)
        if words:
            items.append(f"<li>{esc(name)} — {words}</li>")
    return f"<p>Weakest direction per phase of the path:</p><ul>{''.join(items)}</ul>" if items else ""


def _closed_loop(pose: PoseAccuracy, tracking: Tracking | None) -> str:
    """Simulated RMS errors beside the predictions, with the ratio simulated / predicted."""
    if tracking is None or not tracking.designs:
        return ""
    rows: list[str] = []
    for name, d in tracking.designs.items():
        design = _design(pose, name) if name in DESIGNS else None
        pred = design.rms if design is not None else None
        if pred is None or not present(pred):
            continue
        for m, e in d.estimators.items():
            ref = "error" if m == "pnp" else "iekf"
            for kind, stat, unit in (("translation", e.trans_mm_rms, "mm"), ("rotation", e.rot_deg_rms, "deg")):
                sim = stat.mean if stat is not None else None
                p = getattr(pred, f"{ref}_{kind}_{unit}")
                ratio = sim / p if sim is not None and p else None
                rows.append(text(name) + text(m.upper()) + text(f"{kind} ({unit})") + num(p) + num(sim)
                            + num(ratio, digits=3))
    if not rows:
        return ""
    return ("<p>Closed loop (the study's tracking run) beside the prediction: PnP against the single-frame "
            "prediction, EKF/IEKF against the posterior bound.</p>"
            + table(["design", "estimator", "error", "predicted RMS", "simulated RMS", "simulated / predicted"],
                    rows, "pose-closed-loop"))


def pose_section(results: Results, out_dir: Path, rel: Relative) -> str:
    """The section's HTML ('' when the results have no ``pose_accuracy``)."""
    pose = section(results, "pose_accuracy", PoseAccuracy)
    if pose is None or not present(pose):
        return ""
    parts = ["<p>Predicted error of the robot's estimate of the part pose along the trajectory, from the Fisher "
             "information of the holes' rim-ellipse centres (calibrated detection and measurement models; a hole "
             "whose rim the part hides adds nothing). The single-frame prediction (PnP) combines the detector's "
             "systematic offsets (bias) with the noise bound; the IEKF bound is the filter's posterior Cramér–Rao "
             "bound with the study's tracking tuning.</p>", _summary_table(pose)]
    try:
        path = error_plot(pose, Path(out_dir) / "img" / "pose_accuracy.png")
        parts.append(figure(rel(path), "Predicted pose error along the trajectory, before and after: single frame "
                                       "(solid), its bias part (dotted), IEKF posterior bound (dashed).",
                            "predicted pose error"))
    except ImportError as exc:  # matplotlib missing
        parts.append(note(f"no pose-error plot: {exc}"))
    parts.append("<p>Share of the pose information per hole (mean over the trajectory):</p>" + _share_table(pose))
    parts.append(_weakest(pose))
    which = "after" if present(pose.after) else "before"
    design = _design(pose, which)
    best = design.help_most.best if design is not None and design.help_most is not None else None
    if best is not None and present(best):
        label = "delivered design" if which == "after" else "this design"
        parts.append(f'<p class="help-most">What would help most ({label}): {esc(best.sentence)}</p>')
    parts.append(_closed_loop(pose, section(results, "tracking", Tracking)))
    return "".join(parts)
