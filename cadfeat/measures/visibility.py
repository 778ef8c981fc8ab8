"""Visibility: the camera on the outward side of a hole's face, and (optionally) no occlusion by the part."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

#: Rays start this far (mm, plus 1e-6 of the distance) in front of the feature to clear its own face.
RAY_OFFSET_MM = 1e-4


def facing_margin(centre_cam: ArrayLike, normal_cam: ArrayLike) -> np.ndarray:
    """cos of the angle between the hole axis (out of the material) and the direction to the camera (...).

    −n·c / (‖n‖ ‖c‖) for centre c and axis n in the camera frame; > 0 when the camera sees the open side,
    1 when it looks straight down the axis. A centre at the camera centre gives −1.
    """
    c = np.asarray(centre_cam, dtype=float)
    n = np.asarray(normal_cam, dtype=float)
    den = np.linalg.norm(c, axis=-1) * np.linalg.norm(n, axis=-1)
    return np.where(den > 0, -np.sum(n * c, axis=-1) / np.where(den > 0, den, 1.0), -1.0)


def occluded(mesh: Any, camera_positions: ArrayLike, centres: ArrayLike, axes: ArrayLike) -> np.ndarray:
    """(L, N) bool: the segment from each feature centre (N, 3) to each camera centre (L, 3) hits ``mesh``.

    All in the part frame, mm. ``mesh`` is a ``trimesh.Trimesh`` (e.g. ``export.mesh_from_shape``); one
    batched ray query (trimesh's intersector: Embree through embreex, a dependency) for all L·N rays. Rays start
    slightly off the feature along its axis so they do not hit the feature's own face.
    """
    cam = np.asarray(camera_positions, dtype=float).reshape(-1, 3)
    c = np.asarray(centres, dtype=float).reshape(-1, 3)
    n = np.asarray(axes, dtype=float).reshape(-1, 3)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    L, N = cam.shape[0], c.shape[0]
    to_cam = cam[:, None, :] - c[None, :, :]
    dist = np.linalg.norm(to_cam, axis=-1)
    direction = to_cam / np.where(dist > 0, dist, 1.0)[..., None]
    offset = RAY_OFFSET_MM + 1e-6 * dist
    origins = c[None] + offset[..., None] * (n[None] + direction)
    hit = np.zeros(L * N, dtype=bool)
    locations, index_ray, _ = mesh.ray.intersects_location(origins.reshape(-1, 3), direction.reshape(-1, 3),
                                                           multiple_hits=True)
    if len(index_ray):
        travelled = np.linalg.norm(locations - origins.reshape(-1, 3)[index_ray], axis=-1)
        before = travelled < (dist.reshape(-1) - offset.reshape(-1))[index_ray]
        hit[index_ray[before]] = True
    return hit.reshape(L, N)
