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

With ``camera`` given, a rim whose **surround** is not on the part counts as hidden too: the detector accepts a
dark ellipse only when the ring just outside it (``vision.detection.surround_ok``: 2.5 px beyond the fitted
boundary, after a 0.8 px smoothing) is one face, so a rim that comes within ``SURROUND_GAP_PX`` of the face's
outline (the part's silhouette, a step, a face edge) in the image is rejected, like a rim crossed by an edge.
``surround_off`` samples the ring ``SURROUND_GAP_PX`` image pixels outside each rim sample (the step in mm from
the local image scale of the distorted projection, per pose: a strongly distorted lens squeezes the millimetres
near the image's edge into few pixels) and tests each point for the part's surface there: a point is *off* when
the first surface along its line of sight is in front of it (hidden) or not within the mesh tolerance of it
(beyond the outline, or on a face that falls away). The hidden fraction is then the larger of the rim's and its
surround's. The exact test only: the depth maps' cells (several pixels on a VGA image) cannot resolve a ring
3 px outside a rim, so the optimiser's fast test leaves it out (the requirements' edge distance and the maps'
lean towards "hidden" next to a silhouette keep its holes off edges; reports and the closed loop use the exact
test).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.poses import invert_T

__all__ = ["SURROUND_GAP_PX", "rim_occlusion", "rim_points", "surround_off"]

#: Image distance (px) outside a rim at which the part's surface must continue for the detector to accept the rim:
#: its surround ring's 2.5 px plus the 0.8 px smoothing (``vision.detection.detect_holes``), the same 3 px as the
#: gap to another hole's rim (``pose_models.RIM_GAP_MIN_PX``).
SURROUND_GAP_PX = 3.0
#: A surround point is on the surface when the first hit along its line of sight is within this of it, mm (the
#: mesh tessellation tolerance, 0.05 mm, twice, plus slack for the ring's tangent-plane step on a curved face).
ON_SURFACE_MM = 0.15


def rim_points(centres: ArrayLike, normals: ArrayLike, radii_mm: ArrayLike, samples: int = 16) -> np.ndarray:
    """(N, K, 3) points evenly spaced on each rim circle (part frame, mm)."""
    c = np.asarray(centres, dtype=float)
    n = np.asarray(normals, dtype=float)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    r = np.asarray(radii_mm, dtype=float)
    helper = np.where(np.abs(n[:, :1]) < 0.9, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    u = np.cross(n, helper)
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    v = np.cross(n, u)
    phi = 2.0 * np.pi * (np.arange(samples) + 0.5) / samples
    ring = np.cos(phi)[None, :, None] * u[:, None] + np.sin(phi)[None, :, None] * v[:, None]
    return c[:, None] + r[:, None, None] * ring


def rim_occlusion(mesh: Any, T_cam_part: ArrayLike, centres: ArrayLike, normals: ArrayLike, radii_mm: ArrayLike,
                  *, samples: int = 16, through: ArrayLike | None = None,
                  depth_mm: ArrayLike | None = None, camera: Any = None) -> np.ndarray:
    """Hidden fraction (L, N) of each rim at poses T_cam_part (L, 4, 4) (module docstring).

    ``mesh``: trimesh of the part (part frame) for the exact test, or ``DepthMaps`` built at these poses.
    ``camera``: also count the rim's surround off the part (``surround_off``, exact test only; None: the rim
    alone).
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
    if camera is not None and not hasattr(mesh, "hidden"):
        frac = np.maximum(frac, surround_off(mesh, camera, T, c, n, radii_mm, samples=samples))
    return frac


def surround_points(camera: Any, T_cam_part: np.ndarray, centres: np.ndarray, normals: np.ndarray,
                    radii_mm: ArrayLike, samples: int = 16, gap_px: float = SURROUND_GAP_PX) -> np.ndarray:
    """(L, N, K, 3) part-frame points ``gap_px`` image pixels outside each rim sample, in the hole's face plane:
    rim point p + u (gap_px / s), u the outward radial direction and s the image scale (px per mm) of the
    distorted projection along u at p and pose (a forward difference of ``camera.project``, 1 % of the radius)."""
    c = np.asarray(centres, dtype=float)
    r = np.asarray(radii_mm, dtype=float)
    rim = rim_points(c, normals, r, samples)                                   # (N, K, 3)
    u = (rim - c[:, None]) / np.maximum(r, 1e-9)[:, None, None]                # unit radial
    eps = 0.01 * np.maximum(r, 1e-3)[:, None, None]
    T = np.asarray(T_cam_part, dtype=float)

    def image(p: np.ndarray) -> np.ndarray:  # (N, K, 3) part frame → (L, N, K, 2) px
        return camera.project(np.einsum("lij,nkj->lnki", T[:, :3, :3], p) + T[:, None, None, :3, 3])
    scale = np.linalg.norm(image(rim + eps * u) - image(rim), axis=-1) / eps[None, ..., 0]   # (L, N, K) px/mm
    step = gap_px / np.maximum(scale, 1e-9)
    return rim[None] + step[..., None] * u[None]


def surround_off(mesh: Any, camera: Any, T_cam_part: ArrayLike, centres: ArrayLike, normals: ArrayLike,
                 radii_mm: ArrayLike, *, samples: int = 16, gap_px: float = SURROUND_GAP_PX) -> np.ndarray:
    """(L, N) fraction of each rim's surround ring (``surround_points``) off the part's surface (module
    docstring): exact first-hit ray test on ``mesh`` (trimesh, part frame)."""
    T = np.asarray(T_cam_part, dtype=float)
    c = np.asarray(centres, dtype=float)
    n = np.asarray(normals, dtype=float)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    L, N = len(T), len(c)
    pts = surround_points(camera, T, c, n, radii_mm, samples, gap_px)          # (L, N, K, 3)
    off = _off_surface_exact(mesh, invert_T(T)[:, :3, 3], pts.reshape(L, -1, 3))
    return off.reshape(L, N, samples).mean(axis=-1)


def _off_surface_exact(mesh: Any, cams: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(L, M) bool: the first surface hit on the ray from camera centre ``cams`` (L, 3) towards ``points``
    (L, M, 3) (part frame) is not within ``ON_SURFACE_MM`` of the point (or there is none)."""
    L, M = points.shape[:2]
    d = points - cams[:, None]
    dist = np.linalg.norm(d, axis=-1)
    d = d / np.maximum(dist, 1e-12)[..., None]
    origins = np.broadcast_to(cams[:, None], points.shape).reshape(-1, 3)
    loc, index_ray, _ = mesh.ray.intersects_location(origins, d.reshape(-1, 3), multiple_hits=False)
    on = np.zeros(L * M, dtype=bool)
    if len(index_ray):
        travelled = np.linalg.norm(loc - origins[index_ray], axis=-1)
        on[index_ray] = np.abs(travelled - dist.reshape(-1)[index_ray]) <= ON_SURFACE_MM
    return ~on.reshape(L, M)


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
