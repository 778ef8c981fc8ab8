"""What the camera cannot see of a hole: the hidden fraction h of its rim (issue 17).

h (``rim_hidden_fraction``, ``Measures.rim_hidden``) is a measurement beside the thesis's measures, as are
``Measures.hidden`` (the centre's ray is blocked) and ``Measures.folded`` (past the lens's fold radius): the
measures themselves stay the thesis's equations (issue 32 item 7), and the objectives score unseen holes with the
rule of ``cadfeat.design.unseen`` (a hole facing the camera scores f + (1 − h)(v − f) in FOV, focus and resolution,
f each measure's floor; docs/design.md "Trust rules"). ``evaluate`` also weights each hole's Jacobian rows by its
seen fraction 1 − h (``Measures.seen``, g_DIR), and ``pose_information`` gives a hidden rim no information (g_POSE).

h samples the rim at ``RIM_SAMPLES`` points (``rim_occlusion.rim_points``). With the optimiser's depth maps
(``depth.DepthMaps``) each point's hidden value is bilinear in its image position between the four nearest cells
(``DepthMaps.hidden_fraction``; one compiled pass over the rims, ``DepthMaps.circle_hidden_fraction``), so h is
continuous in the design — a slope out of hiding for the optimiser, where the centre-ray test is a step; with the
part's mesh (the reported values) each point is the exact segment test (``visibility.occluded``'s rule), so h moves
in steps of 1/``RIM_SAMPLES``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cadfeat.measures.rim_occlusion import rim_points
from cadfeat.measures.visibility import RAY_OFFSET_MM

__all__ = ["RIM_SAMPLES", "rim_hidden_fraction"]

#: Rim points per hole and pose of the visibility term h.
RIM_SAMPLES = 16


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
