"""Shop-ready designs: resized holes on standard sizes, moved holes on a drawing grid (issue 13).

An optimum comes out at Ø2.906 mm and positions to 0.0001 mm: not a drill size, not a drawing dimension.
``shop_design`` turns the optimiser's design ``x`` into one the shop can make:

1. position variables (``Variable.kind == "position"``) rounded to the grid (a row ``x0 + i·pitch`` then stays
   evenly spaced and on the grid), and so are a hole's depth and rim chamfer (``kind == "other"``, mm: the
   grid is the shop's step, 0.1 mm by default; ``design.hole_form``);
2. target features: each MOVABLE hole's centre (one a design variable moves) rounded to the grid (components
   across its axis; along the axis the hole stays on its face), each RESIZABLE hole's drilled diameter snapped
   to the nearest size of the table (ISO 273 clearance holes by default) — the bore of a plain hole, so a
   chamfered rim keeps its chamfer and is never snapped as if it were a drill (``hole_form.drill_mask``); the
   entrance of a counterbore or countersink; other holes keep their features;
3. a least-squares step of the design variables towards those targets (finite-difference Jacobian of the
   feature model, batched), clipped to the bounds; variables with their own standard sizes snapped to them.

The caller rebuilds the CAD model at the result and verifies every requirement on it (B-rep and re-imported
STEP), as for any design. ``ShopDesign.residual_mm`` is what the feature model says is still off target
(0 for a linear map that can reach the targets).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, cast

import numpy as np

from cadfeat.cad.features import holes_to_arrays
from cadfeat.design.hole_form import drill_mask, drill_radii_batch
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.design.design_space import DesignSpace, FeatureModel
    from cadfeat.design.problem import Problem

__all__ = ["DEFAULT_GRID_MM", "HOLE_SIZE_TABLES", "ShopDesign", "hole_sizes", "model_jacobian", "off_target",
           "refine_on_rebuild", "shop_design", "snap_diameters"]

DEFAULT_GRID_MM = 0.1
"""Default drawing grid of hole positions (mm)."""

#: ISO 273 clearance hole diameters (mm) for M1.6 … M36, fine / medium / coarse series.
ISO_273 = {
    "fine": (1.7, 2.2, 2.7, 3.2, 4.3, 5.3, 6.4, 8.4, 10.5, 13.0, 15.0, 17.0, 21.0, 25.0, 31.0, 37.0),
    "medium": (1.8, 2.4, 2.9, 3.4, 4.5, 5.5, 6.6, 9.0, 11.0, 13.5, 15.5, 17.5, 22.0, 26.0, 33.0, 39.0),
    "coarse": (2.0, 2.6, 3.1, 3.6, 4.8, 5.8, 7.0, 10.0, 12.0, 14.5, 16.5, 18.5, 24.0, 28.0, 35.0, 42.0),
}
#: Metric twist drills (mm): 0.1 mm steps to 3 mm, 0.5 mm steps to 20 mm, 1 mm steps to 40 mm.
METRIC_DRILLS = tuple(np.round(np.concatenate([np.arange(1.0, 3.0, 0.1), np.arange(3.0, 20.0, 0.5),
                                               np.arange(20.0, 40.01, 1.0)]), 3).tolist())
HOLE_SIZE_TABLES = {"iso273-fine": ISO_273["fine"], "iso273-medium": ISO_273["medium"],
                    "iso273-coarse": ISO_273["coarse"], "metric-drills": METRIC_DRILLS, "none": ()}
"""Named diameter tables a study may choose (``[shop] hole_sizes``); "none" keeps the optimiser's sizes."""


def hole_sizes(spec: str | Sequence[float]) -> tuple[float, ...]:
    """The diameters (mm, sorted) of a table name of ``HOLE_SIZE_TABLES`` or an explicit list."""
    if isinstance(spec, str):
        if spec not in HOLE_SIZE_TABLES:
            raise CadfeatError(f"shop.hole_sizes: {spec!r} is not a table; allowed: "
                               f"{', '.join(HOLE_SIZE_TABLES)} or a list of diameters (mm)")
        return tuple(HOLE_SIZE_TABLES[spec])
    sizes = tuple(sorted(float(s) for s in spec))
    if not sizes or not all(np.isfinite(s) and s > 0 for s in sizes):
        raise CadfeatError(f"shop.hole_sizes: {list(spec)!r}; allowed: a non-empty list of diameters > 0 (mm)")
    return sizes


def snap_diameters(diameters: np.ndarray, sizes: Sequence[float], lower: np.ndarray | None = None,
                   upper: np.ndarray | None = None) -> np.ndarray:
    """Each diameter (mm) moved to the nearest size of ``sizes`` (ties: the smaller); ``sizes`` empty: unchanged.
    With ``lower``/``upper`` (mm, per diameter: what the design variables can reach), only sizes in that range
    count; a diameter with no table size in its range keeps its value."""
    d = np.asarray(diameters, float)
    if not len(sizes):
        return d.copy()
    s = np.asarray(sizes, float)
    dist = np.abs(d[..., None] - s)
    if lower is not None and upper is not None:
        tol = 1e-9 * np.maximum(1.0, s)
        reach = (s >= np.asarray(lower, float)[..., None] - tol) & (s <= np.asarray(upper, float)[..., None] + tol)
        dist = np.where(reach, dist, np.inf)
    best = np.argmin(dist, axis=-1)
    return np.where(np.isfinite(np.min(dist, axis=-1)), s[best], d)


def _round_across_axis(centres: np.ndarray, axes: np.ndarray, grid_mm: float) -> np.ndarray:
    """Centres rounded to the grid in the components across each hole's axis (axis-aligned holes: exactly the
    two drawing coordinates; the coordinate along the axis keeps the face level)."""
    rounded = np.round(centres / grid_mm) * grid_mm
    along = np.sum((rounded - centres) * axes, axis=-1, keepdims=True) * axes
    return rounded - along


@dataclass
class ShopDesign:
    """``x`` (P,) the shop-ready design; ``targets`` per hole (centre mm, diameter mm); what changed."""

    x: np.ndarray
    x_optimum: np.ndarray
    grid_mm: float
    sizes: tuple[float, ...]
    moved: np.ndarray
    resized: np.ndarray
    target_centres: np.ndarray
    target_diameters: np.ndarray
    residual_mm: float
    notes: list[str] = field(default_factory=list[str])
    drill_bore: np.ndarray | None = None
    """(N,) bool: the target diameter is the hole's bore (``hole_form.drill_mask``), else its entrance rim."""


def model_jacobian(model: FeatureModel, x: np.ndarray, h: float = 1e-3) -> np.ndarray:
    """(4N, P) d(centres, drilled radii)/dx by central differences, one batched feature evaluation (drilled
    radius: ``hole_form.drill_radii_batch``, the bore of a plain hole, the entrance of the others)."""
    P = x.size
    X = np.concatenate([x + h * np.eye(P), x - h * np.eye(P)])
    c = model.features_batch(X)[0]
    r = drill_radii_batch(model, X)
    F = np.concatenate([c.reshape(2 * P, -1), r.reshape(2 * P, -1)], axis=1)
    return ((F[:P] - F[P:]) / (2 * h)).T


def _flat(c: np.ndarray, r: np.ndarray) -> np.ndarray:
    return np.concatenate([np.asarray(c, float).reshape(-1), np.asarray(r, float).reshape(-1)])


#: Most floor/ceil combinations of the position variables tried when plain rounding breaks a requirement.
MAX_ROUNDINGS = 4096


def rounding_candidates(space: DesignSpace, x: np.ndarray, grid_mm: float) -> np.ndarray:
    """(C, P) designs with the position and hole-form variables (mm, no standard sizes) on the grid: nearest first,
    then every floor/ceil combination (at most ``MAX_ROUNDINGS``; beyond that, nearest only), clipped to the bounds."""
    x = np.asarray(x, float).reshape(-1)
    pos = np.flatnonzero([v.kind in ("position", "other") and v.unit == "mm" and v.standard_sizes is None
                          for v in space.variables])
    nearest = x.copy()
    if grid_mm <= 0 or not pos.size:
        return nearest[None]
    nearest[pos] = np.round(x[pos] / grid_mm) * grid_mm
    out = [space.clip(nearest)]
    if 2 ** pos.size <= MAX_ROUNDINGS:
        lo, hi = np.floor(x[pos] / grid_mm) * grid_mm, np.ceil(x[pos] / grid_mm) * grid_mm
        bits = cast(np.ndarray, (np.arange(2 ** pos.size)[:, None] >> np.arange(pos.size)) & 1)
        X = np.tile(x, (len(bits), 1))
        X[:, pos] = np.where(bits == 1, hi, lo)
        out += list(space.clip(X))
    return np.array(out)


def shop_design(space: DesignSpace, model: FeatureModel, x: np.ndarray, *, grid_mm: float = DEFAULT_GRID_MM,
                sizes: Sequence[float] = ISO_273["medium"], tol_mm: float = 1e-9,
                problem: Problem | None = None) -> ShopDesign:
    """The shop-ready design near ``x`` (see the module docstring). ``space``: the ``DesignSpace``; ``model``:
    the feature model (``features``, ``features_batch``); ``grid_mm`` 0 keeps positions; ``sizes`` empty
    keeps diameters. With ``problem`` (its ``evaluate_batch`` on ``model``'s variables): when the nearest
    rounding breaks a kept requirement of the model, the floor/ceil combinations are scored in one batch and
    the feasible one with the best combined objective is taken (the optimum often sits on a requirement)."""
    x = np.asarray(x, float).reshape(-1)
    first = _shop_from(space, model, x, rounding_candidates(space, x, grid_mm)[0], grid_mm, sizes, tol_mm)
    if problem is None or _feasible(problem, first.x):
        return first
    cands = rounding_candidates(space, x, grid_mm)[1:]
    if not len(cands):
        return first
    G, C = problem.evaluate_batch(cands)
    ok = C.min(axis=1, initial=0.0) >= -1e-9
    score = np.where(ok, np.asarray(problem.combined_from(G), float), -np.inf)
    for k in np.argsort(-score)[:8]:
        if not np.isfinite(score[k]):
            break
        sd = _shop_from(space, model, x, cands[k], grid_mm, sizes, tol_mm)
        if _feasible(problem, sd.x):
            sd.notes.append("the nearest rounding broke a kept requirement: rounded the other way where needed "
                            "(best feasible floor/ceil combination)")
            return sd
    return first


def _reachable_diameters(space: DesignSpace, x: np.ndarray, r: np.ndarray, J_r: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
    """(N,) lowest and highest diameter (mm) each hole can have within the variable bounds, to first order about
    ``x`` (``J_r``: (N, P) dr/dx): a table size outside them cannot be drilled by this design space."""
    lower, upper = np.asarray(space.lower, float), np.asarray(space.upper, float)
    lo_step, hi_step = J_r * (lower - x), J_r * (upper - x)
    return 2 * (r + np.minimum(lo_step, hi_step).sum(axis=1)), 2 * (r + np.maximum(lo_step, hi_step).sum(axis=1))


def _feasible(problem: Problem, x: np.ndarray) -> bool:
    return float(np.asarray(problem.constraints(x), float).min(initial=0.0)) >= -1e-9


def _shop_from(space: DesignSpace, model: FeatureModel, x: np.ndarray, xr: np.ndarray, grid_mm: float,
               sizes: Sequence[float], tol_mm: float) -> ShopDesign:
    """Targets from the rounded variables ``xr`` and the least-squares step towards them."""
    cr, ar = (np.asarray(v, float) for v in model.features(xr)[:2])
    rr = drill_radii_batch(model, xr)[0]
    J = model_jacobian(model, xr)
    n = len(rr)
    # the holes the design variables move / resize (not "the holes that moved from the start": which holes are
    # rounded must not depend on the part's current values, issue 16)
    moved = np.abs(J[:3 * n]).reshape(n, 3, -1).max(axis=(1, 2), initial=0.0) > tol_mm
    resized = np.abs(J[3 * n:]).max(axis=1, initial=0.0) > tol_mm
    tc = cr.copy()
    if grid_mm > 0:
        tc[moved] = _round_across_axis(cr[moved], ar[moved], grid_mm)
    dr = np.abs(J[3 * n:]) > 1e-9  # (N, P): which variables size each hole
    own_sizes = ~np.any(dr & ~np.asarray(space.discrete, bool), axis=1)
    td = 2 * rr
    table = resized & ~own_sizes  # a hole sized by variables with the study's own sizes keeps that size
    lo, hi = _reachable_diameters(space, xr, rr, J[3 * n:])
    td[table] = snap_diameters(2 * rr[table], sizes, lo[table], hi[table])
    target = _flat(tc, td / 2)
    step = np.linalg.lstsq(J, target - _flat(cr, rr), rcond=None)[0]
    xs = space.snap(space.clip(xr + step))
    cs, rs = model.features(xs)[0], drill_radii_batch(model, xs)[0]
    residual = float(np.max(np.abs(_flat(cs, rs) - target), initial=0.0))
    notes: list[str] = []
    if residual > 1e-6:
        notes.append(f"the design variables cannot put every moved hole on the {grid_mm:g} mm grid and every resized "
                     f"hole on a table size at once (largest remaining difference {residual:.3g} mm, feature model)")
    return ShopDesign(xs, x, float(grid_mm), tuple(sizes), moved, resized, tc, td, residual, notes,
                      drill_mask(model))


# ------------------------------------------------------------------------------ refinement on the CAD rebuild
def _drilled(holes: Sequence[Hole], design: ShopDesign) -> tuple[np.ndarray, np.ndarray]:
    """Centres (N, 3) and drilled radii (N,) mm of CAD holes: the bore where ``design.drill_bore``, else the rim."""
    c, _, r = holes_to_arrays(list(holes))
    if design.drill_bore is not None and len(design.drill_bore) == len(r):
        r = np.where(design.drill_bore, [float(h.bore_radius_mm) for h in holes], r)
    return c, r


def off_target(holes: Sequence[Hole], design: ShopDesign) -> float:
    """Largest distance (mm) of ``holes``' centres and drilled diameters from the shop design's targets."""
    c, r = _drilled(holes, design)
    return float(max(np.abs(c - design.target_centres).max(initial=0.0),
                     np.abs(2 * r - design.target_diameters).max(initial=0.0)))


def refine_on_rebuild(space: DesignSpace, model: FeatureModel, problem: Problem, x: np.ndarray,
                      rebuilt: tuple[Shape, list[Hole], float],
                      design: ShopDesign, rebuild: Callable[[np.ndarray, list[Hole]], tuple[Shape, list[Hole], float]],
                      rounds: int = 6) -> tuple[np.ndarray, tuple[Shape, list[Hole], float], float]:
    """Where the feature model is only a linearisation (a nonlinear part script), the rebuilt holes may miss the
    grid/table targets of ``design``: up to ``rounds`` Newton steps on the real CAD rebuild (the model's
    Jacobian, the rebuilt holes' error), each kept only if it gets closer and keeps the model's constraints.

    ``rebuilt`` = (shape, holes, prediction error) at ``x``; ``rebuild(x, predicted_holes)`` rebuilds at ``x``
    (raising ``CadfeatError`` when it cannot). Returns (x, rebuilt, remaining off-target distance in mm)."""
    shape, holes, err = rebuilt
    off = off_target(holes, design)
    for _ in range(rounds):
        if off <= 1e-6:
            break
        c, r = _drilled(holes, design)
        resid = np.concatenate([(design.target_centres - c).reshape(-1), (design.target_diameters / 2 - r)])
        step = np.linalg.lstsq(model_jacobian(model, x), resid, rcond=None)[0]
        x_new = space.snap(space.clip(x + step))
        if np.asarray(problem.constraints(x_new), float).min(initial=0.0) < -1e-9:
            break
        c_new, _, r_new = model.features(x_new)
        c_old, _, r_old = model.features(x)
        guess = [dataclasses.replace(h, centre=h.centre + d, radius_mm=h.radius_mm + e)
                 for h, d, e in zip(holes, c_new - c_old, r_new - r_old, strict=True)]
        try:
            cand = rebuild(x_new, guess)
        except CadfeatError:
            break
        off_new = off_target(cand[1], design)
        if off_new >= off:
            break
        x, (shape, holes, err), off = x_new, cand, off_new
    return x, (shape, holes, err), off
