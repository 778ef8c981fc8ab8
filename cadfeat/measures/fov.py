"""Field-of-view margins: the thesis's cone (eq. 3.1–3.3) and the rectangular sensor (docs/design.md "The measures").

Margins are positive inside, 0 on the limit. Points at or behind the camera give finite, strongly
negative values: the cone margin is then ≤ −cos(α/2), the image margin ``BEHIND_PX``.

These are the equations' values wherever the hole is, also hidden by the part or past the lens's fold radius
(``evaluate`` reports those beside them). How the objectives score a hole the camera cannot see (f + (1 − h)(margin
− f), f the floor: cone −1 − cos(α/2), image ``behind_px``) is ``cadfeat.design.unseen``'s rule, not this measure's.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import Camera
from cadfeat.measures.ellipse import Ellipse, hole_ellipse


def behind_px(camera: Camera) -> float:
    """Image margin (px) reported for rims not wholly in front of the camera: −2 (width + height)."""
    return -2.0 * float(camera.width + camera.height)


def fov_cone_margin(camera: Camera, points_cam: ArrayLike) -> np.ndarray:
    """cos β − cos(α/2) (...) of points (..., 3) mm, camera frame (eq. 3.2–3.3, dimensionless).

    β is the angle between the optical axis ν = +z and the ray to the point, α = ``camera.fov_rad``
    (smaller sensor dimension). A point at the camera centre gets cos β = −1.
    """
    P = np.asarray(points_cam, dtype=float)
    norm = np.linalg.norm(P, axis=-1)
    cos_beta = np.where(norm > 0, P[..., 2] / np.where(norm > 0, norm, 1.0), -1.0)
    return cos_beta - np.cos(0.5 * camera.fov_rad)


def image_margin_px(camera: Camera, u: np.ndarray, v: np.ndarray, hu: np.ndarray, hv: np.ndarray,
                    valid: np.ndarray) -> np.ndarray:
    """Smallest distance (px) from an ellipse's bounding box (centre u, v; half-widths hu, hv) to the image
    border (image = [0, W]×[0, H], as ``Camera.in_image``); ≥ 0 when the whole rim is inside. Clipped below
    at ``behind_px`` (far outside), which invalid ellipses (rim not in front of the camera) get."""
    margin = np.minimum(np.minimum(u - hu, camera.width - u - hu), np.minimum(v - hv, camera.height - v - hv))
    low = behind_px(camera)
    return np.where(valid, np.maximum(margin, low), low)


def image_margin_from_ellipse(camera: Camera, ellipse: Ellipse) -> np.ndarray:
    """``image_margin_px`` of an ``Ellipse``."""
    h = ellipse.half_extent_px
    return image_margin_px(camera, ellipse.centre_px[..., 0], ellipse.centre_px[..., 1], h[..., 0], h[..., 1],
                           ellipse.valid)


def fov_image_margin_px(camera: Camera, centre_cam: ArrayLike, normal_cam: ArrayLike,
                        radius_mm: ArrayLike) -> np.ndarray:
    """Rectangular-sensor margin (...) px of a hole rim: the rim's image ellipse (``hole_ellipse``) must lie
    inside the image; the margin is the distance of its bounding box to the nearest border (docs/design.md
    "The measures": "centre distance minus semi-major axis", made exact for tilted ellipses)."""
    return image_margin_from_ellipse(camera, hole_ellipse(camera, centre_cam, normal_cam, radius_mm))
