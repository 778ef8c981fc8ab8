"""Host-face outlines that move with the design (issue 16: "a host face's size in the constraint model").

A part script's face may grow or move with a design parameter (the thesis cube's top plate is d + 4 mm wide).
The 2-D constraints (``constraints.ConstraintSet``) measure each hole against its host face's outline; with the
outline of one design only, the requirement "stay 0.5 mm inside the face" became "stay inside the face of THAT
design", so the answer depended on which design the map was built at. Here the outline's vertices get a
derivative per design variable, like the hole centres (finite differences of the same CAD rebuilds):

``OutlineRates.outer`` (S, 2, P): d(vertex in the anchor face's (u, v) frame)/d(variable), mm per unit;
``keepouts``: the same per keep-out polygon. A vertex is paired with the nearest vertex of the stepped build's
outline (3-D, part frame); when the polygons of a step have another vertex count, or the pairing is not one to
one, that outline keeps no rates (it stays fixed, as before).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["OutlineRates", "outline_rates"]


@dataclass(frozen=True)
class OutlineRates:
    """Derivatives of one host-face outline (see the module docstring): ``outer`` (S, 2, P) or None,
    ``keepouts`` one (S_k, 2, P) array (or None) per keep-out polygon of the anchor outline."""

    outer: np.ndarray | None
    keepouts: tuple[np.ndarray | None, ...] = ()

    @property
    def moves(self) -> bool:
        arrays = [self.outer, *self.keepouts]
        return any(a is not None and np.abs(a).max(initial=0.0) > 0 for a in arrays)


def _polygon_3d(outline: Any, poly: np.ndarray) -> np.ndarray:
    return outline.to_3d(np.asarray(poly, float))


def _pair(p0: np.ndarray, p1: np.ndarray, tol_mm: float) -> np.ndarray | None:
    """Index into p1 (S,3) of the nearest vertex of each vertex of p0 (S,3), if one to one within ``tol_mm``."""
    if p0.shape != p1.shape:
        return None
    d = np.linalg.norm(p0[:, None] - p1[None], axis=-1)
    idx = np.argmin(d, axis=1)
    if len(set(idx.tolist())) != len(idx) or d[np.arange(len(idx)), idx].max(initial=0.0) > tol_mm:
        return None
    return idx


def _rate(o0: Any, poly0: np.ndarray, plus: tuple[Any, np.ndarray] | None, minus: tuple[Any, np.ndarray] | None,
          span: float, tol_mm: float) -> np.ndarray | None:
    """(S, 2) d(vertex)/d(variable) in the anchor face's (u, v) frame, or None."""
    p0 = _polygon_3d(o0, poly0)
    ends = []
    for side in (plus, minus):
        if side is None:
            ends.append(p0)
            continue
        o1, poly1 = side
        p1 = _polygon_3d(o1, poly1)
        idx = _pair(p0, p1, tol_mm)
        if idx is None:
            return None
        ends.append(p1[idx])
    d3 = (ends[0] - ends[1]) / span
    return np.stack([d3 @ np.asarray(o0.u, float), d3 @ np.asarray(o0.v, float)], axis=-1)


def _keepout_pairs(o0: Any, o1: Any) -> list[np.ndarray | None]:
    """The keep-out of ``o1`` nearest (centroid, 3-D) to each keep-out of ``o0`` (None when counts differ)."""
    k0, k1 = list(o0.keepouts), list(o1.keepouts)
    if len(k0) != len(k1):
        return [None] * len(k0)
    c1 = [_polygon_3d(o1, k).mean(axis=0) for k in k1]
    out = []
    for k in k0:
        c = _polygon_3d(o0, k).mean(axis=0)
        out.append(k1[int(np.argmin([np.linalg.norm(c - x) for x in c1]))] if c1 else None)
    return out


def outline_rates(holes0: Sequence[Any], plus: Sequence[Sequence[Any] | None], minus: Sequence[Sequence[Any] | None],
                  spans: Sequence[float], tol_mm: float = 0.05) -> list[OutlineRates | None]:
    """Per hole of ``holes0`` (the anchor build), its outline's ``OutlineRates`` from the matched holes of the
    builds at +step / −step of each variable (``plus[j]``, ``minus[j]``: holes in ``holes0`` order, None for a
    side not built) over ``spans[j]`` (the distance between the two sides). None for a hole without an outline.
    """
    out: list[OutlineRates | None] = []
    P = len(spans)
    for i, h in enumerate(holes0):
        o0 = h.outline
        if o0 is None:
            out.append(None)
            continue
        outer = np.zeros((len(o0.outer), 2, P))
        kos = [np.zeros((len(k), 2, P)) for k in o0.keepouts]
        outer_ok, ko_ok = True, [True] * len(kos)
        for j in range(P):
            sides = []
            for holes in (plus[j], minus[j]):
                o1 = None if holes is None else holes[i].outline
                if holes is not None and o1 is None:
                    outer_ok = False
                sides.append(o1)
            op, om = sides
            r = _rate(o0, o0.outer, None if op is None else (op, op.outer), None if om is None else (om, om.outer),
                      spans[j], tol_mm)
            if r is None:
                outer_ok = False
            else:
                outer[:, :, j] = r
            kp = _keepout_pairs(o0, op) if op is not None else [None] * len(kos)
            km = _keepout_pairs(o0, om) if om is not None else [None] * len(kos)
            for k, poly in enumerate(o0.keepouts):
                if (op is not None and kp[k] is None) or (om is not None and km[k] is None):
                    ko_ok[k] = False
                    continue
                r = _rate(o0, poly, None if op is None else (op, kp[k]), None if om is None else (om, km[k]),
                          spans[j], tol_mm)
                if r is None:
                    ko_ok[k] = False
                else:
                    kos[k][:, :, j] = r
        out.append(OutlineRates(outer if outer_ok else None,
                                tuple(k if ok else None for k, ok in zip(kos, ko_ok, strict=True))))
    return out
