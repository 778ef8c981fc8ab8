"""g_POSE of a design with added target holes, batched over candidate designs (issue 31).

The part's holes (N0, fixed during the choice: the original or the move-only optimum) and k added holes are one
hole set; its g_POSE is the study's: ``measures.pose_information`` with the study's cell (detection and
measurement models, sensor noise), each rim's hidden fraction from the exact ray test against the part's mesh,
aggregated over the trajectory by ``design.pose_terms.pose_aggregate_batch`` (rms: minus the RMS over the poses of
√(e_t² + (ℓ e_r)²), mm) — the same numbers as ``study.pose_accuracy.predict`` (tested).

B designs are evaluated in ONE ``pose_information`` call on the B·L stacked poses, each pose with its design's
N0 + k holes (``pose_information`` accepts one hole set per pose); the candidate sites' rim occlusion (L, M) is
computed once (a site's hidden fraction depends on the site alone, against the part's mesh before drilling).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.camera import Camera

__all__ = ["CHUNK", "PoseScene", "TargetObjective"]

CHUNK = 48
"""Designs per ``pose_information`` call (memory: CHUNK·L·N·(2·6 + 36) floats)."""


@dataclass(frozen=True)
class PoseScene:
    """What the prediction needs besides the holes: the camera, the poses T_cam_part (L, 4, 4) mm, the
    rotation length ℓ (mm), the aggregate ("rms", "worst", "logdet"), the cell's models and grey-level noise, and
    g_POSE's glare maps with the cell (``design.pose_terms.designs_glare_rate``)."""

    camera: Camera
    T_cam_part: np.ndarray
    rotation_length_mm: float
    aggregate: str
    models: Any
    noise_grey: float
    glare: Any = None   # g_POSE's glare maps at these poses (measures.glare), None: none
    cell: Any = None    # the cell (its material decides whether the glare counts)


class TargetObjective:
    """g_POSE (larger is better: minus the predicted error, mm) of the part's holes plus added holes.

    ``base``: the part's holes' (centres (N0, 3), axes (N0, 3), rim radii (N0,), through (N0,), depth (N0,) mm),
    ``base_kinds`` their kinds, ``base_occlusion`` (L, N0) their rims' hidden fractions; an added hole has rim
    radius ``rim_radius_mm``, depth ``depth_mm``, kind ``kind``. ``site_centres``/``site_axes`` (M, 3) and
    ``site_occlusion`` (L, M): the candidate sites, for ``of_sets``."""

    def __init__(self, scene: PoseScene, base: Sequence[np.ndarray], base_kinds: Sequence[str],
                 base_occlusion: np.ndarray, rim_radius_mm: float, depth_mm: float, kind: str,
                 site_centres: np.ndarray, site_axes: np.ndarray, site_occlusion: np.ndarray) -> None:
        self.scene = scene
        self.base = tuple(np.asarray(a) for a in base)
        self.base_kinds = list(base_kinds)
        self.base_occlusion = np.asarray(base_occlusion, float)
        self.rim_radius_mm, self.depth_mm, self.kind = float(rim_radius_mm), float(depth_mm), kind
        self.site_centres = np.asarray(site_centres, float)
        self.site_axes = np.asarray(site_axes, float)
        self.site_occlusion = np.asarray(site_occlusion, float)
        self.evaluations = 0

    def of_sets(self, sets: np.ndarray) -> np.ndarray:
        """g_POSE (B,) of B designs, each the part's holes plus the sites ``sets`` (B, k) (k may be 0)."""
        sets = np.asarray(sets, int).reshape(len(sets), -1)
        return self.at(self.site_centres[sets], self.site_axes[sets],
                       np.moveaxis(self.site_occlusion[:, sets], 0, 1))

    def at(self, centres: np.ndarray, axes: np.ndarray, occlusion: np.ndarray,
           base: Sequence[np.ndarray] | None = None) -> np.ndarray:
        """g_POSE (B,) of B designs whose added holes are at ``centres``, ``axes`` (B, k, 3) with hidden fractions
        ``occlusion`` (B, L, k); ``base``: the part's holes per design (centres (B, N0, 3), axes (B, N0, 3), rim
        radii (B, N0), hidden fractions (B, L, N0)) when they move too (default: ``self.base``, as built);
        evaluated ``CHUNK`` designs per call."""
        B = len(centres)
        out = np.empty(B)
        for s in range(0, B, CHUNK):
            e = slice(s, min(B, s + CHUNK))
            part = None if base is None else tuple(np.asarray(b)[e] for b in base)
            out[e] = self._chunk(centres[e], axes[e], occlusion[e], part)
        self.evaluations += B
        return out

    def _base(self, B: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The part's holes as built, for B designs: centres, axes, radii, hidden fractions."""
        c0, a0, r0 = self.base[:3]
        L = len(self.scene.T_cam_part)
        return (np.broadcast_to(c0, (B,) + c0.shape), np.broadcast_to(a0, (B,) + a0.shape),
                np.broadcast_to(r0, (B,) + r0.shape), np.broadcast_to(self.base_occlusion, (B, L, len(c0))))

    def errors(self, centres: np.ndarray, axes: np.ndarray, occlusion: np.ndarray,
               base: Sequence[np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(per-pose error (B, L) mm, information (B, L, 6, 6)) of B designs (arguments as ``at``)."""
        from cadfeat.measures import pose_information  # lazy: would import scipy.spatial at module load

        through0, depth0 = self.base[3], self.base[4]
        B, k = centres.shape[:2]
        c0, a0, r0, occ0 = self._base(B) if base is None else base
        L = len(self.scene.T_cam_part)
        N = c0.shape[1] + k
        c = np.concatenate([c0, centres], axis=1)
        a = np.concatenate([a0, axes], axis=1)
        r = np.concatenate([r0, np.full((B, k), self.rim_radius_mm)], axis=1)
        depth = np.concatenate([depth0, np.full(k, self.depth_mm)])
        occ = np.concatenate([occ0, occlusion], axis=2)
        sc = self.scene
        through = np.concatenate([through0, np.zeros(k, bool)])
        rate = None
        if sc.glare is not None and sc.cell is not None:
            from cadfeat.design.pose_terms import designs_glare_rate

            rate = designs_glare_rate(sc.glare, sc.cell, sc.T_cam_part, c, a, r, through, sc.noise_grey)
        info = pose_information(sc.camera, np.tile(sc.T_cam_part, (B, 1, 1)), np.repeat(c, L, axis=0),
                                np.repeat(a, L, axis=0), np.repeat(r, L, axis=0),
                                occlusion=occ.reshape(B * L, N), through=through, contrast_rate=rate,
                                kinds=self.base_kinds + [self.kind] * k,
                                depth_ratio=np.repeat(depth / (2.0 * np.maximum(r, 1e-9)), L, axis=0),
                                rotation_length_mm=sc.rotation_length_mm, model=sc.models, noise_grey=sc.noise_grey)
        return info.error_mm(sc.rotation_length_mm).reshape(B, L), info.information.reshape(B, L, 6, 6)

    def _chunk(self, centres: np.ndarray, axes: np.ndarray, occlusion: np.ndarray,
               base: Sequence[np.ndarray] | None) -> np.ndarray:
        from cadfeat.design.pose_terms import pose_aggregate_batch

        errors, information = self.errors(centres, axes, occlusion, base)
        return pose_aggregate_batch(errors, information, self.scene.aggregate, self.scene.rotation_length_mm)
