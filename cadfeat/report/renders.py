"""The report's renders: part before/after and camera views, made by ``cadfeat.render`` (PyVista, off-screen).

Rendering needs an OpenGL context (EGL/OSMesa); where there is none, or the render module is missing, or
the context lacks the shapes, the report is still written, with a note in place of the images and a
logged warning. Nothing here may stop a study.
"""

from __future__ import annotations

import logging
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cadfeat.camera import build_camera
from cadfeat.report.context import ReportContext, worst_poses
from cadfeat.results import Results, value

log = logging.getLogger(__name__)


@dataclass
class Renders:
    """Images rendered for the report (absolute paths inside ``img/``) and notes about what is missing."""

    comparison: dict[str, Path] = field(default_factory=dict)  # "before"/"after"(/"*_closeup") or "current"
    views: dict[str, list[Path]] = field(default_factory=dict)  # "before"/"after" -> one per sample
    samples: list[int] = field(default_factory=list)
    sample_times_s: list[float] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    timings_s: dict[str, float] = field(default_factory=dict)  # "part", "views"
    worst: dict[int, list[str]] = field(default_factory=dict)  # sample -> holes whose worst pose it is


def _camera(context: ReportContext, results: Results):
    if context.camera is not None:
        return context.camera
    camera = value(results, "camera")
    if camera:
        return build_camera({k: v for k, v in camera.items() if k != "source"})
    return None


def _inside(paths, img_dir: Path) -> list[Path]:
    """Paths moved into ``img_dir`` if the renderer wrote them elsewhere (links stay relative)."""
    out = []
    for p in paths:
        p = Path(p)
        if p.resolve().parent != img_dir.resolve():
            target = img_dir / p.name
            shutil.copyfile(p, target)
            p = target
        out.append(p)
    return out


def _fail(renders: Renders, what: str, exc: BaseException) -> None:
    message = f"{what} not rendered: {type(exc).__name__}: {exc}"
    log.warning("report: %s", message)
    renders.notes.append(message)


def make_renders(context: ReportContext | None, results: Results, img_dir: str | Path) -> Renders:
    """Render the before/after comparison and the camera views at ``context.samples()`` into ``img_dir``.

    With only ``shape_before`` (an evaluation, nothing optimised) the part and its views are rendered once,
    under the key "current".
    """
    img_dir = Path(img_dir)
    img_dir.mkdir(parents=True, exist_ok=True)
    renders = Renders()
    if context is None or context.shape_before is None:
        renders.notes.append("Renders skipped: the report was written without the part shapes "
                             "(no report context), e.g. from results.json alone.")
        return renders
    try:
        from cadfeat import render
    except Exception as exc:  # module missing or PyVista/VTK failing to import
        _fail(renders, "renders", exc)
        return renders
    try:
        camera = _camera(context, results)
    except Exception as exc:
        _fail(renders, "camera for the renders", exc)
        camera = None
    holes_b, holes_a = list(context.holes_before or []), list(context.holes_after or [])
    start = time.perf_counter()
    if context.shape_after is None:
        designs = [("current", context.shape_before, holes_b)]
        _render_part(renders, render, context, img_dir)
    else:
        designs = [("before", context.shape_before, holes_b), ("after", context.shape_after, holes_a)]
        _render_comparison(renders, render, context, camera, img_dir)
    renders.timings_s["part"] = time.perf_counter() - start
    worst = worst_poses(results)
    renders.worst = worst
    samples = context.samples(sorted(worst))
    if camera is None or not samples:
        renders.notes.append("Camera views skipped: no camera or trajectory in the report context.")
        return renders
    renders.samples = samples
    renders.sample_times_s = [float(context.trajectory.times_s[i]) for i in samples]
    T_cam_part = context.T_cam_part(samples)
    start = time.perf_counter()
    for which, shape, holes in designs:
        try:
            paths = render.render_camera_views(shape, holes, camera, T_cam_part, img_dir, f"view_{which}")
            renders.views[which] = _inside(paths, img_dir)
        except Exception as exc:
            _fail(renders, f"camera views ({which})", exc)
    renders.timings_s["views"] = time.perf_counter() - start
    return renders


def _render_comparison(renders: Renders, render, context: ReportContext, camera, img_dir: Path) -> None:
    holes_b, holes_a = list(context.holes_before or []), list(context.holes_after or [])
    fixed = list(context.fixed_mask) if context.fixed_mask is not None else [False] * len(holes_b)
    try:
        out = render.render_comparison(context.shape_before, context.shape_after, holes_b, holes_a, fixed,
                                       img_dir, trajectory=context.trajectory, camera=camera,
                                       T_task_part=context.T_task_part, closeup=True)
        renders.comparison = {k: p for k, p in zip(out, _inside(out.values(), img_dir), strict=True)}
    except Exception as exc:
        _fail(renders, "before/after part renders", exc)
        return
    try:
        crop_to_content([p for k, p in renders.comparison.items() if k in ("before", "after")])
    except Exception as exc:  # a crop is cosmetic: keep the full pictures
        log.warning("report: overview not cropped: %s", exc)


def crop_to_content(paths: list[Path], pad_frac: float = 0.03) -> tuple[int, int, int, int] | None:
    """Crop PNGs rendered from one viewpoint to the union of their non-background pixels (background = the
    corner colour) plus ``pad_frac`` of the size, in place and with one box for all (they stay comparable):
    the overview of part and trajectory then fills the picture. Returns the box (left, top, right, bottom)."""
    from PIL import Image

    if not paths:
        return None
    images = [np.asarray(Image.open(p).convert("RGB")) for p in paths]
    if len({im.shape for im in images}) != 1:
        return None
    mask = np.zeros(images[0].shape[:2], bool)
    for im in images:
        mask |= np.any(np.abs(im.astype(int) - im[0, 0].astype(int)) > 8, axis=-1)
    if not mask.any():
        return None
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    h, w = mask.shape
    pad = int(pad_frac * max(h, w))
    box = (max(int(cols[0]) - pad, 0), max(int(rows[0]) - pad, 0), min(int(cols[-1]) + 1 + pad, w),
           min(int(rows[-1]) + 1 + pad, h))
    for p, im in zip(paths, images, strict=True):
        Image.fromarray(im[box[1]:box[3], box[0]:box[2]]).save(p)
    return box


def _render_part(renders: Renders, render, context: ReportContext, img_dir: Path) -> None:
    holes = list(context.holes_before) if context.holes_before is not None else None
    try:
        renders.comparison = {"current": Path(render.render_part(context.shape_before, img_dir / "part.png", holes))}
    except Exception as exc:
        _fail(renders, "part render", exc)
