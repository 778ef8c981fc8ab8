"""Synthetic image sequences along a trajectory, with the sensor effects that decide detection in practice.

Pipeline (deterministic; only the last step depends on the Monte-Carlo seed):

1. ``render_sequence``: the part as the study camera sees it at each pose (``cadfeat.render``'s
   ``CameraViewRenderer``, one off-screen plotter for all frames; real intrinsics, lens distortion by
   remapping), converted to grey levels (F, H, W) float32 in 0..255. The expensive step, done once.
2. ``optics_kernels`` + ``apply_optics``: per frame, a **defocus** pillbox whose diameter is the thin-lens
   circle of confusion at the depth of the part (eq. 3.4–3.6 rearranged):

       c_mm = a f |Z − s| / (Z (s − f)),   c_px = c_mm / pitch,

   a = f/N the aperture, f the focal length, s the focus distance, Z the depth of the holes' centroid
   (mm), pitch = f / fx; and an optional **motion blur**: a line of length ‖J(P̄) γ̇‖ · exposure (px) along
   the image velocity of the holes' centroid, J the image Jacobian (eq. 4.9–4.11), γ̇ the camera's
   velocity screw. The kernels are normalised to sum 1, so the mean grey level is kept. Done once.
3. ``sensor_images``: additive Gaussian grey-level noise (σ in grey levels) and 8-bit quantisation
   (round, clip to 0..255) → (F, H, W) uint8. Seeded per (seed, frame): run ``seed`` always gives the
   same images, and Monte-Carlo runs reuse steps 1–2.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypedDict, Unpack

import numpy as np

from cadfeat.camera import Camera
from cadfeat.cell import defaults as D
from cadfeat.measures import image_jacobian
from cadfeat.measures.focus import defocus_diameter_px

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cad.features import Hole, ShapeLike
    from cadfeat.cell.light import Light
    from cadfeat.cell.material import Material
    from cadfeat.render.sensor import Sensor

#: Kernels are drawn on a grid this many times finer than the pixel grid, then summed (area coverage).
SUPERSAMPLE = 8


class RenderOptions(TypedDict, total=False):
    """The keyword arguments of ``render.camera_renderer`` a closed loop renders with (``render_options``)."""

    light: Light
    material: Material
    spp: int
    hole_ends: str
    sensor: Sensor


@dataclass(frozen=True)
class SensorModel:
    """Sensor effects: ``noise_grey`` σ of additive Gaussian noise (grey levels, 8-bit scale), ``defocus``
    (thin-lens blur on/off), ``exposure_s`` (0 = no motion blur), ``blur_scale`` multiplies both blurs."""

    noise_grey: float = D.NOISE_SIGMA_GREY
    defocus: bool = True
    exposure_s: float = 0.0
    blur_scale: float = 1.0


def render_sequence(shape: ShapeLike, holes: Sequence[Hole], camera: Camera, T_cam_part: np.ndarray,
                    renderer: str = "raster", **options: Unpack[RenderOptions]) -> np.ndarray:
    """Noiseless grey images (F, H, W) float32 (0..255) of the part at poses T_cam_part (F, 4, 4), mm, by the
    ``renderer`` kind (``render.camera_renderer``: "raster" VTK, "pbr" Mitsuba 3 with the cell's ``options``:
    light, material, spp, hole_ends, sensor)."""
    from cadfeat.render import camera_renderer  # lazy: would import scipy.optimize at module load

    T = np.asarray(T_cam_part, dtype=float)
    out = np.empty((len(T), camera.height, camera.width), dtype=np.float32)
    with camera_renderer(renderer, shape, holes, camera, **options) as r:
        for k, pose in enumerate(T):
            out[k] = r.render_grey(pose)
    return out


def grey(rgb: np.ndarray) -> np.ndarray:
    """Luma (ITU-R BT.601, as ``cv2.COLOR_RGB2GRAY``) of an RGB uint8 image, float32 (H, W)."""
    return (rgb[..., :3].astype(np.float32) @ np.array([0.299, 0.587, 0.114], dtype=np.float32))


def image_velocity_px_s(camera: Camera, point_cam: np.ndarray, screw: np.ndarray) -> np.ndarray:
    """Image velocity (F, 2) px/s of points (F, 3) (camera frame, mm) for camera screws (F, 6) (eq. 4.9)."""
    return np.einsum("fij,fj->fi", image_jacobian(camera, point_cam), screw)


def _disk_kernel(diameter_px: float) -> np.ndarray | None:
    """Pillbox kernel of the given diameter (area coverage by supersampling), None below 1 px."""
    if diameter_px < 1.0:
        return None
    r = diameter_px / 2.0
    half = int(np.ceil(r))
    size = 2 * half + 1
    s = (np.arange(size * SUPERSAMPLE) + 0.5) / SUPERSAMPLE - size / 2.0
    inside = (s[:, None] ** 2 + s[None, :] ** 2) <= r * r
    k = inside.reshape(size, SUPERSAMPLE, size, SUPERSAMPLE).sum(axis=(1, 3)).astype(np.float32)
    return k / k.sum()


def _line_kernel(vector_px: np.ndarray) -> np.ndarray | None:
    """Uniform line kernel along ``vector_px`` (2,) (centred, supersampled), None below 1 px."""
    length = float(np.hypot(*vector_px))
    if length < 1.0:
        return None
    half = int(np.ceil(length / 2.0)) + 1
    size = 2 * half + 1
    k = np.zeros((size, size), dtype=np.float32)
    ts = (np.arange(64) + 0.5) / 64 - 0.5
    pts = ts[:, None] * vector_px[None, :] + half
    iu, iv = np.clip(np.floor(pts[:, 0] + 0.5).astype(int), 0, size - 1), np.clip(
        np.floor(pts[:, 1] + 0.5).astype(int), 0, size - 1)
    np.add.at(k, (iv, iu), 1.0)
    return k / k.sum()


def optics_kernels(camera: Camera, T_cam_part: np.ndarray, points_part: np.ndarray, sensor: SensorModel,
                   screws: np.ndarray | None = None) -> list[np.ndarray | None]:
    """Per-frame blur kernel (defocus ∗ motion) or None, from poses (F, 4, 4), hole centres (N, 3) and
    camera screws (F, 6) (mm/s, rad/s; needed when ``sensor.exposure_s > 0``)."""
    import cv2

    T = np.asarray(T_cam_part, dtype=float)
    centroid = np.asarray(points_part, dtype=float).mean(axis=0)
    c_cam = T[:, :3, :3] @ centroid + T[:, :3, 3]                     # (F, 3)
    diam = defocus_diameter_px(camera, c_cam[:, 2]) * sensor.blur_scale if sensor.defocus else np.zeros(len(T))
    motion = np.zeros((len(T), 2))
    if sensor.exposure_s > 0 and screws is not None:
        motion = image_velocity_px_s(camera, c_cam, np.asarray(screws, dtype=float)) * sensor.exposure_s
        motion *= sensor.blur_scale
    kernels: list[np.ndarray | None] = []
    for d, m in zip(diam, motion, strict=True):
        kd, km = _disk_kernel(float(d)), _line_kernel(m)
        if kd is not None and km is not None:
            pad = km.shape[0] // 2
            kd = cv2.filter2D(np.pad(kd, pad), -1, km, borderType=cv2.BORDER_CONSTANT)
            kernels.append(kd / kd.sum())
        else:
            kernels.append(kd if kd is not None else km)
    return kernels


def apply_optics(images: np.ndarray, kernels: Sequence[np.ndarray | None]) -> np.ndarray:
    """Blur each frame (F, H, W) float32 with its kernel (``cv2.filter2D``, replicated borders)."""
    import cv2

    out = np.empty_like(images)
    for k, (img, ker) in enumerate(zip(images, kernels, strict=True)):
        out[k] = img if ker is None else cv2.filter2D(img, -1, ker, borderType=cv2.BORDER_REPLICATE)
    return out


def sensor_images(optical: np.ndarray, noise_grey: float, seed: int) -> np.ndarray:
    """Noisy 8-bit frames (F, H, W) uint8: optical image + N(0, σ²) per pixel, rounded and clipped.

    The noise of frame k comes from ``numpy.random.default_rng([seed, k])``: deterministic per seed and frame.
    """
    out = np.empty(optical.shape, dtype=np.uint8)
    for k, img in enumerate(optical):
        noisy = img
        if noise_grey > 0:
            rng = np.random.default_rng([int(seed), k])
            noisy = img + rng.standard_normal(img.shape, dtype=np.float32) * np.float32(noise_grey)
        out[k] = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
    return out
