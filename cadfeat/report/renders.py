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

from cadfeat.report.context import ReportContext

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


def _camera(context: ReportContext, results: dict):
    if context.camera is not None:
        return context.camera
    if results.get("camera"):
        from cadfeat.camera import camera_from_dict

        data = {k: v for k, v in results["camera"].items() if k != "source"}
        return camera_from_dict(data, "results.json camera")
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


def make_renders(context: ReportContext | None, results: dict, img_dir: str | Path) -> Renders:
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
    samples = context.samples()
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


def _render_part(renders: Renders, render, context: ReportContext, img_dir: Path) -> None:
    holes = list(context.holes_before) if context.holes_before is not None else None
    try:
        renders.comparison = {"current": Path(render.render_part(context.shape_before, img_dir / "part.png", holes))}
    except Exception as exc:
        _fail(renders, "part render", exc)
