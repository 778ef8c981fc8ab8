"""Focus: depth-of-field margin (thesis eq. 3.4–3.6).

Near and far planes D2, D1 (``Camera.depth_of_field_mm``) come from the thin lens: focal length f,
aperture a = f/N, image distance d (from the focus distance) and blur circle c; D1 = ∞ at or past the
hyperfocal distance. A point at depth Z (its distance along the optical axis, (r_A − r_C)·ν_C of
eq. 3.6) is in focus when D2 ≤ Z ≤ D1.

This is eq. 3.6's margin wherever the hole is, also hidden by the part or past the lens's fold radius
(``evaluate`` reports those beside it). How the objectives score a hole the camera cannot see (f + (1 − h)(margin
− f), f = −(near + far)/scale) is ``cadfeat.design.unseen``'s rule, not this measure's.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import Camera
from cadfeat.errors import CadfeatError


def focus_scale_mm(camera: Camera) -> float:
    """Normalising half-width of the depth of field, mm: (D1 − D2)/2, or D2 when D1 = ∞."""
    near, far = camera.depth_of_field_mm
    return 0.5 * (far - near) if np.isfinite(far) else near


def focus_margin(camera: Camera, points_cam: ArrayLike) -> np.ndarray:
    """min(Z − D2, D1 − Z) / ((D1 − D2)/2) (...) for points (..., 3) mm, camera frame (dimensionless).

    1 in the middle of the depth of field, 0 on the near/far planes, negative outside. With D1 = ∞
    (focused at or beyond the hyperfocal distance) the margin is (Z − D2)/D2. Points behind the camera
    give finite values below −2 D2 / scale (strongly negative).
    """
    return focus_margin_depth(camera, np.asarray(points_cam, dtype=float)[..., 2])


def focus_margin_depth(camera: Camera, z: np.ndarray) -> np.ndarray:
    """``focus_margin`` of depths z (...) mm."""
    near, far = camera.depth_of_field_mm
    margin = z - near if not np.isfinite(far) else np.minimum(z - near, far - z)
    return margin / focus_scale_mm(camera)


def defocus_diameter_px(camera: Camera, depth_mm: ArrayLike) -> np.ndarray:
    """Thin-lens circle-of-confusion diameter (px) of a point at ``depth_mm`` (camera z, mm): with aperture a = f/N,
    focal length f and focus distance s, c = a f |Z − s| / (Z (s − f)) mm on the sensor (the relation behind the
    depth of field, eq. 3.4–3.6), divided by the pixel pitch. Depths are clipped just beyond f."""
    Z = np.maximum(np.asarray(depth_mm, dtype=float), camera.focal_length_mm * 1.001)
    f, s, a = camera.focal_length_mm, camera.focus_distance_mm, camera.aperture_mm
    if a is None:
        raise CadfeatError("defocus_diameter_px: the camera has no aperture; allowed: a Camera with f_number or "
                           "aperture_mm")
    c_mm = a * f * np.abs(Z - s) / (Z * (s - f))
    return c_mm / camera.pixel_pitch_mm
