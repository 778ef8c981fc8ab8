"""Lens model kernel: OpenCV distortion and its Jacobian on separate coordinate arrays (speed kernel).

Same model as ``Camera.distort_normalized`` / ``Camera.distortion_jacobian`` (tests check they agree),
written on component arrays (x, y) so the batched measures work on contiguous (L, N) arrays and share
r² between the pixel position and the 2×2 Jacobian. Without distortion the Jacobian entries are the
scalars (fx, 0, 0, fy).
"""

from __future__ import annotations

import numpy as np

from cadfeat.camera import Camera

Array = np.ndarray | float


def distort_terms(camera: Camera, x: np.ndarray, y: np.ndarray) -> tuple[Array, ...]:
    """(u, v, d00, d01, d10, d11): pixels and ∂(u, v)/∂(x, y) of normalised coordinates x, y (same shape)."""
    fx, fy = camera.fx, camera.fy
    if not camera.has_distortion:
        return fx * x + camera.cx, fy * y + camera.cy, fx, 0.0, 0.0, fy
    k1, k2, p1, p2, k3 = camera.dist
    xx, yy, xy = x * x, y * y, x * y
    r2 = xx + yy
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    drad = 2.0 * (k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2))  # 2 ∂radial/∂r²
    u = fx * (x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * xx)) + camera.cx
    v = fy * (y * radial + p1 * (r2 + 2.0 * yy) + 2.0 * p2 * xy) + camera.cy
    cross = xy * drad + 2.0 * (p1 * x + p2 * y)
    d00 = fx * (radial + xx * drad + 2.0 * p1 * y + 6.0 * p2 * x)
    d11 = fy * (radial + yy * drad + 6.0 * p1 * y + 2.0 * p2 * x)
    return u, v, d00, fx * cross, fy * cross, d11
