"""Resolution margins (thesis §3.3.3): exact rim ellipse (default), the thesis's sphere, line segments.

A hole is resolvable when the minor axis of its image ellipse is at least ``min_axis_px`` (the thesis's
ω, eq. 3.22). Margins are in pixels; a rim not wholly in front of the camera gets a minor axis of 0
and the margin −min_axis_px − max(width, height) (strongly negative, finite).

These are the margins wherever the hole is, also hidden by the part or past the lens's fold radius (``evaluate``
reports those beside them). How the objectives score a hole the camera cannot see (f + (1 − h)(margin − f),
f = −ω − max(W, H), so a hidden hole gains nothing by shrinking) is ``cadfeat.design.unseen``'s rule.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import MIN_DEPTH_MM, Camera
from cadfeat.measures.ellipse import Ellipse, hole_ellipse, sphere_conic, sphere_ellipse


def minor_axis_margin(camera: Camera, minor_px: np.ndarray, valid: np.ndarray, min_axis_px: float) -> np.ndarray:
    """Minor full axis − ``min_axis_px`` (px), with the invalid-ellipse penalty of the module docstring."""
    penalty = float(max(camera.width, camera.height))
    return np.where(valid, minor_px - min_axis_px, -min_axis_px - penalty)


def margin_from_ellipse(camera: Camera, ellipse: Ellipse, min_axis_px: float) -> np.ndarray:
    """``minor_axis_margin`` of an ``Ellipse``."""
    return minor_axis_margin(camera, ellipse.minor_px, ellipse.valid, min_axis_px)


def resolution_margin_px(camera: Camera, centre_cam: ArrayLike, normal_cam: ArrayLike, radius_mm: ArrayLike,
                         min_axis_px: float = 5.0) -> np.ndarray:
    """Minor full axis of the rim's exact image ellipse minus ``min_axis_px`` (...), px (docs/design.md, "The
    measures")."""
    return margin_from_ellipse(camera, hole_ellipse(camera, centre_cam, normal_cam, radius_mm), min_axis_px)


def resolution_margin_sphere(camera: Camera, centre_cam: ArrayLike, normal_cam: ArrayLike | None, radius_mm: ArrayLike,
                             min_axis_px: float = 5.0, *, thesis_eigenvalues: bool = False) -> np.ndarray:
    """The thesis's variant: the hole as a sphere of the rim's radius (eq. 3.13–3.18).

    Same arguments as ``resolution_margin_px`` so it is a drop-in replacement; ``normal_cam`` is ignored (a
    sphere has no orientation) and may be None. Default: minor full axis (px) of the sphere's exact outline
    ellipse minus ``min_axis_px`` — independent of the hole's orientation. ``thesis_eigenvalues=True``
    reproduces eq. 3.22 literally: min eigenvalue of the 2×2 block C_T of the conic as written in eq. 3.18
    (coefficients (Y²+Z²−R²)/f², −XY/f², (X²+Z²−R²)/f² with f = √(fx fy) px, principal point at the origin)
    minus ``min_axis_px``; those eigenvalues are not lengths (mm²/px²), so use it only to compare with the thesis.
    """
    c = np.asarray(centre_cam, dtype=float)
    if not thesis_eigenvalues:
        return margin_from_ellipse(camera, sphere_ellipse(camera, c, radius_mm), min_axis_px)
    a, b, cc, *_ = sphere_conic(c, radius_mm)
    f2 = camera.fx * camera.fy
    a, b, cc = -a / f2, -b / f2, -cc / f2  # eq. 3.18 signs: (Y² + Z² − R²)/f² on x²
    lam_min = 0.5 * (a + cc) - np.hypot(0.5 * (a - cc), b)
    return lam_min - min_axis_px


def line_segment_margin_px(camera: Camera, a_cam: ArrayLike, b_cam: ArrayLike, min_length_px: float) -> np.ndarray:
    """Eq. 3.7 for a segment AB (..., 3) mm, camera frame: image length (px) − ``min_length_px``.

    Image length of the undistorted pinhole, f ‖(A × u) × ν‖ δ / (Z_A Z_B) with u = (B − A)/δ, ν = +z and
    f = √(fx fy) px (exact when fx = fy). A segment reaching behind the camera gets −min_length_px − max(W, H).
    """
    A = np.asarray(a_cam, dtype=float)
    B = np.asarray(b_cam, dtype=float)
    d = B - A
    delta = np.linalg.norm(d, axis=-1)
    u = d / np.where(delta > 0, delta, 1.0)[..., None]
    w = np.cross(np.cross(A, u), np.array([0.0, 0.0, 1.0]))
    za, zb = A[..., 2], B[..., 2]
    front = (za > MIN_DEPTH_MM) & (zb > MIN_DEPTH_MM)
    zz = np.where(front, za * zb, 1.0)
    length = np.sqrt(camera.fx * camera.fy) * np.linalg.norm(w, axis=-1) * delta / zz
    return np.where(front, length - min_length_px, -min_length_px - float(max(camera.width, camera.height)))
