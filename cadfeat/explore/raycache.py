"""The explorer's exact per-ray occlusion cache: ``cadfeat.measures.raycache`` (shared with the study run)."""

from __future__ import annotations

from cadfeat.measures.raycache import CachedRayMesh, cache_rays

__all__ = ["CachedRayMesh", "cache_rays"]
