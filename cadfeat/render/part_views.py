"""Pictures of a part: a single view, and the before/after comparison of a redesign (like thesis Fig. 1.2c).

The comparison renders both parts from ONE viewpoint (fitted to both parts, the camera trajectory
and its frusta), so the two PNGs can be laid side by side or flipped between. Moved holes are
highlighted, with arrows from the old to the new rim centre and the old rim drawn as a ghost ring;
fixed holes are blue and labelled; the camera path is a polyline with camera frusta (from the
real intrinsics) at a few samples; a legend names the colours. With ``closeup=True`` a second pair
shows the part alone, fitted to its bounding box from a viewpoint chosen to show the most (moved) rims,
with every hole labelled beside its rim and labels kept off each other, the rims and the arrows.

Units: millimetres, part frame. Trajectory poses are ``T_task_cam``; with ``T_task_part`` they are
brought into the part frame (``T_part_cam = T_task_part⁻¹ T_task_cam``).
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cadfeat.cad.features import extract_holes
from cadfeat.render.scene import (
    HOLE_DARK,
    PICTURE_ANGULAR_TOLERANCE_RAD,
    PICTURE_TOLERANCE_MM,
    RenderError,
    add_part,
    cell_colours,
    hole_cell_labels,
    new_plotter,
    shape_polydata,
)
from cadfeat.render.view_geometry import (
    _facing_side,
    _hole_name,
    _label_anchor,
    _moved_mask,
    _ring,
    _side_view,
    _trajectory_in_part,
    _unit,
    _view_up,
    _visible_from,
    closeup_view_direction,
    default_view_direction,
    frustum_lines,
    place_labels,
)

if TYPE_CHECKING:  # pragma: no cover
    import pyvista as pv

    from cadfeat.cad.features import Hole, ShapeLike
    from cadfeat.camera import Camera
    from cadfeat.trajectory import Trajectory

MOVED_BEFORE = (0.95, 0.55, 0.10)   # orange: a hole that will move / its old place
MOVED_AFTER = (0.10, 0.70, 0.25)    # green: a moved hole at its new place
FIXED = (0.15, 0.35, 0.90)          # blue: a hole that may not move
ADDED = (0.80, 0.10, 0.60)          # magenta: a target hole cadfeat added ([add_targets])
ARROW = (0.85, 0.10, 0.10)
PATH = (0.55, 0.20, 0.70)
LEGEND_GREY = (0.55, 0.55, 0.58)    # the part's swatch in the legend (PART_GREY is invisible on white)
FRUSTUM = (0.35, 0.35, 0.40)


def _fit_view(plotter: pv.Plotter, points: np.ndarray, direction: np.ndarray, fill: float = 0.9) -> None:
    """Look along ``-direction`` at ``points`` (M, 3), zoomed so their projection spans ``fill`` of the
    image (VTK's reset fits the bounding sphere, which wastes a third of the picture)."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
    plotter.camera_position = [tuple(centre + direction * 4.0 * radius), tuple(centre), _view_up(direction)]
    plotter.reset_camera(bounds=(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]))
    sample = points[:: max(1, len(points) // 20000)]
    width, height = plotter.window_size
    cam = plotter.camera
    for _ in range(4):  # centre the projection, then zoom (perspective is not linear): a few fixed-point steps
        M = _vtk_matrix(cam.GetCompositeProjectionTransformMatrix(width / height, -1.0, 1.0))
        clip = np.c_[sample, np.ones(len(sample))] @ M.T
        ndc = clip[:, :2] / clip[:, 3:4]
        lo_ndc, hi_ndc = ndc.min(axis=0), ndc.max(axis=0)
        mid, extent = 0.5 * (lo_ndc + hi_ndc), float(np.max(0.5 * (hi_ndc - lo_ndc)))
        if not np.all(np.isfinite(ndc)) or extent <= 0:
            break
        position, focal = np.array(cam.GetPosition()), np.array(cam.GetFocalPoint())
        forward = focal - position
        up = np.array(cam.GetViewUp())
        right = np.cross(forward, up)
        right /= np.linalg.norm(right)
        up = np.cross(right, forward) / np.linalg.norm(forward)
        half_h = np.linalg.norm(forward) * np.tan(np.radians(cam.GetViewAngle()) / 2.0)
        shift = mid[0] * half_h * width / height * right + mid[1] * half_h * up
        cam.SetPosition(*(position + shift))
        cam.SetFocalPoint(*(focal + shift))
        cam.Zoom(fill / extent)  # > 1 zooms in
    plotter.renderer.ResetCameraClippingRange()


def _get_view(plotter: pv.Plotter) -> tuple:
    """Everything that fixes what a perspective camera sees: position, focal point, view-up, view angle."""
    cam = plotter.camera
    return cam.GetPosition(), cam.GetFocalPoint(), cam.GetViewUp(), cam.GetViewAngle()


def _set_view(plotter: pv.Plotter, view: tuple) -> None:
    cam = plotter.camera
    cam.SetPosition(*view[0])
    cam.SetFocalPoint(*view[1])
    cam.SetViewUp(*view[2])
    cam.SetViewAngle(view[3])
    plotter.renderer.ResetCameraClippingRange()


def _vtk_matrix(m: Any) -> np.ndarray:
    return np.array([[m.GetElement(i, j) for j in range(4)] for i in range(4)])


def _label_points(plotter: pv.Plotter, points: np.ndarray, labels: list[str], colour: Sequence[float]) -> None:
    if len(labels):
        plotter.add_point_labels(points, labels, font_size=14, text_color=colour, shape_color="white",
                                 shape_opacity=0.75, show_points=False, always_visible=True)


def render_part(shape: ShapeLike, path: str | Path, holes: Sequence[Hole] | None = None, *,
                view_direction: Sequence[float] | None = None, size: tuple[int, int] = (900, 700)) -> Path:
    """A PNG of ``shape`` from ``view_direction`` (part frame, towards the viewer), holes dark and labelled.

    ``holes=None`` extracts them (``cadfeat.cad.features.extract_holes``). Without ``view_direction`` the
    view is ``default_view_direction(holes)``. Returns the PNG path.
    """
    holes = extract_holes(shape) if holes is None else list(holes)
    direction = default_view_direction(holes) if view_direction is None else _unit(view_direction, "view_direction")
    mesh = _picture_mesh(shape)
    plotter = _picture_plotter(size)
    try:
        add_part(plotter, mesh, cell_colours(hole_cell_labels(mesh, holes), None), specular=0.2)
        _label_points(plotter, _label_anchor(holes, mesh), [_hole_name(h, j) for j, h in enumerate(holes)],
                      (0.1, 0.1, 0.1))
        _fit_view(plotter, np.asarray(mesh.points), direction)
        return _save(plotter, path)
    finally:
        plotter.close()


def _picture_plotter(size: tuple[int, int], headlight: float = 0.15) -> pv.Plotter:
    """White background, VTK's light kit plus a soft headlight (faces seen edge-on to the key light stay
    readable), super-sampled anti-aliasing."""
    import pyvista as pv

    plotter = new_plotter(size)
    plotter.add_light(pv.Light(light_type="headlight", intensity=headlight))
    plotter.enable_anti_aliasing("ssaa")
    return plotter


def _picture_mesh(shape: ShapeLike) -> Any:
    return shape_polydata(shape, PICTURE_TOLERANCE_MM, PICTURE_ANGULAR_TOLERANCE_RAD)


def _save(plotter: pv.Plotter, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    plotter.screenshot(str(path))
    return path


# ------------------------------------------------------------------------------------ comparison


class _Scene:
    """What both comparison images share: meshes, colours, overlays and the fitted viewpoint."""

    def __init__(self, shape_before: ShapeLike, shape_after: ShapeLike, holes_before: Sequence[Hole],
                 holes_after: Sequence[Hole], fixed: Sequence[bool], T_part_cam: np.ndarray | None,
                 camera: Camera | None, n_frusta: int) -> None:
        n = len(holes_before)
        if not (len(fixed) == n <= len(holes_after)):
            raise RenderError(f"render_comparison: holes_before ({n}), holes_after ({len(holes_after)}) and fixed "
                              f"({len(fixed)}): before and fixed must have the same length, after at least as many "
                              "(hole i before corresponds to hole i after; holes after those are added ones)")
        self.before, self.after = list(holes_before), list(holes_after)
        k = len(self.after) - n  # added target holes, after the part's (``[add_targets]``)
        self.fixed = np.concatenate([np.asarray(fixed, dtype=bool), np.zeros(k, bool)])
        self.moved = np.concatenate([_moved_mask(self.before, self.after[:n]), np.zeros(k, bool)]) & ~self.fixed
        self.added = np.arange(len(self.after)) >= n
        self.mesh_before, self.mesh_after = _picture_mesh(shape_before), _picture_mesh(shape_after)
        pts = np.vstack([self.mesh_before.points, self.mesh_after.points])
        self.size_mm = float(np.linalg.norm(np.ptp(pts, axis=0)))
        self.T_part_cam = T_part_cam
        self.frusta = None
        if T_part_cam is not None:
            pts = np.vstack([pts, T_part_cam[:, :3, 3]])
            k = min(max(int(n_frusta), 0), len(T_part_cam))
            if k:
                idx = np.unique(np.linspace(0, len(T_part_cam) - 1, k).round().astype(int))
                self.frusta = frustum_lines(camera, T_part_cam[idx], 0.12 * self.size_mm)
                pts = np.vstack([pts, self.frusta[0]])
        self.bounds_points = pts
        self.direction = default_view_direction(self.after)
        if T_part_cam is not None:
            self.direction = _side_view(self.direction, self.mesh_after.center, T_part_cam[:, :3, 3])

    def marks(self, after: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(fixed, moved, added) masks of the holes of one picture (the added holes exist after only)."""
        n = len(self.after if after else self.before)
        return self.fixed[:n], self.moved[:n], self.added[:n]

    def hole_colours(self, after: bool) -> list[tuple[float, float, float]]:
        moved = MOVED_AFTER if after else MOVED_BEFORE
        fixed, mv, added = self.marks(after)
        return [ADDED if a else FIXED if f else moved if m else HOLE_DARK
                for f, m, a in zip(fixed, mv, added, strict=True)]

    def draw(self, plotter: pv.Plotter, after: bool, overview: bool = True) -> None:
        """The part, hole highlights, old rims and move arrows; with ``overview`` also the point labels, the
        camera path, frusta and legend (the close-up places its labels itself, see ``_place_labels``)."""
        import pyvista as pv

        mesh = self.mesh_after if after else self.mesh_before
        holes = self.after if after else self.before
        add_part(plotter, mesh, cell_colours(hole_cell_labels(mesh, holes), self.hole_colours(after)), specular=0.2)
        lift = 0.004 * self.size_mm
        colours = self.hole_colours(after)
        fixed, moved, added = self.marks(after)
        for j in np.flatnonzero(moved | fixed | added):  # a translucent disc over each highlighted rim
            h = holes[j]
            plotter.add_mesh(pv.Disc(center=h.centre + h.axis * lift, inner=0.0, outer=h.radius_mm, normal=h.axis,
                                     c_res=64), color=colours[j], opacity=0.8)
        if after:
            for j in np.flatnonzero(self.moved):
                old, new = self.before[j], self.after[j]
                plotter.add_mesh(pv.lines_from_points(_ring(old.centre + old.axis * lift, old.axis, old.radius_mm)),
                                 color=MOVED_BEFORE, line_width=3 if overview else 4)
                start, end = old.centre + old.axis * 2 * lift, new.centre + new.axis * 2 * lift
                gap = np.linalg.norm(end - start)
                if not overview and gap > 2.0 * new.radius_mm:  # close-up: the tip stops at the new rim
                    end = end - (end - start) / gap * new.radius_mm
                self._arrow(plotter, start, end)
        if not overview:
            plotter.add_legend(self._legend(overview=False), bcolor="white", border=True, size=(0.2, 0.14),
                               loc="upper left", face="rectangle")
            return
        fixed_idx = np.flatnonzero(fixed)
        _label_points(plotter, _label_anchor([holes[j] for j in fixed_idx], mesh),
                      [f"fixed {_hole_name(holes[j], j)}" for j in fixed_idx], FIXED)
        moved_idx = np.flatnonzero(moved)
        _label_points(plotter, _label_anchor([holes[j] for j in moved_idx], mesh),
                      [_hole_name(holes[j], j) for j in moved_idx], MOVED_AFTER if after else MOVED_BEFORE)
        added_idx = np.flatnonzero(added)
        _label_points(plotter, _label_anchor([holes[j] for j in added_idx], mesh),
                      [f"added {_hole_name(holes[j], j)}" for j in added_idx], ADDED)
        if self.T_part_cam is not None:
            path = pv.lines_from_points(self.T_part_cam[:, :3, 3])
            plotter.add_mesh(path, color=PATH, line_width=3)
            plotter.add_mesh(pv.PolyData(self.T_part_cam[:1, :3, 3]), color=PATH, point_size=12,
                             render_points_as_spheres=True)
        if self.frusta is not None:
            plotter.add_mesh(pv.PolyData(self.frusta[0], lines=self.frusta[1]), color=FRUSTUM, line_width=1.5)
        plotter.add_legend(self._legend(), bcolor="white", border=True, size=(0.26, 0.2), loc="upper left",
                           face="rectangle")

    def _arrow(self, plotter: pv.Plotter, start: np.ndarray, end: np.ndarray) -> None:
        import pyvista as pv

        d = end - start
        length = float(np.linalg.norm(d))
        if length < 1e-9:
            return
        head = min(0.4 * length, 0.05 * self.size_mm)
        tip_base = end - d / length * head
        plotter.add_mesh(pv.Line(start, tip_base).tube(radius=min(0.006 * self.size_mm, 0.18 * head)), color=ARROW)
        plotter.add_mesh(pv.Cone(center=tip_base + d / length * head / 2, direction=d, height=head,
                                 radius=min(0.016 * self.size_mm, 0.45 * head), resolution=24), color=ARROW)

    def _legend(self, overview: bool = True) -> list[list[Any]]:
        """The same entries in both pictures, so they can be flipped between (no camera in the close-up)."""
        entries: list[list[Any]] = [["part", LEGEND_GREY]]
        if self.moved.any():
            entries += [["moved hole, old place", MOVED_BEFORE], ["moved hole, new place", MOVED_AFTER],
                        ["move old -> new", ARROW]]
        if self.fixed.any():
            entries.append(["fixed hole", FIXED])
        if self.added.any():
            entries.append(["added target hole", ADDED])
        if (~self.fixed & ~self.moved & ~self.added).any():
            entries.append(["unchanged hole", HOLE_DARK])
        if self.T_part_cam is not None and overview:
            entries.append(["camera path (dot: start)", PATH])
        if self.frusta is not None and overview:
            entries.append(["camera frusta", FRUSTUM])
        return entries


def render_comparison(shape_before: ShapeLike, shape_after: ShapeLike, holes_before: Sequence[Hole],
                      holes_after: Sequence[Hole],
                      fixed: Sequence[bool], out_dir: str | Path, *, trajectory: Trajectory | None = None,
                      camera: Camera | None = None, T_task_part: np.ndarray | None = None, n_frusta: int = 5,
                      size: tuple[int, int] = (1000, 760), closeup: bool = False) -> dict[str, Path]:
    """Before/after PNGs from the same viewpoint: ``{"before": out_dir/before.png, "after": out_dir/after.png}``.

    ``holes_before[i]`` and ``holes_after[i]`` are the same hole (index correspondence), ``fixed[i]``
    marks holes that may not move. ``trajectory`` (a ``Trajectory`` or (L, 4, 4) ``T_task_cam``) is
    drawn as a polyline with ``n_frusta`` camera frusta (from ``camera``'s intrinsics), placed in the
    part frame with ``T_task_part`` (identity when None). This overview is fitted to the part AND the
    trajectory, so the part may be small; ``closeup=True`` adds the part alone, fitted to its bounding
    box (same viewpoint for both): keys "before_closeup"/"after_closeup" (``closeup_before.png``, ...).
    """
    scene = _Scene(shape_before, shape_after, holes_before, holes_after, fixed,
                   _trajectory_in_part(trajectory, T_task_part), camera, n_frusta)
    out = Path(out_dir)
    paths = {}
    view = None
    for key in ("before", "after"):
        plotter = _picture_plotter(size)
        try:
            scene.draw(plotter, after=key == "after")
            if view is None:
                _fit_view(plotter, scene.bounds_points, scene.direction)
                view = _get_view(plotter)
            else:
                _set_view(plotter, view)
            paths[key] = _save(plotter, out / f"{key}.png")
        finally:
            plotter.close()
    if closeup:
        paths.update(_render_closeup(scene, out, size))
    return paths


# ------------------------------------------------------------------------------------ close-up

LABEL_FONT_SIZE = 17
UNCHANGED_LABEL = (0.25, 0.25, 0.28)


def _render_closeup(scene: _Scene, out: Path, size: tuple[int, int]) -> dict[str, Path]:
    """The part alone, before and after, from one viewpoint fitted to both parts' bounding box (no camera
    path): moved holes with old rims and arrows, fixed holes marked, every hole labelled (labels placed
    beside their rims, away from each other, the rims and the arrows)."""
    points = np.vstack([scene.mesh_before.points, scene.mesh_after.points])
    direction, _ = closeup_view_direction(scene.mesh_after, scene.after,
                                          weights=np.where(scene.moved | scene.added, 3.0, 1.0))
    scene = copy.copy(scene)
    scene.before, scene.after = _facing_side(scene.before, direction), _facing_side(scene.after, direction)
    paths: dict[str, Path] = {}
    view = None
    for key in ("before", "after"):
        plotter = _picture_plotter(size, headlight=0.25)
        try:
            scene.draw(plotter, after=key == "after", overview=False)
            if view is None:
                _fit_view(plotter, points, direction, fill=0.84)
                view = _get_view(plotter)
                scene.visible = _visible_from(scene.mesh_after, scene.after, np.array(view[0]))
            else:
                _set_view(plotter, view)
            _add_hole_labels(plotter, scene, after=key == "after")
            paths[f"{key}_closeup"] = _save(plotter, out / f"closeup_{key}.png")
        finally:
            plotter.close()
    return paths


def _project_px(plotter: pv.Plotter, points: np.ndarray) -> np.ndarray:
    """Display coordinates (px, origin bottom-left, as VTK's 2D actors use) of part-frame points (M, 3)."""
    width, height = plotter.window_size
    M = _vtk_matrix(plotter.camera.GetCompositeProjectionTransformMatrix(width / height, -1.0, 1.0))
    clip = np.c_[points, np.ones(len(points))] @ M.T
    return (clip[:, :2] / clip[:, 3:4] + 1.0) * 0.5 * np.array([width, height])


def _add_hole_labels(plotter: pv.Plotter, scene: _Scene, after: bool) -> None:
    """Every hole labelled in 2D (display coordinates), beside its rim, placed by ``place_labels``."""
    from vtkmodules.vtkRenderingCore import vtkTextActor

    holes = scene.after if after else scene.before
    if not holes:
        return
    plotter.render()
    fixed, moved, added = scene.marks(after)
    colours = [ADDED if a else FIXED if f else (MOVED_AFTER if after else MOVED_BEFORE) if m else UNCHANGED_LABEL
               for f, m, a in zip(fixed, moved, added, strict=True)]
    texts = [f"fixed {_hole_name(h, j)}" if fixed[j] else f"added {_hole_name(h, j)}" if added[j]
             else _hole_name(h, j) for j, h in enumerate(holes)]
    visible = getattr(scene, "visible", np.ones(len(scene.after), dtype=bool))[:len(holes)]
    texts = [t if v else f"{t} (hidden)" for t, v in zip(texts, visible, strict=True)]
    actors = []
    for text, colour in zip(texts, colours, strict=True):
        actor = vtkTextActor()
        actor.SetInput(text)
        prop = actor.GetTextProperty()
        prop.SetFontSize(LABEL_FONT_SIZE)
        prop.SetBold(True)
        prop.SetColor(*colour)
        prop.SetBackgroundColor(1.0, 1.0, 1.0)
        prop.SetBackgroundOpacity(0.85)
        if text.endswith("(hidden)"):
            prop.SetItalic(True)
            prop.SetOpacity(0.6)
        prop.SetFrame(True)
        prop.SetFrameColor(*colour)
        plotter.renderer.AddViewProp(actor)
        actors.append(actor)
    sizes = np.zeros((len(actors), 2))
    for j, actor in enumerate(actors):
        wh = [0.0, 0.0]
        actor.GetSize(plotter.renderer, wh)
        sizes[j] = np.array(wh) + 4.0
    anchors, radii, obstacles = _label_geometry(plotter, scene, holes)
    corners = place_labels(anchors, radii, sizes, obstacles, plotter.window_size)
    for actor, corner in zip(actors, corners, strict=True):
        actor.SetPosition(float(corner[0]) + 2.0, float(corner[1]) + 2.0)


def _label_geometry(plotter: pv.Plotter, scene: _Scene, holes: Sequence[Hole]
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rim centres (N, 2) and radii (N,) in px of ``holes``, and obstacle boxes (K, 4): every highlighted rim
    of both designs, samples along the move arrows, and the legend (upper left)."""
    rings = np.stack([_ring(h.centre, h.axis, h.radius_mm, 24) for h in holes])          # (N, 25, 3)
    px = _project_px(plotter, rings.reshape(-1, 3)).reshape(len(holes), -1, 2)
    anchors = px.mean(axis=1)
    radii = np.linalg.norm(px - anchors[:, None], axis=-1).max(axis=1)
    boxes = [np.c_[px.min(axis=1), px.max(axis=1)]]
    moved = np.flatnonzero(scene.moved)
    if len(moved):
        old = np.stack([_ring(scene.before[j].centre, scene.before[j].axis, scene.before[j].radius_mm, 24)
                        for j in moved])
        opx = _project_px(plotter, old.reshape(-1, 3)).reshape(len(moved), -1, 2)
        boxes.append(np.c_[opx.min(axis=1), opx.max(axis=1)])
        t = np.linspace(0.0, 1.0, 12)[:, None]
        seg = np.concatenate([scene.before[j].centre + t * (scene.after[j].centre - scene.before[j].centre)
                              for j in moved])
        spx = _project_px(plotter, seg)
        boxes.append(np.c_[spx - 4.0, spx + 4.0])
    width, height = plotter.window_size
    boxes.append(np.array([[0.0, 0.84 * height, 0.22 * width, height]]))
    return anchors, radii, np.vstack(boxes)
