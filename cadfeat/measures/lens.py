"""Lens model kernel: OpenCV distortion and its Jacobian on separate coordinate arrays (speed kernel).

Same model as ``Camera.distort_normalized`` / ``Camera.distortion_jacobian`` (tests check they agree),
written on component arrays (x, y) so the batched measures work on contiguous (L, N) arrays, share r²
between the pixel position and the 2×2 Jacobian, and skip the terms of zero coefficients. Without
distortion the Jacobian entries are the scalars (fx, 0, 0, fy).
"""

from __future__ import annotations

import numpy as np

from cadfeat.camera import Camera

Array = np.ndarray | float


def _radial(camera: Camera, r2: np.ndarray) -> tuple[Array, Array]:
    """radial = 1 + k1 r² + k2 r⁴ + k3 r⁶ and 2 ∂radial/∂r², skipping zero coefficients."""
    k1, k2, _, _, k3 = camera.dist
    if k3:
        return 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)), 2.0 * k1 + r2 * (4.0 * k2 + 6.0 * k3 * r2)
    if k2:
        t = k2 * r2
        return 1.0 + r2 * (k1 + t), 2.0 * k1 + 4.0 * t
    return 1.0 + k1 * r2, 2.0 * k1


def distort_terms(camera: Camera, x: np.ndarray, y: np.ndarray, positions: bool = True
                  ) -> tuple[Array | None, Array | None, Array, Array, Array, Array]:
    """(u, v, d00, d01, d10, d11): pixels and ∂(u, v)/∂(x, y) of normalised coordinates x, y (same shape).

    ``positions=False`` skips the pixel positions (returns None for u, v).
    """
    fx, fy = camera.fx, camera.fy
    if not any(camera.dist):
        if not positions:
            return None, None, fx, 0.0, 0.0, fy
        return fx * x + camera.cx, fy * y + camera.cy, fx, 0.0, 0.0, fy
    _, _, p1, p2, _ = camera.dist
    xx, yy, xy = x * x, y * y, x * y
    r2 = xx + yy
    radial, g = _radial(camera, r2)  # g = 2 ∂radial/∂r²
    u = v = None
    tangential = bool(p1 or p2)
    if positions:
        xd, yd = x * radial, y * radial
        if tangential:
            xd += 2.0 * p1 * xy + p2 * (r2 + 2.0 * xx)
            yd += p1 * (r2 + 2.0 * yy) + 2.0 * p2 * xy
        u, v = fx * xd + camera.cx, fy * yd + camera.cy
    cross = g * xy
    d00 = radial + g * xx
    d11 = radial + g * yy
    if tangential:
        cross += 2.0 * (p1 * x + p2 * y)
        d00 += 2.0 * p1 * y + 6.0 * p2 * x
        d11 += 6.0 * p1 * y + 2.0 * p2 * x
    return u, v, fx * d00, fx * cross, fy * cross, fy * d11
