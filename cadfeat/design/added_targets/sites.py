"""Candidate drill sites for added target holes: a grid on each allowed planar face, kept where every kept
requirement holds (issue 31).

A site is the rim centre of a new blind hole of rim radius ``R`` (drill radius + chamfer) on a face. Its margin
(mm, ≥ 0 feasible) is the least of the 2-D forms of ``design.constraints`` measured in the face's own frame:

- ``edge``:     signed distance(centre, face outer polygon) − R − edge_distance_mm (inside positive);
- ``keepout``:  distance(centre, each keep-out polygon of the face: slots, pockets) − R − keepout_mm;
- ``ligament``: ‖c − c_h‖ − R − r_h − ligament_mm to every hole h of the part on that face (and, in the
  greedy choice, to every hole already added: ``conflicts``);
- ``box``:      distance(centre, each keep-out box of the study, 3-D) − R − ligament_mm;
- ``keepin``:   with keep-in boxes, how far the whole rim lies inside the best of them: per box
  min_i(min(p_i − lo_i, hi_i − p_i) − R √(1 − n_i²)) (a circle of radius R in a plane of normal n reaches
  R √(1 − n_i²) along axis i), the largest over the boxes.

All functions are batched over sites (no Python loop over sites). Units: mm, part frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from cadfeat.cad.features import FaceOutline
from cadfeat.design.constraints import _pad_polygons, point_polygon_distance  # pyright: ignore[reportPrivateUsage]

__all__ = ["FaceRules", "Sites", "box_distance", "conflicts", "face_grid", "keepin_margin", "site_margins",
           "sites_on_faces"]


@dataclass(frozen=True)
class FaceRules:
    """What a site on one face must keep (mm): the face outline, the part's holes on it (rim centres (H, 3),
    rim radii (H,)), the study's keep-out boxes (K, 6) [xmin, ymin, zmin, xmax, ymax, zmax], the added hole's rim
    radius and the requirements of ``[constraints]``."""

    outline: FaceOutline
    hole_centres: np.ndarray
    hole_radii: np.ndarray
    boxes: np.ndarray
    rim_radius_mm: float
    edge_distance_mm: float
    ligament_mm: float
    keepout_mm: float
    keepin: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    """(B, 6) keep-in boxes [xmin, ymin, zmin, xmax, ymax, zmax] mm: the rim must lie inside one (none: anywhere)."""


@dataclass(frozen=True)
class Sites:
    """M candidate sites: rim centres (M, 3) mm, axes out of the material (M, 3), the index of each site's face
    in the allowed-face list (M,), face coordinates (M, 2) mm and margins (M,) mm (all ≥ 0)."""

    centres: np.ndarray
    axes: np.ndarray
    face: np.ndarray
    uv: np.ndarray
    margin: np.ndarray

    def __len__(self) -> int:
        return len(self.centres)

    def take(self, idx: np.ndarray) -> Sites:
        """The sites ``idx`` (a subset, e.g. a coarser grid for the exhaustive check)."""
        return Sites(self.centres[idx], self.axes[idx], self.face[idx], self.uv[idx], self.margin[idx])


def face_grid(outline: FaceOutline, pitch_mm: float) -> np.ndarray:
    """(G, 2) face coordinates (mm) of a square grid of ``pitch_mm`` over the face's bounding box, centred on it
    (so a symmetric face gets a symmetric grid)."""
    lo, hi = outline.outer.min(axis=0), outline.outer.max(axis=0)
    mid: np.ndarray = 0.5 * (lo + hi)
    n: np.ndarray = np.floor(0.5 * (hi - lo) / pitch_mm).astype(int)
    s: np.ndarray = mid[0] + pitch_mm * np.arange(-int(n[0]), int(n[0]) + 1)
    t: np.ndarray = mid[1] + pitch_mm * np.arange(-int(n[1]), int(n[1]) + 1)
    S, T = np.meshgrid(s, t, indexing="ij")
    return np.stack([S.ravel(), T.ravel()], axis=-1)


def box_distance(points: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Euclidean distance (..., K) mm from points (..., 3) to axis-aligned boxes (K, 6) (0 inside)."""
    p = np.asarray(points, float)[..., None, :]
    lo, hi = boxes[:, :3], boxes[:, 3:]
    gap = np.maximum(np.maximum(lo - p, p - hi), 0.0)
    return np.linalg.norm(gap, axis=-1)


def keepin_margin(points: np.ndarray, normal: np.ndarray, radius_mm: float, boxes: np.ndarray) -> np.ndarray:
    """(...,) mm: how far a rim circle (centre ``points`` (..., 3), plane normal ``normal`` (3,), radius
    ``radius_mm``) lies inside the best of the axis-aligned ``boxes`` (B, 6) — ≥ 0 inside one, negative outside
    all (module docstring)."""
    p = np.asarray(points, float)[..., None, :]
    reach = radius_mm * np.sqrt(np.clip(1.0 - np.square(np.asarray(normal, float)), 0.0, 1.0))
    inside = np.minimum(p - boxes[:, :3], boxes[:, 3:] - p) - reach
    return np.max(np.min(inside, axis=-1), axis=-1)


def site_margins(uv: np.ndarray, rules: FaceRules) -> dict[str, np.ndarray]:
    """Each requirement's least margin (...,) mm at face coordinates ``uv`` (..., 2) (module docstring);
    a requirement with nothing to keep apart from gives +inf."""
    uv = np.asarray(uv, float)
    o, R = rules.outline, rules.rim_radius_mm
    inf = np.full(uv.shape[:-1], np.inf)
    a, b, valid = _pad_polygons([o.outer])
    d, inside = point_polygon_distance(uv[..., None, :], a, b, valid)
    out = {"edge": (np.where(inside, d, -d) - R - rules.edge_distance_mm)[..., 0]}
    if o.keepouts:
        a, b, valid = _pad_polygons(list(o.keepouts))
        k = len(o.keepouts)
        d, inside = point_polygon_distance(np.broadcast_to(uv[..., None, :], uv.shape[:-1] + (k, 2)), a, b, valid)
        out["keepout"] = np.min(np.where(inside, -d, d), axis=-1) - R - rules.keepout_mm
    else:
        out["keepout"] = inf
    if len(rules.hole_radii):
        c = o.to_face(rules.hole_centres)
        gap = np.linalg.norm(uv[..., None, :] - c, axis=-1) - rules.hole_radii
        out["ligament"] = np.min(gap, axis=-1) - R - rules.ligament_mm
    else:
        out["ligament"] = inf
    if len(rules.boxes):
        out["box"] = np.min(box_distance(o.to_3d(uv), rules.boxes), axis=-1) - R - rules.ligament_mm
    else:
        out["box"] = inf
    out["keepin"] = keepin_margin(o.to_3d(uv), o.normal, R, rules.keepin) if len(rules.keepin) else inf
    return out


def sites_on_faces(rules: Sequence[FaceRules], pitch_mm: float) -> Sites:
    """The feasible grid sites (every margin ≥ 0) of each face of ``rules`` (``face_grid`` of ``pitch_mm``)."""
    parts: list[tuple[np.ndarray, ...]] = []
    for f, r in enumerate(rules):
        uv = face_grid(r.outline, pitch_mm)
        m = np.min(np.stack(list(site_margins(uv, r).values())), axis=0)
        keep = m >= 0
        uv = uv[keep]
        parts.append((r.outline.to_3d(uv), np.broadcast_to(r.outline.normal, (len(uv), 3)),
                      np.full(len(uv), f), uv, m[keep]))
    if not parts:
        return Sites(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, int), np.zeros((0, 2)), np.zeros(0))
    return Sites(*(np.concatenate([p[i] for p in parts]) for i in range(5)))


def conflicts(sites: Sites, rim_radius_mm: float, ligament_mm: float) -> np.ndarray:
    """(M, M) bool: two sites that cannot both be drilled — on the same face and closer than two rims plus the
    ligament (a site conflicts with itself)."""
    d = np.linalg.norm(sites.centres[:, None] - sites.centres[None], axis=-1)
    same = sites.face[:, None] == sites.face[None]
    return same & (d < 2.0 * rim_radius_mm + ligament_mm)
