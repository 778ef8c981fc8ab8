"""Physically based camera images (Mitsuba 3 path tracer): the referee of docs/design.md "Closed loop".

``PbrRenderer(shape, holes, camera, light=..., material=..., spp=16)`` is the counterpart of the raster
``CameraViewRenderer``: ``render(T_cam_part)`` returns linear radiance (H, W) float32, scaled so that a white
Lambertian face lit on axis by the light's ``intensity`` 1 reads 1.0 (a mid-grey lit face ≈ 0.5; see
``cell.light``); ``render_grey`` the noiseless exposed grey 0 … 255 (``render.sensor.expose``) the closed loop
reads; ``render.sensor.capture`` adds the sensor's noise. The part is one material (``cell.material``); the
holes are not painted: a bore is dark or bright as the light and its walls make it (path tracer, ``max_depth``
bounces: shadows and interreflection).

Geometry, exact to the OpenCV ``Camera`` (tests/render/test_render_pbr.py: a projected point within 0.1 px):

- the part is tessellated finely (``TOLERANCE_MM``, ``ANGULAR_TOLERANCE_RAD``: any bore is a ≥ 63-gon) with
  smooth normals within each B-rep face (``pbr_scene.part_mesh_arrays``), written as a PLY to a temporary
  folder and loaded once; each frame's scene reuses it (only the sensor and the camera-borne light move);
- a Mitsuba ``perspective`` sensor of square pixels with fx (``pbr_scene.sensor_dict``: fov along x, the
  principal point with OpenCV's half-pixel shift). **fx ≠ fy**: the rows are rendered at fy' = fx (height
  ⌈H·fx/fy⌉) and resampled to fy by exact area weights (``row_resampling``: output row v is the mean of the
  rendered rows over its span [v·s, (v + 1)·s), s = fx/fy, in edge coordinates) — a box in the row direction,
  so no edge moves;
- **pixel integration**: the film's ``box`` reconstruction filter (radius ½ px) makes each pixel the mean
  radiance over its own square (stratified samples), as a sensor pixel integrates light: an edge's pixel reads
  its covered fraction, so the edge's sub-pixel position survives; a wider filter (gaussian) would blur but,
  being symmetric, not move edges;
- **lens distortion** after rendering, as the raster renderer: the pinhole image is padded and remapped with
  ``camera_views._distortion_maps`` / ``_padding`` (bilinear).

The Mitsuba variant is chosen once per process (``pbr_scene.use_variant``). ``estimate_seconds`` times a small
warm render and scales it to a frame (the CLI can announce a PBR run's time before it starts).
"""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cadfeat.cad.hole_ends import HOLE_ENDS
from cadfeat.cell.light import Light
from cadfeat.cell.material import Material, bsdf_dict
from cadfeat.render.camera_views import _distortion_maps, _padding, near_far_mm
from cadfeat.render.pbr_scene import (
    background_radiance,
    emitter_mesh_ply,
    light_dicts,
    part_mesh_arrays,
    sensor_dict,
    use_variant,
    write_ply,
)
from cadfeat.render.scene import RenderError
from cadfeat.render.sensor import Sensor, expose

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cad.features import Hole, ShapeLike
    from cadfeat.camera import Camera

__all__ = ["HOLE_ENDS", "PbrRenderer", "row_resampling"]

#: Chord (mm) and angular (rad) tolerances of the PBR tessellation, the raster's: a bore is a ≥ 63-gon (a Ø 5 rim
#: within 3 µm of its circle, < 0.02 px on the flagship's camera at 260 mm); the smooth per-face vertex normals
#: make its wall shade round (a glossy wall's highlight does not break into facets).
TOLERANCE_MM = 0.01
ANGULAR_TOLERANCE_RAD = 0.1
#: Film pixels added around the part's projected extent when only that window is rendered (the box filter gives
#: a pixel only the samples inside its own square: 2 px cover round-off).
CROP_PAD_PX = 2
#: A window covering more than this fraction of the film is rendered as the whole film.
CROP_MAX_FRACTION = 0.8
#: Luminance of linear RGB (Rec. 709 / sRGB primaries, Mitsuba's RGB variants).
LUMINANCE_RGB = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)


def row_resampling(height_out: int, height_in: int, scale: float) -> np.ndarray:
    """(height_out, height_in) area weights: output row v (edge coordinates [v, v + 1)) is the mean of the input
    rows over [v·scale, (v + 1)·scale) (input row k covers [k, k + 1)); rows sum to 1 where covered."""
    lo = np.arange(height_out)[:, None] * scale
    k = np.arange(height_in)[None, :]
    overlap = np.clip(np.minimum(lo + scale, k + 1) - np.maximum(lo, k), 0.0, None)
    return (overlap / scale).astype(np.float32)


class PbrRenderer:
    """Renders a part as the study's camera sees it with Mitsuba 3 (module docstring); ONE loaded mesh for all
    poses. ``render(T_cam_part)`` → radiance (H, W) float32; ``render_grey`` → grey 0 … 255 float32. Call
    ``close()`` (or use as a context manager) to remove the temporary mesh files.

    ``light`` / ``material`` / ``sensor``: the cell's (defaults: ring light, machined aluminium, auto exposure);
    ``spp`` samples per pixel; ``max_depth`` path length (≥ 4: a bore's floor seen after two wall bounces);
    ``variant``: a Mitsuba variant (None: ``use_variant``'s choice); ``hole_ends``: ``"as_modelled"``, or
    ``"drilled"`` (a 118° drill point cut into each blind hole's floor, ``cad.hole_ends``) or ``"milled"`` (a
    flat floor: the model as it is when it has one); ``seed``: the sampler's seed of the first frame (frame k
    uses seed + k); ``crop``: path-trace only the film window the part covers (``part_window``) and give the rest
    the background's radiance (what a ray that misses the part reads) — the same image at the cost of the part's
    pixels.
    """

    def __init__(self, shape: ShapeLike, holes: Sequence[Hole], camera: Camera, *, light: Light | None = None,
                 material: Material | None = None, sensor: Sensor | None = None, spp: int = 16,
                 max_depth: int = 6, variant: str | None = None, hole_ends: str = "as_modelled",
                 seed: int = 0, crop: bool = True) -> None:
        if hole_ends not in HOLE_ENDS:
            raise RenderError(f"hole_ends: {hole_ends!r} is not allowed; allowed: {', '.join(HOLE_ENDS)}")
        if isinstance(spp, bool) or not isinstance(spp, int) or spp < 1 or max_depth < 4:
            raise RenderError(f"spp must be an integer ≥ 1 and max_depth ≥ 4, got spp={spp!r}, "
                              f"max_depth={max_depth!r}")
        self.variant = use_variant(variant)
        self.camera, self.holes, self.spp, self.max_depth = camera, list(holes), spp, max_depth
        self.light, self.material = light or Light(), material or Material()
        self.sensor = sensor or Sensor()
        self._frame, self.crop = seed, crop
        self._tmp = tempfile.TemporaryDirectory(prefix="cadfeat_pbr_")
        self._part, self._corners, self._hull = self._load_part(_shaped_holes(shape, self.holes, hole_ends))
        self._emitter = emitter_mesh_ply(self.light, Path(self._tmp.name) / "emitter.ply")
        self._geometry()

    def _load_part(self, shape: ShapeLike) -> tuple[Any, np.ndarray, np.ndarray]:
        """(the loaded Mitsuba mesh, its bounding box's 8 corners (near/far planes), its convex hull's vertices
        (``part_window``)), part frame, mm."""
        import mitsuba as mi

        vertices, tris, normals = part_mesh_arrays(shape, TOLERANCE_MM, ANGULAR_TOLERANCE_RAD)
        path = write_ply(Path(self._tmp.name) / "part.ply", vertices, tris, normals)
        part = mi.load_dict({"type": "ply", "filename": str(path), "face_normals": False,
                             "bsdf": bsdf_dict(self.material)})
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        corners = np.array(np.meshgrid(*zip(lo, hi, strict=True), indexing="ij")).reshape(3, -1).T
        return part, corners, _hull_points(vertices)

    def _geometry(self) -> None:
        """The pinhole camera (padded for the distortion remap) and the square-pixel one Mitsuba renders."""
        cam = self.camera
        self._maps = _distortion_maps(cam) if cam.has_distortion else None
        pad = 0 if self._maps is None else _padding(cam, self._maps)
        if pad and self._maps is not None:
            self._maps = (self._maps[0] + pad, self._maps[1] + pad)
        self.pinhole = replace(cam, width=cam.width + 2 * pad, height=cam.height + 2 * pad,
                               cx=cam.cx + pad, cy=cam.cy + pad) if pad else cam
        s = self.pinhole.fx / self.pinhole.fy
        self._rows = None if s == 1.0 else row_resampling(self.pinhole.height, math.ceil(self.pinhole.height * s), s)
        self.render_height = self.pinhole.height if self._rows is None else self._rows.shape[1]
        self.render_cy = (self.pinhole.cy + 0.5) * s - 0.5   # v' + ½ = (v + ½)·s: edge coordinates scale by s

    def scene(self, T_cam_part: np.ndarray, *, spp: int | None = None,
              crop: tuple[int, int, int, int] | None = None, decimate: int = 1) -> Any:
        """The Mitsuba scene at pose ``T_cam_part`` (4, 4): the part, the sensor and the light. ``decimate`` = k
        renders the same view on a k× coarser film (fx / k; pixel centres k(c + ½) − ½ → c)."""
        import mitsuba as mi

        T = _checked_pose(T_cam_part)
        near, far = near_far_mm(self._corners, T)
        p, k = self.pinhole, decimate
        sensor = sensor_dict(p.width // k, self.render_height // k, p.fx / k, (p.cx + 0.5) / k - 0.5,
                             (self.render_cy + 0.5) / k - 0.5, T, spp=spp or self.spp,
                             near_far_mm=(near * 0.5, far * 2.0), crop=crop)
        return mi.load_dict({"type": "scene", "integrator": {"type": "path", "max_depth": self.max_depth},
                             "sensor": sensor, "part": self._part, **light_dicts(self.light, T, self._emitter)})

    def render_raw(self, T_cam_part: np.ndarray, *, spp: int | None = None,
                   crop: tuple[int, int, int, int] | None = None, decimate: int = 1) -> np.ndarray:
        """Radiance × π of the square-pixel pinhole film (or its ``crop`` = (x, y, w, h); ``decimate``: see
        ``scene``), before the row resampling and the distortion: (h, w) float32."""
        import mitsuba as mi

        scene = self.scene(T_cam_part, spp=spp, crop=crop, decimate=decimate)
        rgb = np.asarray(mi.render(scene, spp=spp or self.spp, seed=self._frame), dtype=np.float32)
        self._frame += 1
        return _film_radiance(rgb)

    def part_window(self, T_cam_part: np.ndarray) -> tuple[int, int, int, int] | None:
        """(x, y, w, h) of the render film (square pixels, before the row resampling and the distortion) holding
        every pixel the part covers at pose ``T_cam_part``: the projections of the part's convex hull (a convex
        body projects inside its hull points' image) + ``CROP_PAD_PX``, clipped to the film; w or h 0 when the part
        is outside it. None — render the whole film — when a hull point is not in front of the camera or the
        window exceeds ``CROP_MAX_FRACTION`` of the film."""
        T = _checked_pose(T_cam_part)
        p = self._hull @ T[:3, :3].T + T[:3, 3]
        if np.any(p[:, 2] <= 1e-6):
            return None
        W, H = self.pinhole.width, self.render_height
        u = self.pinhole.fx * p[:, 0] / p[:, 2] + self.pinhole.cx    # pixel i spans [i − ½, i + ½)
        v = self.pinhole.fx * p[:, 1] / p[:, 2] + self.render_cy     # rendered rows: fy' = fx
        x0, y0 = (max(0, math.floor(float(c.min()) + 0.5) - CROP_PAD_PX) for c in (u, v))
        x1 = min(W, math.floor(float(u.max()) + 0.5) + 1 + CROP_PAD_PX)
        y1 = min(H, math.floor(float(v.max()) + 0.5) + 1 + CROP_PAD_PX)
        w, h = max(0, x1 - x0), max(0, y1 - y0)
        return None if w * h > CROP_MAX_FRACTION * W * H else (min(x0, W), min(y0, H), w, h)

    def render_film(self, T_cam_part: np.ndarray) -> np.ndarray:
        """Radiance × π of the whole square-pixel film: path-traced in ``part_window`` (``crop``), the background's
        radiance elsewhere."""
        window = self.part_window(T_cam_part) if self.crop else None
        if window is None:
            return self.render_raw(T_cam_part)
        miss = _film_radiance(np.full(3, background_radiance(self.light), dtype=np.float32))  # as render_raw reads it
        film = np.full((self.render_height, self.pinhole.width), miss, dtype=np.float32)
        x, y, w, h = window
        if w and h:
            film[y:y + h, x:x + w] = self.render_raw(T_cam_part, crop=window)
        else:
            self._frame += 1  # (the frame's seed is used up all the same)
        return film

    def render(self, T_cam_part: np.ndarray) -> np.ndarray:
        """Linear radiance (H, W) float32 at pose ``T_cam_part`` (4, 4) (maps part to camera frame, mm); a white
        Lambertian face lit on axis by intensity 1 reads 1.0."""
        import cv2

        image = self.render_film(T_cam_part)
        if self._rows is not None:
            image = self._rows @ image
        if self._maps is not None:
            image = cv2.remap(image, *self._maps, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
        return np.ascontiguousarray(image, dtype=np.float32)

    def render_grey(self, T_cam_part: np.ndarray) -> np.ndarray:
        """Noiseless grey (H, W) float32 in 0 … 255: ``render`` exposed by the cell's sensor (``sensor.expose``);
        the noise is ``render.sensor.capture``'s."""
        return expose(self.render(T_cam_part), self.sensor)

    def estimate_seconds(self, T_cam_part: np.ndarray, spp: int | None = None, decimate: int = 4) -> float:
        """Expected seconds of one ``render`` at ``spp`` and pose ``T_cam_part``: the same view on a ``decimate``×
        coarser film (the same content, 1/decimate² of the pixels) at ``spp`` is timed warm (after an untimed one
        that compiles the kernels) and scaled by decimate² — with ``crop``, the part's window of it. Within ~±30 %
        of the measured frame on the flagship part (benchmarks/bench_pbr.py); it costs ~2/decimate² of a frame."""
        spp = spp or self.spp
        window = self.part_window(T_cam_part) if self.crop else None
        crop = None
        if window is not None:
            if not (window[2] and window[3]):
                return 0.0
            x, y, w, h = window
            W, H = self.pinhole.width // decimate, self.render_height // decimate
            x, y = min(x // decimate, W - 1), min(y // decimate, H - 1)
            crop = (x, y, max(1, min(-(-w // decimate), W - x)), max(1, min(-(-h // decimate), H - y)))
        self.render_raw(T_cam_part, spp=spp, decimate=decimate, crop=crop)
        t0 = time.perf_counter()
        self.render_raw(T_cam_part, spp=spp, decimate=decimate, crop=crop)
        return (time.perf_counter() - t0) * decimate ** 2

    def close(self) -> None:
        self._part = None
        self._tmp.cleanup()

    def __enter__(self) -> PbrRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _checked_pose(T_cam_part: np.ndarray) -> np.ndarray:
    T = np.asarray(T_cam_part, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise RenderError(f"T_cam_part must be a finite 4x4 transform, got shape {T.shape}")
    return T


def _shaped_holes(shape: ShapeLike, holes: Sequence[Hole], hole_ends: str) -> Any:
    """``shape`` with its blind holes' ends made as ``hole_ends`` says (``cad.hole_ends``)."""
    from cadfeat.cad.hole_ends import with_hole_ends

    return with_hole_ends(shape, holes, hole_ends)


def _film_radiance(rgb: np.ndarray) -> np.ndarray:
    """Radiance × π (luminance, ``LUMINANCE_RGB``) of Mitsuba's RGB(A) film values (..., ≥ 3), float32."""
    return (rgb[..., :3] @ LUMINANCE_RGB) * np.float32(math.pi)


def _hull_points(vertices: np.ndarray) -> np.ndarray:
    """The vertices (M, 3) of the convex hull of ``vertices`` (all of them when the hull is degenerate)."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        return np.asarray(vertices[ConvexHull(vertices).vertices], dtype=float)
    except (QhullError, ValueError):
        return np.asarray(vertices, dtype=float)
