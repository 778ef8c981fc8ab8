"""Unseen and partly seen holes in the thesis proxies: the rule, and the smooth visibility term (issue 17).

The rule (docs/design.md "Trust rules"), per feature-pose, for each of the FOV cone margin (eq. 3.3), the FOV image
margin (px), the focus margin (eq. 3.6) and the resolution margin (px, §3.3.3) — v the measure's value as if
the hole were seen, f its floor (``unseen_floors``: the value of a feature behind the camera, below any seen
one):

- past the lens's fold radius (``folded``), or facing away from the camera with its centre hidden by the part:
  f;
- facing the camera: ``f + (1 − h)(v − f)``, h in [0, 1] the hidden fraction of the hole's rim
  (``rim_hidden_fraction``). A rim seen whole (h = 0) scores v, bit for bit as without occlusion; a rim
  hidden whole scores f; a partly hidden one scores between, in proportion to the rim seen.

So a hidden hole never scores better than the same hole seen (f ≤ v); a wholly hidden hole scores f whatever its
size and position, so it gains nothing by shrinking, by moving while it stays hidden or by vanishing; and a
partly hidden one gains only by showing more of its rim — the slope that leads an optimiser out from behind
what hides it (the old centre-ray rule was a staircase of constant floors, flat inside each step). A partly
hidden hole whose centre is seen may gain by shrinking when the smaller rim comes wholly into view: that is a hole
coming into view (it then scores as the smaller hole seen), not a hidden one gaining; with its centre hidden,
shrinking only hides more of its rim (behind a convex occluder).

h samples the rim at ``RIM_SAMPLES`` points (``rim_occlusion.rim_points``). With the optimiser's depth maps
(``depth.DepthMaps``) each point's hidden value is bilinear in its image position between the four nearest cells
(``DepthMaps.hidden_fraction``; one compiled pass over the rims, ``DepthMaps.circle_hidden_fraction``), so h is
continuous in the design; with the part's mesh (the reported values) each point is the exact segment test
(``visibility.occluded``'s rule), so h moves in steps of 1/``RIM_SAMPLES``. The hard flags stay for reporting:
``Measures.hidden`` (the centre's ray is blocked) and ``Measures.visible``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cadfeat.camera import Camera
from cadfeat.measures.focus import focus_scale_mm
from cadfeat.measures.fov import behind_px
from cadfeat.measures.rim_occlusion import rim_points
from cadfeat.measures.visibility import RAY_OFFSET_MM

__all__ = ["RIM_SAMPLES", "UNSEEN_KEYS", "apply_unseen", "rim_hidden_fraction", "unseen_floors"]

#: Rim points per hole and pose of the visibility term h.
RIM_SAMPLES = 16
#: The ``Measures`` fields the rule applies to.
UNSEEN_KEYS = ("fov", "fov_px", "focus", "resolution_px")


def unseen_floors(camera: Camera, min_axis_px: float) -> dict[str, float]:
    """The floor f of each measure (module docstring): cone −1 − cos(α/2), image ``behind_px``, focus
    −(near + far)/scale (below any seen hole up to a depth of 2·far + near), resolution −ω − max(W, H) px."""
    near, far = camera.depth_of_field_mm
    return {"fov": -1.0 - float(np.cos(0.5 * camera.fov_rad)), "fov_px": behind_px(camera),
            "focus": -(near + (far if np.isfinite(far) else 0.0)) / focus_scale_mm(camera),
            "resolution_px": -float(min_axis_px) - float(max(camera.width, camera.height))}


def rim_hidden_fraction(occlusion: Any, T_cam_part: np.ndarray, centres: np.ndarray, axes: np.ndarray,
                        radii: np.ndarray, where: np.ndarray, samples: int = RIM_SAMPLES) -> np.ndarray:
    """Hidden fraction h (L, N) of each rim (centres, unit axes (N, 3), radii (N,), part frame, mm) at poses
    T_cam_part (L, 4, 4), computed where ``where`` (L, N) is true (0 elsewhere). ``occlusion``: the part's
    ``DepthMaps`` at these poses (bilinear, continuous) or its trimesh (exact segment tests; module docstring)."""
    L, N = where.shape
    h = np.zeros((L, N))
    if not where.any():
        return h
    pts = rim_points(centres, axes, radii, samples)  # (N, K, 3)
    if hasattr(occlusion, "circle_hidden_fraction"):
        R, t = T_cam_part[:, :3, :3], T_cam_part[:, :3, 3]
        li, nj = np.nonzero(where)
        # rim point k = centre + cos φ_k · r u + sin φ_k · r v (``rim_points``' frame u, v): solve for r u, r v
        # from its first two points
        phi = 2.0 * np.pi * (np.arange(2) + 0.5) / samples
        basis = np.linalg.inv(np.column_stack([np.cos(phi), np.sin(phi)]))
        ru, rv = np.einsum("ij,jnk->ink", basis, pts[:, :2].transpose(1, 0, 2) - centres[None])
        C, U, V = (np.stack([(R[:, k] @ p.T + (t[:, k, None] if p is centres else 0.0))[li, nj] for k in range(3)])
                   for p in (centres, ru, rv))  # camera-frame centres and r u, r v (3, M)
        h[li, nj] = occlusion.circle_hidden_fraction(C, U, V, samples, li)
        return h
    li, nj = np.nonzero(where)
    cams = -np.einsum("lji,lj->li", T_cam_part[:, :3, :3], T_cam_part[:, :3, 3])  # camera centres, part frame
    blocked = _segments_blocked(occlusion, pts[nj].reshape(-1, 3), np.repeat(axes[nj], samples, axis=0),
                                np.repeat(cams[li], samples, axis=0))
    h[li, nj] = blocked.reshape(-1, samples).mean(axis=-1)
    return h


def _segments_blocked(mesh: Any, points: np.ndarray, axes: np.ndarray, cams: np.ndarray) -> np.ndarray:
    """(M,) bool: the segment from each point (M, 3) to its camera centre (M, 3) hits ``mesh`` — the rule of
    ``visibility.occluded`` (rays start slightly off the surface along the axis and the view), pair by pair."""
    to_cam = cams - points
    dist = np.linalg.norm(to_cam, axis=-1)
    direction = to_cam / np.where(dist > 0, dist, 1.0)[:, None]
    offset = RAY_OFFSET_MM + 1e-6 * dist
    origins = points + offset[:, None] * (axes + direction)
    hit = np.zeros(len(points), dtype=bool)
    locations, index_ray, _ = mesh.ray.intersects_location(origins, direction, multiple_hits=True)
    if len(index_ray):
        travelled = np.linalg.norm(locations - origins[index_ray], axis=-1)
        hit[index_ray[travelled < (dist - offset)[index_ray]]] = True
    return hit


def apply_unseen(camera: Camera, out: dict[str, np.ndarray], hidden: np.ndarray, folded: np.ndarray,
                 rim_hidden: np.ndarray, min_axis_px: float) -> None:
    """Apply the rule (module docstring) to the measures ``out`` in place: ``hidden`` (L, N) the centre's ray
    blocked, ``folded`` past the fold radius, ``rim_hidden`` h (L, N); ``out["facing"]`` tells facing away."""
    floors = unseen_floors(camera, min_axis_px)
    hard = folded | (hidden & (out["facing"] <= 0.0))
    part = (rim_hidden > 0.0) & ~hard
    if part.any():
        seen = 1.0 - rim_hidden[part]
        for key in UNSEEN_KEYS:
            v = out[key][part]
            out[key][part] = floors[key] + seen * (v - floors[key])
    if hard.any():
        for key in UNSEEN_KEYS:
            out[key][hard] = floors[key]
