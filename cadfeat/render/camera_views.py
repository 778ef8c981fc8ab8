"""Synthetic camera images: what the study's camera sees, with its real intrinsics and pose.

The VTK camera is set from the OpenCV model (docs/design.md "Conventions", eq. A.1–A.7 of the thesis):

- pose: ``T_part_cam = inv(T_cam_part)``; position = its translation, focal point one unit along the
  camera's +z column, view-up = −y column (OpenCV y points down in the image);
- vertical view angle ``2·atan(height / (2·fy))``, explicit aspect ratio ``(width/height)·(fy/fx)``
  (so fx ≠ fy is exact);
- principal point through ``vtkCamera.SetWindowCenter``: OpenCV puts pixel centres at integer
  coordinates, VTK at half-integers, so ``(cx + ½, height − cy − ½)`` in VTK window coordinates
  becomes the window centre ``(1 − 2(cx + ½)/w, 2(cy + ½)/h − 1)``.

Lens distortion is applied after rendering by remapping the pinhole image (``cv2.remap`` with the
maps from ``cv2.undistortPoints``), so a hole's rim lands where ``Camera.project`` puts it. The pinhole render
is padded (same fx, fy; the principal point moved by the pad) to cover every pinhole pixel that a distorted
pixel inside the lens model's valid field (``Camera.fold_radius``) shows: a barrel lens (k₁ < 0) images a wider
field than its pinhole, and an unpadded render left a black band along the image's edge where the real camera
sees the part (its edge then failed the detector's surround test on holes next to it).
The part is light grey, lit from the camera; hole faces are dark; the background is black. Anti-aliasing
is off (each pixel samples its centre), which keeps edges unbiased: the dark hole regions found by
thresholding agree with the exact rim ellipses to ~0.2 px (tests/render/test_render_camera.py).

``supersample=k`` (default ``DEFAULT_SUPERSAMPLE`` = 1: point sampling) integrates each pixel over its area as
a sensor does: the pinhole image is rendered at k× (fx, fy, width, height × k; principal point k(c + ½) − ½, so
that the k × k block of sub-pixels of pixel (u, v) is centred on it) and each k × k block is averaged
(``cv2.resize`` with ``INTER_AREA``, an exact box mean for an integer factor), before the lens distortion and any
optics blur. A point sampled edge sits on the pixel grid (a rim's fitted centre then carries a staircase error
that depends on its sub-pixel placement); the box mean of k² point samples gives each edge pixel its covered
fraction to 1/k², so the edge keeps its sub-pixel position. Unlike MSAA's resolve (off, above), the box mean is
centred on the pixel: it does not move edges (tests/render/test_render_supersample.py: against the exact
coverage of a polygon).
One plotter serves any number of poses (``CameraViewRenderer``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cadfeat.cad.features import holes_to_arrays
from cadfeat.cad.features.identity import hole_name
from cadfeat.measures import hole_ellipse
from cadfeat.poses import invert_T
from cadfeat.render.scene import (
    RenderError,
    add_part,
    cell_colours,
    hole_cell_labels,
    new_plotter,
    screenshot,
    shape_polydata,
)

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

    from cadfeat.cad.features import Hole, ShapeLike
    from cadfeat.camera import Camera

BACKGROUND_BLACK = (0.0, 0.0, 0.0)
ELLIPSE_COLOUR_RGB = (40, 220, 60)
CENTRE_COLOUR_RGB = (255, 60, 40)
#: Sub-pixels per pixel side of ``CameraViewRenderer`` when it is not given ``supersample`` (module docstring):
#: 1 = point sampling at pixel centres. The closed loop and the calibration renders go through this default;
#: ``tools/pose_panel.py --supersample`` and ``tools/calibrate_detection.py --supersample`` set it for a run.
DEFAULT_SUPERSAMPLE = 1


def set_vtk_camera(vtk_camera: Any, camera: Camera, T_cam_part: np.ndarray, near_far_mm: tuple[float, float]) -> None:
    """Point a ``vtkCamera`` like the OpenCV camera ``camera`` at pose ``T_cam_part`` (pinhole part only)."""
    T = invert_T(np.asarray(T_cam_part, dtype=float))
    position, z_axis, y_axis = T[:3, 3], T[:3, 2], T[:3, 1]
    vtk_camera.SetPosition(*position)
    vtk_camera.SetFocalPoint(*(position + z_axis))
    vtk_camera.SetViewUp(*(-y_axis))
    vtk_camera.SetViewAngle(math.degrees(2.0 * math.atan(camera.height / (2.0 * camera.fy))))
    vtk_camera.SetUseHorizontalViewAngle(False)
    vtk_camera.SetExplicitAspectRatio(camera.width / camera.height * camera.fy / camera.fx)
    vtk_camera.SetUseExplicitAspectRatio(True)
    vtk_camera.SetWindowCenter(1.0 - 2.0 * (camera.cx + 0.5) / camera.width,
                               2.0 * (camera.cy + 0.5) / camera.height - 1.0)
    vtk_camera.SetClippingRange(*near_far_mm)


def near_far_mm(points_part: np.ndarray, T_cam_part: np.ndarray) -> tuple[float, float]:
    """Clipping range (mm) enclosing ``points_part`` (M, 3) seen from ``T_cam_part``."""
    z = points_part @ T_cam_part[:3, :3].T[:, 2] + T_cam_part[2, 3]
    far = max(float(z.max()) * 1.05, 1.0)
    return max(float(z.min()) * 0.95, far * 1e-4, 1e-3), far


class CameraViewRenderer:
    """Renders a part as the study's camera sees it; ONE off-screen plotter for all poses.

    ``render(T_cam_part)`` returns a (height, width, 3) uint8 RGB image; ``overlay=True`` draws the
    predicted hole ellipses (``cadfeat.measures.hole_ellipse``) and projected centres (``Camera.project``).
    Call ``close()`` (or use as a context manager) to free the OpenGL context.
    """

    def __init__(self, shape: ShapeLike, holes: Sequence[Hole], camera: Camera, *, mesh: trimesh.Trimesh | None = None,
                 supersample: int | None = None) -> None:
        if supersample is None:
            supersample = DEFAULT_SUPERSAMPLE
        if isinstance(supersample, bool) or not isinstance(supersample, int | np.integer) \
                or not 1 <= supersample <= 8:
            raise RenderError(f"supersample must be an integer in 1..8 (sub-pixels per pixel side), "
                              f"got {supersample!r}")
        self.camera = camera
        self.supersample = int(supersample)
        self.holes = list(holes)
        self.mesh = shape_polydata(shape) if mesh is None else mesh
        self._corners = _box_corners(np.asarray(self.mesh.bounds))
        self._maps = _distortion_maps(camera) if camera.has_distortion else None
        pad = 0 if self._maps is None else _padding(camera, self._maps)
        if pad:
            self._maps = (self._maps[0] + pad, self._maps[1] + pad)
        self._pinhole = replace(camera, width=camera.width + 2 * pad, height=camera.height + 2 * pad,
                                cx=camera.cx + pad, cy=camera.cy + pad) if pad else camera
        self._rendered = supersampled(self._pinhole, self.supersample)
        self.plotter = new_plotter((self._rendered.width, self._rendered.height), background=BACKGROUND_BLACK,
                                   lighting="none")
        self.plotter.disable_anti_aliasing()  # point sampling at pixel centres: MSAA's resolve biases edges ~¼ px
        import pyvista as pv

        self.plotter.add_light(pv.Light(light_type="headlight", intensity=0.75))
        labels = hole_cell_labels(self.mesh, self.holes)
        add_part(self.plotter, self.mesh, cell_colours(labels, None), ambient=0.3, diffuse=0.75, specular=0.0)

    def render(self, T_cam_part: np.ndarray, overlay: bool = False) -> np.ndarray:
        """The camera image at pose ``T_cam_part`` (4, 4) (maps part to camera frame, mm)."""
        T = np.asarray(T_cam_part, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise RenderError(f"T_cam_part must be a finite 4x4 transform, got shape {T.shape}")
        import cv2

        pinhole, rendered = self._pinhole, self._rendered
        set_vtk_camera(self.plotter.camera, rendered, T, near_far_mm(self._corners, T))
        image = screenshot(self.plotter)
        if image.shape[:2] != (rendered.height, rendered.width):
            raise RenderError(f"rendered {image.shape[1]}x{image.shape[0]} px, expected "
                              f"{rendered.width}x{rendered.height}")
        if self.supersample > 1:
            # the box mean of each k × k block (OpenCV's fixed point on 8 bits: within 1 grey level of the exact
            # mean, 9x faster than in float at 2560 x 2048)
            image = cv2.resize(image, (pinhole.width, pinhole.height), interpolation=cv2.INTER_AREA)
        if self._maps is not None:
            image = cv2.remap(image, *self._maps, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
        if overlay and self.holes:
            image = draw_hole_overlay(image, self.camera, self.holes, T)
        return image

    def render_grey(self, T_cam_part: np.ndarray) -> np.ndarray:
        """Grey (H, W) float32 in 0 … 255 at pose ``T_cam_part``: the luma of ``render`` (as
        ``vision.images.grey``), what the closed loop reads (``render.interface.CameraRenderer``)."""
        rgb = self.render(T_cam_part).astype(np.float32)
        return rgb @ np.array([0.299, 0.587, 0.114], dtype=np.float32)

    def close(self) -> None:
        self.plotter.close()

    def __enter__(self) -> CameraViewRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def supersampled(camera: Camera, k: int) -> Camera:
    """The pinhole ``camera`` with k × k sub-pixels per pixel: fx, fy, width, height × k and the principal point
    k(c + ½) − ½. Image coordinates map as x' = k(x + ½) − ½ (OpenCV's pixel centres at integers): sub-pixel
    i = 0 … k − 1 of pixel u, centred at u − ½ + (i + ½)/k, lands on the integer k·u + i, so the k × k block
    (k·u … k·u + k − 1) covers exactly pixel u's area. Only the pinhole part is rendered (``set_vtk_camera``)."""
    if k == 1:
        return camera
    return replace(camera, fx=camera.fx * k, fy=camera.fy * k, cx=k * (camera.cx + 0.5) - 0.5,
                   cy=k * (camera.cy + 0.5) - 0.5, width=camera.width * k, height=camera.height * k)


def _box_corners(bounds: np.ndarray) -> np.ndarray:
    """The 8 corners (8, 3) of the axis-aligned box ``bounds = (xmin, xmax, ymin, ymax, zmin, zmax)``."""
    xs, ys, zs = bounds[0:2], bounds[2:4], bounds[4:6]
    return np.array(np.meshgrid(xs, ys, zs, indexing="ij")).reshape(3, -1).T


def _distortion_maps(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """``cv2.remap`` maps taking the pinhole render to the distorted image (float32, (h, w) each).

    For every distorted pixel, ``cv2.undistortPoints`` (with P = K) gives the pinhole pixel it shows.
    """
    import cv2

    u, v = np.meshgrid(np.arange(camera.width, dtype=np.float64), np.arange(camera.height, dtype=np.float64))
    pts = np.stack([u.ravel(), v.ravel()], axis=-1)[:, None, :]
    und = cv2.undistortPoints(pts, camera.K, camera.dist_coeffs, P=camera.K).reshape(camera.height, camera.width, 2)
    return und[..., 0].astype(np.float32), und[..., 1].astype(np.float32)


def _padding(camera: Camera, maps: tuple[np.ndarray, np.ndarray]) -> int:
    """Pixels to add on each side of the pinhole render so that it holds every pinhole pixel (``maps``) shown
    by a distorted pixel inside the lens model's valid field (``Camera.fold_radius``; past it the model folds
    and the pixels are left as they map); at most the image's larger side."""
    u, v = np.meshgrid(np.arange(camera.width, dtype=np.float64), np.arange(camera.height, dtype=np.float64))
    valid = np.hypot((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy) < camera.fold_radius_distorted
    mx, my = maps[0][valid], maps[1][valid]
    if mx.size == 0:
        return 0
    over = max(0.0, -float(mx.min()), float(mx.max()) - (camera.width - 1),
               -float(my.min()), float(my.max()) - (camera.height - 1))
    return 0 if over == 0.0 else min(int(math.ceil(over)) + 2, max(camera.width, camera.height))


def predicted_ellipses(camera: Camera, holes: Sequence[Hole], T_cam_part: np.ndarray) -> Any:
    """``cadfeat.measures.hole_ellipse`` of the holes' entrance rims at one pose ``T_cam_part`` (4, 4)."""
    centres, axes, radii = holes_to_arrays(holes)
    R, t = T_cam_part[:3, :3], T_cam_part[:3, 3]
    return hole_ellipse(camera, centres @ R.T + t, axes @ R.T, radii)


def draw_hole_overlay(image: np.ndarray, camera: Camera, holes: Sequence[Hole], T_cam_part: np.ndarray) -> np.ndarray:
    """Copy of ``image`` with each hole's predicted rim ellipse (green, ``measures.hole_ellipse``), its
    projected centre (red cross, ``Camera.project``) and its name (``H<i+1>`` when the hole has none, the
    numbering of every other output). Holes whose rim is not wholly in front of the camera (invalid ellipse)
    or reaches past the lens's fold radius (``Camera.fold_radius``: the image there is folded) are skipped."""
    import cv2

    out = np.ascontiguousarray(image.copy())
    centres, _, radii = holes_to_arrays(holes)
    ellipses = predicted_ellipses(camera, holes, T_cam_part)
    P = centres @ T_cam_part[:3, :3].T + T_cam_part[:3, 3]
    centre_px = camera.project(P)
    z = np.maximum(P[:, 2], 1e-9)
    folded = np.hypot(P[:, 0] / z, P[:, 1] / z) + radii / z > camera.fold_radius
    shift = 4  # cv2 sub-pixel drawing: coordinates scaled by 2**shift
    scale = 1 << shift
    limit = 4.0 * max(camera.width, camera.height)  # cv2 drawing needs bounded integers
    for j in np.flatnonzero(np.asarray(ellipses.valid) & ~folded):
        c, ax = np.asarray(ellipses.centre_px)[j], np.asarray(ellipses.axes_px)[j]
        if not (np.all(np.isfinite(c)) and np.all(np.abs(c) < limit) and 0 < ax[0] < limit):
            continue
        angle = math.degrees(float(np.asarray(ellipses.angle_rad)[j]))
        cv2.ellipse(out, (int(round(c[0] * scale)), int(round(c[1] * scale))),
                    (int(round(ax[0] / 2 * scale)), int(round(ax[1] / 2 * scale))), angle, 0, 360,
                    ELLIPSE_COLOUR_RGB, 1, cv2.LINE_AA, shift)
        p = np.round(centre_px[j]).astype(int)
        cv2.drawMarker(out, (int(p[0]), int(p[1])), CENTRE_COLOUR_RGB, cv2.MARKER_CROSS, 7, 1)
        _label(out, hole_name(holes[j], j), (int(p[0]) + 6, int(p[1]) - 6))
    return out


def _label(image: np.ndarray, text: str, at: tuple[int, int]) -> None:
    """A hole name readable when the view is shown at ~600 px wide: text height ≈ 2.2 % of the image width
    (about 13 px there), white on a black outline."""
    import cv2

    scale = max(0.5, 0.022 * image.shape[1] / 22.0)  # FONT_HERSHEY_SIMPLEX is ~22 px high at scale 1
    thick = max(1, int(round(2 * scale)))
    cv2.putText(image, text, at, cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), thick + 3, cv2.LINE_AA)
    cv2.putText(image, text, at, cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), thick, cv2.LINE_AA)


def render_camera_views(shape: ShapeLike, holes: Sequence[Hole], camera: Camera, T_cam_part: np.ndarray,
                        out_dir: str | Path, prefix: str = "view", *, overlay: bool = True) -> list[Path]:
    """Synthetic camera images at poses ``T_cam_part`` (K, 4, 4), one PNG each (``{prefix}_{k:03d}.png``).

    One plotter renders all K poses (only the VTK camera changes between images).
    """
    import cv2

    T = np.asarray(T_cam_part, dtype=float)
    if T.ndim == 2:
        T = T[None]
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise RenderError(f"T_cam_part must have shape (K, 4, 4), got {T.shape}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    with CameraViewRenderer(shape, holes, camera) as renderer:
        for k, pose in enumerate(T):
            path = out / f"{prefix}_{k:03d}.png"
            image = renderer.render(pose, overlay=overlay)
            if not cv2.imwrite(str(path), cv2.cvtColor(image, cv2.COLOR_RGB2BGR)):
                raise RenderError(f"cannot write {path}")
            paths.append(path)
    return paths
