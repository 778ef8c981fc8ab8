"""How much of each hole's rim the part hides, per pose: the ``occlusion`` input of ``pose_information``.

A hole's centre may be in view while part of its rim is not (a base hole half behind the motor plate): the
detector then sees a cut ellipse. ``rim_occlusion`` samples K points on each rim (part frame, mm) and tests
the segment from each to the camera centre against the part's mesh (``visibility.occluded``, the exact ray
test; or ``depth.DepthMaps`` at these poses, the optimiser's fast test), giving the hidden fraction in [0, 1].

A through hole whose bore shows the lit part behind it (the pilot bore showing the base flange) has no dark
interior to detect: with ``through`` and ``depth_mm`` given, a hole whose exit ellipse overlaps its entrance in
the view in more than half of its area (the lens of two circles of radius R whose centres are depth · tan θ
apart, θ the view angle) and whose line of sight through the centre meets the part beyond the exit counts as
hidden (fraction 1): the detector sees a crescent, not an ellipse (rejected). Smaller windows are ignored (a
sliver at the rim's edge; measured on the flagship's M3 holes, detected within 0.1 px).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.poses import invert_T

__all__ = ["rim_occlusion", "rim_points"]


def rim_points(centres: ArrayLike, normals: ArrayLike, radii_mm: ArrayLike, samples: int = 16,
               phase: float = 0.5) -> np.ndarray:
    """(N, K, 3) points evenly spaced on each rim circle (part frame, mm); the first at ``phase`` sample spacings
    from the circle's in-plane axis u."""
    c = np.asarray(centres, dtype=float)
    n = np.asarray(normals, dtype=float)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    r = np.asarray(radii_mm, dtype=float)
    helper = np.where(np.abs(n[:, :1]) < 0.9, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    u = np.cross(n, helper)
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    v = np.cross(n, u)
    phi = 2.0 * np.pi * (np.arange(samples) + phase) / samples
    ring = np.cos(phi)[None, :, None] * u[:, None] + np.sin(phi)[None, :, None] * v[:, None]
    return c[:, None] + r[:, None, None] * ring


def rim_occlusion(mesh: Any, T_cam_part: ArrayLike, centres: ArrayLike, normals: ArrayLike, radii_mm: ArrayLike,
                  *, samples: int = 16, through: ArrayLike | None = None,
                  depth_mm: ArrayLike | None = None) -> np.ndarray:
    """Hidden fraction (L, N) of each rim at poses T_cam_part (L, 4, 4) (module docstring).

    ``mesh``: trimesh of the part (part frame) for the exact test, or ``DepthMaps`` built at these poses.
    """
    # lazy: import cycle (cadfeat.measures.visibility imports cadfeat.measures.rim_occlusion)
    from cadfeat.measures.visibility import occluded

    T = np.asarray(T_cam_part, dtype=float)
    c = np.asarray(centres, dtype=float)
    n = np.asarray(normals, dtype=float)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    N, L = len(c), len(T)
    pts = rim_points(c, n, radii_mm, samples).reshape(-1, 3)
    axes = np.repeat(n, samples, axis=0)
    if hasattr(mesh, "hidden"):  # depth maps at these poses
        P = pts @ np.swapaxes(T[:, :3, :3], 1, 2) + T[:, None, :3, 3]  # R p + t (L, M, 3), one GEMM
        hidden = mesh.hidden(P[..., 0], P[..., 1], P[..., 2])
    else:
        cams = invert_T(T)[:, :3, 3]
        hidden = occluded(mesh, cams, pts, axes)
    frac = hidden.reshape(L, N, samples).mean(axis=-1)
    if through is not None and depth_mm is not None and not hasattr(mesh, "hidden"):
        frac = np.maximum(frac, _lit_through(mesh, T, c, n, np.asarray(radii_mm, float),
                                             np.asarray(through, bool), np.asarray(depth_mm, float)))
    return frac


def _lit_through(mesh: Any, T: np.ndarray, c: np.ndarray, n: np.ndarray, r: np.ndarray, through: np.ndarray,
                 depth: np.ndarray) -> np.ndarray:
    """(L, N) 1.0 where a through hole's see-through window shows the part behind it (module docstring)."""
    cams = invert_T(T)[:, :3, 3]                                           # (L, 3) part frame
    view = c[None] - cams[:, None]                                         # camera → hole (L, N, 3)
    dist = np.linalg.norm(view, axis=-1)
    d = view / dist[..., None]
    cos_t = np.clip(-np.sum(d * n[None], axis=-1), 1e-6, 1.0)
    tan_t = np.sqrt(1.0 - cos_t ** 2) / cos_t
    h = np.clip(depth[None] * tan_t / (2.0 * np.maximum(r[None], 1e-9)), 0.0, 1.0)   # centre distance / 2R
    lens = (2.0 * np.arccos(h) - 2.0 * h * np.sqrt(1.0 - h * h)) / np.pi               # overlap area / πR²
    window = through[None] & (lens > 0.5)
    out = np.zeros(window.shape)
    if not window.any():
        return out
    li, nj = np.nonzero(window)
    exit_pt = c[nj] - n[nj] * depth[nj][:, None]
    origins = exit_pt + d[li, nj] * 1e-2
    hit = np.zeros(len(li), bool)
    _, index_ray, _ = mesh.ray.intersects_location(origins, d[li, nj], multiple_hits=False)
    hit[np.unique(index_ray)] = True
    out[li, nj] = hit.astype(float)
    return out
