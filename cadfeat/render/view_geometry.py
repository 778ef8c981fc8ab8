"""View geometry and label placement of the part pictures, without VTK (numpy; trimesh rays for occlusion).

The directions a picture is seen from (``default_view_direction``, ``closeup_view_direction``), camera frusta as
line segments, hole rings and which holes moved, and the greedy placement of hole labels in image space
(``place_labels``). ``cadfeat.render.part_views`` draws with these in PyVista.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.cad.features import holes_to_arrays
from cadfeat.cad.features.identity import hole_name as identity_name
from cadfeat.poses import invert_T
from cadfeat.render.scene import RenderError

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

    from cadfeat.cad.features import Hole
    from cadfeat.camera import Camera
    from cadfeat.trajectory import Trajectory

#: Centre or radius changes (mm) above this count as a move.
MOVE_TOL_MM = 1e-6


DEFAULT_VIEW = (1.0, -1.3, 1.1)     # from front-right-above, when nothing better is known


def _unit(v: Sequence[float], what: str) -> np.ndarray:
    v = np.asarray(v, dtype=float).reshape(-1)
    n = float(np.linalg.norm(v)) if v.shape == (3,) else 0.0
    if not np.isfinite(n) or n == 0.0:
        raise RenderError(f"{what} must be a non-zero 3-vector (x, y, z), got {v.tolist()}")
    return v / n


def default_view_direction(holes: Sequence[Hole], towards: Sequence[float] | None = None) -> np.ndarray:
    """Direction (part frame, unit) from the part towards the viewer: ``towards`` (e.g. a part script's
    VIEW_DIRECTION) or else the mean hole axis, tilted towards ``DEFAULT_VIEW`` so the part shows depth;
    ``DEFAULT_VIEW`` when neither is known."""
    iso = _unit(DEFAULT_VIEW, "DEFAULT_VIEW")
    base = np.mean([h.axis for h in holes], axis=0) if towards is None and holes else towards
    if base is None or np.linalg.norm(base) < 1e-6:
        return iso
    base = _unit(base, "view direction")
    d = base + 0.6 * (iso - np.dot(iso, base) * base)
    if np.linalg.norm(d - base) < 1e-6:  # base along DEFAULT_VIEW: tilt sideways
        d = base + 0.6 * _perpendicular(base)
    return _unit(d, "view direction")


def _view_up(direction: np.ndarray) -> tuple[float, float, float]:
    return (0.0, 1.0, 0.0) if abs(direction[2]) > 0.95 else (0.0, 0.0, 1.0)


def _hole_name(hole: Hole, index: int) -> str:
    return identity_name(hole, index)


def _label_anchor(holes: Sequence[Hole], mesh: trimesh.Trimesh) -> np.ndarray:
    """Where a hole's label sits: beside its rim, a little out of the face (mm)."""
    if not holes:
        return np.zeros((0, 3))
    scale = 0.02 * float(np.linalg.norm(np.ptp(np.asarray(mesh.points), axis=0)))
    return np.array([h.centre + h.axis * scale + _perpendicular(h.axis) * (1.6 * h.radius_mm + scale)
                     for h in holes])


def _perpendicular(axis: np.ndarray) -> np.ndarray:
    other = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    p = np.cross(axis, other)
    return p / np.linalg.norm(p)


def _trajectory_in_part(trajectory: Trajectory | None, T_task_part: np.ndarray | None) -> np.ndarray | None:
    """Camera poses T_part_cam (L, 4, 4) from a ``Trajectory`` or an (L, 4, 4) array of T_task_cam."""
    if trajectory is None:
        return None
    T = np.asarray(getattr(trajectory, "T_task_cam", trajectory), dtype=float)
    if T.ndim != 3 or T.shape[1:] != (4, 4) or len(T) == 0:
        raise RenderError(f"trajectory must be a Trajectory or (L, 4, 4) poses, got shape {T.shape}")
    if T_task_part is not None:
        T = invert_T(np.asarray(T_task_part, dtype=float))[None] @ T
    return T


def frustum_lines(camera: Camera | None, T_part_cam: np.ndarray, depth_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Camera frusta as line segments: points (K·5, 3) and VTK line cells, for poses (K, 4, 4).

    The apex is the camera centre, the base the image rectangle at depth ``depth_mm`` (rays
    ``K⁻¹ [u, v, 1]`` through the image corners; a 60° square pyramid without a camera).
    """
    if camera is None:
        h = np.tan(np.pi / 6)
        corners = np.array([[-h, -h, 1.0], [h, -h, 1.0], [h, h, 1.0], [-h, h, 1.0]])
    else:
        w, h = camera.width, camera.height
        uv1 = np.array([[0, 0, 1], [w, 0, 1], [w, h, 1], [0, h, 1]], dtype=float)
        corners = uv1 @ np.linalg.inv(camera.K).T
    local = np.vstack([np.zeros(3), corners * depth_mm])                  # (5, 3) camera frame
    pts = np.einsum("kij,mj->kmi", T_part_cam[:, :3, :3], local) + T_part_cam[:, None, :3, 3]
    seg = np.array([[0, 1], [0, 2], [0, 3], [0, 4], [1, 2], [2, 3], [3, 4], [4, 1]])
    offsets = (np.arange(len(T_part_cam)) * 5)[:, None, None]
    cells = np.concatenate([np.full((len(T_part_cam), len(seg), 1), 2), seg[None] + offsets], axis=-1)
    return pts.reshape(-1, 3), cells.ravel()


def _moved_mask(before: Sequence[Hole], after: Sequence[Hole]) -> np.ndarray:
    c0, _, r0 = holes_to_arrays(before)
    c1, _, r1 = holes_to_arrays(after)
    return (np.linalg.norm(c1 - c0, axis=-1) > MOVE_TOL_MM) | (np.abs(r1 - r0) > MOVE_TOL_MM)


def _ring(centre: np.ndarray, axis: np.ndarray, radius: float, n: int = 96) -> np.ndarray:
    u = _perpendicular(axis)
    w = np.cross(axis, u)
    phi = np.linspace(0.0, 2.0 * np.pi, n + 1)
    return centre + radius * (np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * w)


def _side_view(direction: np.ndarray, centre: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Tilt ``direction`` half-way towards the normal of the plane through the part centre and the camera
    path, so the path is seen beside the part rather than across it."""
    pts = np.vstack([centre, path]) - np.mean(np.vstack([centre, path]), axis=0)
    normal = np.linalg.svd(pts, full_matrices=False)[2][-1]
    if np.linalg.matrix_rank(pts, tol=1e-6 * (1.0 + np.abs(pts).max())) < 2:
        return direction  # path and centre on one line: no plane
    normal = normal if np.dot(normal, direction) >= 0 else -normal
    return _unit(direction + normal, "view direction")


#: A rim seen at less than this cosine between its axis and the view direction counts as hidden.
MIN_RIM_COSINE = 0.3


def closeup_view_direction(mesh: trimesh.Trimesh, holes: Sequence[Hole], weights: np.ndarray | None = None,
                           n_candidates: int = 160) -> tuple[np.ndarray, np.ndarray]:
    """Viewing direction (part frame, unit, towards the viewer) that shows the most hole rims: among
    ``default_view_direction(holes)`` and ``n_candidates`` directions spread over the sphere (Fibonacci), the
    one maximising the ``weights`` (N,) of rims that face it (axis·d ≥ ``MIN_RIM_COSINE``) and are not
    occluded (a ray from the rim centre along d misses the mesh; trimesh, batched), ties broken towards the
    default view. A flat plate keeps its default (tilted) view; an L-bracket gets one showing both flanges.
    Returns the direction and which holes are seen from it (N,) bool."""
    import trimesh

    target = default_view_direction(holes)
    if not holes:
        return target, np.zeros(0, dtype=bool)

    k = np.arange(n_candidates) + 0.5
    z = 1.0 - 2.0 * k / n_candidates
    phi = np.pi * (1.0 + 5.0**0.5) * k
    cand = np.vstack([target, np.c_[np.sqrt(1 - z**2) * np.cos(phi), np.sqrt(1 - z**2) * np.sin(phi), z]])
    centres, axes, _ = holes_to_arrays(holes)
    through = np.array([h.through for h in holes])
    depth = np.array([h.depth_mm for h in holes])
    w = np.ones(len(holes)) if weights is None else np.asarray(weights, dtype=float)
    cosine = axes @ cand.T                                                    # (N, D)
    seen = np.where(through[:, None], np.abs(cosine), cosine)                 # a through hole shows both rims
    facing = seen >= MIN_RIM_COSINE
    faces = np.asarray(mesh.faces).reshape(-1, 4)[:, 1:]
    tri = trimesh.Trimesh(np.asarray(mesh.points), faces, process=False)
    lift = 1e-3 * float(np.linalg.norm(np.ptp(np.asarray(mesh.points), axis=0)))
    n, d = np.nonzero(facing)
    free = np.zeros_like(facing)
    if len(n):
        front = cosine[n, d] >= 0
        origin = np.where(front[:, None], centres[n] + axes[n] * lift, centres[n] - axes[n] * (depth[n, None] + lift))
        free[n, d] = ~tri.ray.intersects_any(origin, cand[d])
    score = w @ free + 0.5 * (cand @ target) + (w @ (free * seen)) / w.sum()
    best = int(np.argmax(score))
    return cand[best], free[:, best]


def _visible_from(mesh: trimesh.Trimesh, holes: Sequence[Hole], eye: np.ndarray) -> np.ndarray:
    """Which rims (N,) bool face the eye point (mm, part frame) and see it unobstructed (trimesh rays)."""
    import trimesh

    if not holes:
        return np.zeros(0, dtype=bool)

    centres, axes, _ = holes_to_arrays(holes)
    lift = 1e-3 * float(np.linalg.norm(np.ptp(np.asarray(mesh.points), axis=0)))
    origin = centres + axes * lift
    rays = eye - origin
    tri = trimesh.Trimesh(np.asarray(mesh.points), np.asarray(mesh.faces).reshape(-1, 4)[:, 1:], process=False)
    return (np.einsum("ij,ij->i", rays, axes) > 0) & ~tri.ray.intersects_any(origin, rays)


def _facing_side(holes: Sequence[Hole], direction: np.ndarray) -> list[Hole]:
    """The holes as seen along ``-direction``: a through hole whose entrance faces away is described by its
    exit rim (centre moved down the bore by depth_mm, axis reversed, bore radius), so highlights, rings,
    arrows and labels land on the visible side."""
    out = []
    for h in holes:
        if h.through and float(np.dot(h.axis, direction)) < 0.0:
            h = dataclasses.replace(h, centre=h.centre - h.axis * h.depth_mm, axis=-h.axis, radius_mm=h.bore_radius_mm,
                                    kind="plain", outline=None)
        out.append(h)
    return out


def _boxes_overlap(box: np.ndarray, boxes: np.ndarray) -> float:
    """Summed overlap area (px²) of ``box`` (4,) [x0, y0, x1, y1] with ``boxes`` (K, 4)."""
    if len(boxes) == 0:
        return 0.0
    w = np.clip(np.minimum(box[2], boxes[:, 2]) - np.maximum(box[0], boxes[:, 0]), 0.0, None)
    h = np.clip(np.minimum(box[3], boxes[:, 3]) - np.maximum(box[1], boxes[:, 1]), 0.0, None)
    return float((w * h).sum())


def place_labels(anchors: np.ndarray, radii: np.ndarray, sizes: np.ndarray, obstacles: np.ndarray,
                 image_size: tuple[int, int], gap: float = 4.0) -> np.ndarray:
    """Lower-left corners (N, 2) of label boxes ``sizes`` (N, 2) px beside circles (``anchors`` (N, 2),
    ``radii`` (N,) px), greedily: each label takes the first of 8 directions × 4 distances with the least
    overlap with the labels placed so far (×4), the ``obstacles`` (K, 4) boxes and the image border (×8)."""
    width, height = image_size
    angles = np.radians([45, 135, -45, -135, 0, 180, 90, -90])
    dirs = np.c_[np.cos(angles), np.sin(angles)]
    placed: list[np.ndarray] = []
    out = np.zeros((len(anchors), 2))
    for i in np.argsort(-anchors[:, 1], kind="stable"):  # top to bottom
        w, h = sizes[i]
        best, best_cost = None, np.inf
        for k in range(4):
            for d in dirs:
                centre = anchors[i] + d * (radii[i] + gap + k * h) + d * np.array([w, h]) * 0.5
                box = np.r_[centre - 0.5 * np.array([w, h]), centre + 0.5 * np.array([w, h])]
                inside = (min(box[2], width) - max(box[0], 0.0)) * (min(box[3], height) - max(box[1], 0.0))
                cost = (4.0 * _boxes_overlap(box, np.array(placed).reshape(-1, 4))
                        + _boxes_overlap(box, obstacles) + 8.0 * (w * h - max(inside, 0.0)) + 0.01 * k)
                if cost < best_cost - 1e-9:
                    best, best_cost = box, cost
            if best_cost < 1.0:
                break
        placed.append(best)
        out[i] = best[:2]
    return out
