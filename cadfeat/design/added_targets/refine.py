"""Continuous refinement of the added holes' positions after the greedy choice (issue 31).

The greedy choice puts holes on the grid of candidate sites; a compass search then moves them in their faces'
planes: at each iteration every added hole is tried ``step`` mm along ± each face axis (4k trial designs,
evaluated in ONE batched prediction, their rims' hidden fractions from one exact ray test), the best feasible
improving move is taken, and the step halves when none improves, down to ``min_step_mm``. A move is feasible
when every requirement of ``sites.site_margins`` holds at the new place and the hole keeps the ligament to the
other added holes on its face.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from cadfeat.design.added_targets.objective import TargetObjective
from cadfeat.design.added_targets.sites import FaceRules, site_margins

__all__ = ["Refined", "refine"]

Hidden = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""Rim hidden fraction (L, n) of n holes at centres (n, 3), axes (n, 3) (the exact ray test on the part)."""

_DIRECTIONS = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])


@dataclass
class Refined:
    """The refined face coordinates (k, 2) mm, rim centres (k, 3) mm, hidden fractions (L, k), g_POSE before
    and after, the moves taken and the designs evaluated."""

    uv: np.ndarray
    centres: np.ndarray
    occlusion: np.ndarray
    value_before: float
    value: float
    moves: int
    evaluations: int


def _feasible(uv: np.ndarray, hole: int, faces: np.ndarray, rules: Sequence[FaceRules], all_uv: np.ndarray,
              rim_radius_mm: float) -> np.ndarray:
    """(T,) bool: trial places ``uv`` (T, 2) of added hole ``hole`` keep every requirement of its face and the
    ligament to the other added holes on that face (their places ``all_uv`` (k, 2))."""
    r = rules[int(faces[hole])]
    ok = np.min(np.stack(list(site_margins(uv, r).values())), axis=0) >= 0
    others = [j for j in range(len(faces)) if j != hole and faces[j] == faces[hole]]
    if others:
        gap = np.linalg.norm(uv[:, None] - all_uv[others][None], axis=-1).min(axis=1)
        ok &= gap >= 2 * rim_radius_mm + r.ligament_mm
    return ok


def refine(objective: TargetObjective, rules: Sequence[FaceRules], faces: Sequence[int], uv0: np.ndarray,
           hidden: Hidden, step_mm: float, min_step_mm: float = 0.25, max_iterations: int = 40) -> Refined:
    """Compass search of the added holes' face coordinates ``uv0`` (k, 2) on their faces (``faces`` (k,) indices
    into ``rules``), from ``step_mm`` down to ``min_step_mm`` (module docstring)."""
    faces_a = np.asarray(faces, int)
    outlines = [rules[f].outline for f in faces_a]
    uv = np.asarray(uv0, float).copy()
    k = len(uv)
    axes = np.stack([o.normal for o in outlines])
    centres = np.stack([o.to_3d(p) for o, p in zip(outlines, uv, strict=True)])
    occ = hidden(centres, axes)
    g0 = g = float(objective.at(centres[None], axes[None], occ[None])[0])
    evaluations, moves, step = 1, 0, float(step_mm)
    for _ in range(max_iterations):
        if step < min_step_mm or k == 0:
            break
        trial = uv[:, None] + step * _DIRECTIONS[None]                          # (k, 4, 2)
        ok = np.stack([_feasible(trial[i], i, faces_a, rules, uv, objective.rim_radius_mm) for i in range(k)])
        who, way = np.nonzero(ok)
        if not who.size:
            step /= 2
            continue
        moved = np.stack([outlines[i].to_3d(trial[i, w]) for i, w in zip(who, way, strict=True)])
        occ_moved = hidden(moved, axes[who])                                    # (L, T)
        C = np.broadcast_to(centres, (len(who), k, 3)).copy()
        C[np.arange(len(who)), who] = moved
        O = np.broadcast_to(occ, (len(who),) + occ.shape).copy()
        O[np.arange(len(who)), :, who] = occ_moved.T
        values = objective.at(C, np.broadcast_to(axes, C.shape), O)
        evaluations += len(who)
        best = int(np.argmax(values))
        if values[best] <= g + 1e-12:
            step /= 2
            continue
        i = int(who[best])
        uv[i], centres[i], occ[:, i], g = trial[i, way[best]], moved[best], occ_moved[:, best], float(values[best])
        moves += 1
    return Refined(uv, centres, occ, g0, g, moves, evaluations)
