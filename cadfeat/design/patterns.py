"""Hole patterns of a part: bolt circles, rectangular grids and mirror pairs (issue 13).

A drawing dimensions a bolt circle by its pitch diameter and count, not hole by hole; a design that moves one
bolt off the circle has broken the pattern even if every hole still meets its requirements. ``find_patterns``
detects the patterns of the ORIGINAL holes; ``check_patterns`` tells which of them a new design keeps.

Holes are compared in groups of the same diameter, the same axis direction and the same face plane
(``axis · centre`` equal), all to ``tol_mm``:

- ``bolt_circle``: ≥ 3 holes at one distance from a common centre on the face plane, evenly spaced over the
  full turn (angle steps 2π/n to ``tol_mm`` of arc);
- ``grid``: ≥ 4 holes at every node of an n_u × n_v lattice (n_u, n_v ≥ 2) with even spacing in each direction;
- ``opposite``: two holes diametrically opposite about the axis through ``centre`` (default the origin of the
  part frame) along their common axis (a two-hole bolt circle), not both already in one bolt circle or grid;
- ``mirror``: two holes mirror images in a plane through ``centre`` normal to x, y or z (pairs not opposite).

Units: mm. Set-up code (a handful of holes, run once per study): plain loops are fine here.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cad.features import Hole
    from cadfeat.results import JsonDict

__all__ = ["Pattern", "check_patterns", "find_patterns"]

TOL_MM = 1e-3


@dataclass(frozen=True)
class Pattern:
    """A pattern of holes (indices into the hole list): ``kind`` "bolt_circle" | "grid" | "opposite" | "mirror", its
    parameters (bolt circle: ``centre`` (3,), ``radius_mm``; grid: ``pitch_mm`` (2,), ``shape`` (2,);
    mirror: ``normal`` (3,), ``point`` (3,))."""

    kind: str
    holes: tuple[int, ...]
    params: JsonDict = field(default_factory=dict[str, Any])

    def to_dict(self, names: Sequence[str] | None = None) -> JsonDict:
        out: JsonDict = {"kind": self.kind, "indices": list(self.holes),
               "holes": [names[i] for i in self.holes] if names is not None else list(self.holes)}
        out.update({k: (np.asarray(cast(Any, v)).tolist() if isinstance(v, np.ndarray | tuple) else v)
                    for k, v in self.params.items()})
        return out


def _arrays(holes: Sequence[Hole]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    c = np.array([np.asarray(h.centre, float) for h in holes]).reshape(-1, 3)
    a = np.array([np.asarray(h.axis, float) for h in holes]).reshape(-1, 3)
    r = np.array([float(h.radius_mm) for h in holes])
    return c, a, r


def _groups(c: np.ndarray, a: np.ndarray, r: np.ndarray, tol: float) -> list[list[int]]:
    """Indices grouped by same radius, axis direction and face plane."""
    groups: list[list[int]] = []
    for i in range(len(r)):
        for g in groups:
            j = g[0]
            if abs(r[i] - r[j]) <= tol and a[i] @ a[j] > 1 - 1e-9 and abs(a[j] @ (c[i] - c[j])) <= tol:
                g.append(i)
                break
        else:
            groups.append([i])
    return groups


def _plane_frame(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two in-plane unit vectors (u, v) for a face with normal ``axis``: the part-frame axes where possible."""
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    u = helper - (helper @ axis) * axis
    u /= np.linalg.norm(u)
    return u, np.cross(axis, u)


def _circle_ok(p: np.ndarray, tol: float) -> tuple[np.ndarray, float] | None:
    """(centre (2,), radius) if the 2-D points ``p`` (n ≥ 3) lie on one circle, evenly spaced over a full turn."""
    n = len(p)
    centre = p.mean(axis=0)  # evenly spaced points over a full turn: the centroid is the centre
    d = np.linalg.norm(p - centre, axis=1)
    rho = float(d.mean())
    if n < 3 or rho <= tol or np.abs(d - rho).max() > tol:
        return None
    ang = np.sort(np.arctan2(p[:, 1] - centre[1], p[:, 0] - centre[0]))
    steps = np.diff(np.concatenate([ang, ang[:1] + 2 * np.pi]))
    if np.abs(steps - 2 * np.pi / n).max() * rho > tol:
        return None
    return centre, rho


def _grid_ok(p: np.ndarray, tol: float) -> tuple[np.ndarray, tuple[int, int]] | None:
    """(pitch (2,), (n_u, n_v)) if the 2-D points form a full, evenly spaced n_u × n_v lattice (n_u, n_v ≥ 2)."""
    us = _levels(p[:, 0], tol)
    vs = _levels(p[:, 1], tol)
    if len(us) < 2 or len(vs) < 2 or len(us) * len(vs) != len(p):
        return None
    present = {(int(np.argmin(np.abs(us - x))), int(np.argmin(np.abs(vs - y)))) for x, y in p}
    if len(present) != len(p):
        return None
    du, dv = np.diff(us), np.diff(vs)
    if np.ptp(du) > tol or np.ptp(dv) > tol:
        return None
    return np.array([du.mean(), dv.mean()]), (len(us), len(vs))


def _levels(x: np.ndarray, tol: float) -> np.ndarray:
    xs = np.sort(x)
    levels = [xs[0]]
    for v in xs[1:]:
        if v - levels[-1] > tol:
            levels.append(v)
    return np.array(levels)


def find_patterns(holes: Sequence[Hole], *, centre: Sequence[float] = (0.0, 0.0, 0.0),
                  tol_mm: float = TOL_MM) -> list[Pattern]:
    """Bolt circles, grids and mirror pairs among ``holes`` (``cadfeat.cad.features.Hole``-like: centre, axis,
    radius_mm); see the module docstring. Largest patterns first; a hole may be in a circle or grid and a
    mirror pair."""
    c, a, r = _arrays(holes)
    out: list[Pattern] = []
    covered: list[set[int]] = []
    for g in _groups(c, a, r, tol_mm):
        if len(g) < 3:
            continue
        u, v = _plane_frame(a[g[0]])
        p_all = np.stack([c[g] @ u, c[g] @ v], axis=1)
        # circles: every maximal subset of ≥ 3 holes at one distance from a candidate centre (circumcentres)
        found: list[tuple[int, ...]] = []
        for tri in itertools.combinations(range(len(g)), 3):
            cc = _circumcentre(p_all[list(tri)])
            if cc is None:
                continue
            d = np.linalg.norm(p_all - cc, axis=1)
            members = tuple(int(k) for k in np.flatnonzero(np.abs(d - d[tri[0]]) <= tol_mm))
            if members in found or len(members) < 3:
                continue
            fit = _circle_ok(p_all[list(members)], tol_mm)
            if fit is not None:
                found.append(members)
                idx = tuple(g[k] for k in members)
                centre3 = fit[0][0] * u + fit[0][1] * v + (a[g[0]] @ c[g[0]]) * a[g[0]]
                out.append(Pattern("bolt_circle", idx, {"centre": centre3, "radius_mm": fit[1], "count": len(idx)}))
                covered.append(set(idx))
        if len(g) >= 4:
            fit_g = _grid_ok(p_all, tol_mm)
            if fit_g is not None and set(g) not in covered:  # a square 2 × 2 grid is already a bolt circle
                out.append(Pattern("grid", tuple(g), {"pitch_mm": fit_g[0], "shape": list(fit_g[1])}))
                covered.append(set(g))
    point = np.asarray(centre, float)
    for i, j in itertools.combinations(range(len(r)), 2):
        if abs(r[i] - r[j]) > tol_mm or any({i, j} <= s for s in covered):
            continue
        if _opposite_error(c[i], c[j], a[i], a[j], point) <= tol_mm:
            out.append(Pattern("opposite", (i, j), {"point": point}))
            continue
        for k in range(3):
            n = np.eye(3)[k]
            m = c[i] - 2 * ((c[i] - centre) @ n) * n
            am = a[i] - 2 * (a[i] @ n) * n
            if np.linalg.norm(m - c[j]) <= tol_mm and am @ a[j] > 1 - 1e-9 and abs(c[i][k] - centre[k]) > tol_mm:
                out.append(Pattern("mirror", (i, j), {"normal": n, "point": centre}))
                break
    return sorted(out, key=lambda p: -len(p.holes))


def _opposite_error(ci: np.ndarray, cj: np.ndarray, ai: np.ndarray, aj: np.ndarray, centre: np.ndarray) -> float:
    """How far (mm) two holes on one face plane are from diametrically opposite about the axis through
    ``centre`` along their common axis (inf when they are not on one face plane)."""
    if ai @ aj < 1 - 1e-9 or abs(ai @ (ci - cj)) > TOL_MM:
        return float("inf")
    mid = 0.5 * (ci + cj) - centre
    across = mid - (mid @ ai) * ai
    return float(2 * np.linalg.norm(across)) if np.linalg.norm(ci - cj) > TOL_MM else float("inf")


def _circumcentre(p: np.ndarray) -> np.ndarray | None:
    (x1, y1), (x2, y2), (x3, y3) = p
    d = 2 * (x1 * (y2 - y3) + x2 * (y3 - y1) + x3 * (y1 - y2))
    if abs(d) < 1e-12:
        return None
    s1, s2, s3 = x1 * x1 + y1 * y1, x2 * x2 + y2 * y2, x3 * x3 + y3 * y3
    return np.array([(s1 * (y2 - y3) + s2 * (y3 - y1) + s3 * (y1 - y2)) / d,
                     (s1 * (x3 - x2) + s2 * (x1 - x3) + s3 * (x2 - x1)) / d])


def pattern_kept(pattern: Pattern, holes: Sequence[Hole], tol_mm: float = TOL_MM) -> tuple[bool, str]:
    """Whether ``holes`` (the new design, same order as the original) still form ``pattern`` (a moved, turned
    or rescaled bolt circle or grid still counts; a mirror pair must mirror in the same plane), with why not."""
    c, a, r = _arrays([holes[i] for i in pattern.holes])
    if np.ptp(r) > tol_mm:
        return False, f"diameters differ by {2 * np.ptp(r):.3g} mm"
    if pattern.kind == "mirror":
        n, p0 = np.asarray(pattern.params["normal"], float), np.asarray(pattern.params["point"], float)
        m = c[0] - 2 * ((c[0] - p0) @ n) * n
        err = float(np.linalg.norm(m - c[1]))
        return (err <= tol_mm, "" if err <= tol_mm else f"off the mirror image by {err:.3g} mm")
    if pattern.kind == "opposite":
        err = _opposite_error(c[0], c[1], a[0], a[1], np.asarray(pattern.params["point"], float))
        return (err <= tol_mm, "" if err <= tol_mm else f"no longer opposite about the centre ({err:.3g} mm off)")
    if np.min(a @ a[0]) < 1 - 1e-9 or np.ptp(c @ a[0]) > tol_mm:
        return False, "not on one face plane any more"
    u, v = _plane_frame(a[0])
    p = np.stack([c @ u, c @ v], axis=1)
    if pattern.kind == "bolt_circle":
        centre = p.mean(axis=0)
        d = np.linalg.norm(p - centre, axis=1)
        if _circle_ok(p, tol_mm) is None:
            return False, f"off the circle by up to {float(np.abs(d - d.mean()).max()):.3g} mm or unevenly spaced"
        return True, ""
    if pattern.kind == "grid":
        return (_grid_ok(p, tol_mm) is not None, "no longer an evenly spaced grid")
    return True, ""


def check_patterns(patterns: Sequence[Pattern], holes_after: Sequence[Hole], names: Sequence[str] | None = None,
                   tol_mm: float = TOL_MM) -> list[JsonDict]:
    """results.json ``patterns``: each original pattern with ``broken`` (bool) and ``why``."""
    out: list[JsonDict] = []
    for p in patterns:
        kept, why = pattern_kept(p, holes_after, tol_mm)
        out.append({**p.to_dict(names), "broken": not kept, "why": why})
    return out
