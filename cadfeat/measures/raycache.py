"""A triangle mesh whose ray queries remember their answers, ray by ray (exact: the same numbers).

``measures.visibility.occluded`` asks ``mesh.ray.intersects_location(origins, directions, multiple_hits=True)``
for all L·N rays from the holes to the camera positions. When a slider moves one hole, the rays of every other
hole are the same floats as before; ``CachedRayMesh`` answers those from a dictionary keyed by the ray's exact
bytes and sends only the new rays to trimesh. Each ray's hits do not depend on the other rays of the batch, so
the result is identical to the uncached query (``tests/explore/test_explore.py`` checks it).

``cache_rays(mesh)`` gives a ``trimesh.Trimesh`` itself such a cache (its ``mesh.ray``), so every exact ray test of a
study run that repeats a ray (the original's rims in the measures, the score and the pose prediction) traces it
once; the mesh stays a ``Trimesh`` for everything else (depth maps, points, the pre-flight).
"""

from __future__ import annotations

from collections import OrderedDict
from types import SimpleNamespace
from typing import Any

import numpy as np

__all__ = ["CachedRayMesh", "cache_rays"]


class CachedRayMesh:
    """Wraps a ``trimesh.Trimesh``: ``.ray.intersects_location`` with a per-ray cache of at most ``max_rays``."""

    def __init__(self, mesh: Any, max_rays: int = 200_000) -> None:
        self.mesh = mesh
        self.max_rays = max_rays
        self._cache: OrderedDict[bytes, tuple[np.ndarray, np.ndarray]] = OrderedDict()
        self.hits = self.misses = 0

    @property
    def ray(self) -> CachedRayMesh:
        return self

    def __getattr__(self, name: str) -> Any:
        """The wrapped intersector's other queries (``intersects_any``, ``contains_points``, ...), uncached."""
        if name.startswith("__") or name in ("mesh", "max_rays", "_cache", "hits", "misses"):
            raise AttributeError(name)
        return getattr(self.mesh.ray, name)

    def intersects_location(self, origins: np.ndarray, directions: np.ndarray,
                            multiple_hits: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(locations (H, 3), index_ray (H,), index_tri (H,)) as ``trimesh``'s ray intersector returns them."""
        origins = np.ascontiguousarray(origins, float).reshape(-1, 3)
        directions = np.ascontiguousarray(directions, float).reshape(-1, 3)
        keys = [o.tobytes() + d.tobytes() + bytes([multiple_hits]) for o, d in zip(origins, directions, strict=True)]
        todo = [i for i, k in enumerate(keys) if k not in self._cache]
        self.hits += len(keys) - len(todo)
        self.misses += len(todo)
        if todo:
            loc, idx, tri = self.mesh.ray.intersects_location(origins[todo], directions[todo],
                                                              multiple_hits=multiple_hits)
            idx = np.asarray(idx, int)
            for j, i in enumerate(todo):
                sel = idx == j
                self._cache[keys[i]] = (np.asarray(loc, float)[sel].reshape(-1, 3), np.asarray(tri, int)[sel])
        parts = [self._cache[k] for k in keys]
        while len(self._cache) > self.max_rays:  # (after reading this batch's answers)
            self._cache.popitem(last=False)
        counts = [len(p[1]) for p in parts]
        if not sum(counts):
            return np.zeros((0, 3)), np.zeros(0, int), np.zeros(0, int)
        locations = np.concatenate([p[0] for p in parts])
        index_ray = np.repeat(np.arange(len(keys)), counts)
        index_tri = np.concatenate([p[1] for p in parts])
        return locations, index_ray, index_tri


def cache_rays(mesh: Any, max_rays: int = 200_000) -> Any:
    """``mesh`` (a ``trimesh.Trimesh``, or None) with its ray intersector ``mesh.ray`` wrapped in a
    ``CachedRayMesh`` (module docstring); the same object, returned for chaining. Calling it again keeps the cache."""
    if mesh is not None and not isinstance(getattr(mesh, "ray", None), CachedRayMesh):
        mesh.ray = CachedRayMesh(SimpleNamespace(ray=mesh.ray), max_rays)
    return mesh
