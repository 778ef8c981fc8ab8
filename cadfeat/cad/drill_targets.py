"""Added target holes in CAD: the planar faces a part offers, and blind holes drilled into its solid (issue 31).

Both kinds of part take the same path: a part script's solid after ``build`` (and after the move-only optimum's
rebuild), a STEP part's B-rep as imported (or re-drilled). ``drill_targets`` cuts each added hole — a flat-floored
blind cylinder of the drill's radius to its depth and, with a chamfer, a 45° cone widening the rim — with tools
that start ``OUTSIDE_MM`` outside the face (no coplanar Boolean), merges same-domain faces, and verifies:

- the material removed equals the holes' analytic volume (measured on the small tool solids, which OCCT
  integrates exactly: ``step_parts._material_in``), so no hole breaks out of the part or into another feature;
- the B-rep is valid (if the input was);
- re-extraction finds every added hole at its centre, axis and rim radius, and every hole the part had
  unchanged (centre, axis, radius, depth).

Units: mm, part frame. CadQuery/OCP are imported inside the functions.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cadfeat.cad.features import FaceOutline, Hole, extract_holes
from cadfeat.cad.tolerance import ModelTolerance
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cad.features import ShapeLike

__all__ = ["OUTSIDE_MM", "AddedHole", "PlanarFace", "added_hole", "drill_targets", "planar_faces",
           "verify_drilled"]

OUTSIDE_MM = 1.0
"""The cutting tools start this far outside the face (mm)."""


@dataclass(frozen=True)
class PlanarFace:
    """A planar face of a solid: its index in ``Faces()`` (not stable across rebuilds), its outline (face
    frame, outer boundary and keep-outs, mm), its area (mm²) and the holes of the part that open into it."""

    index: int
    outline: FaceOutline
    area_mm2: float
    holes: tuple[int, ...]

    @property
    def normal(self) -> np.ndarray:
        """(3,) outward unit normal."""
        return self.outline.normal

    def describe(self) -> str:
        """"face 3 (normal (0, -1, 0), 3960 mm²)": for error messages."""
        n = ", ".join(f"{x:.3g}" for x in np.round(self.normal, 3) + 0.0)
        return f"face {self.index} (normal ({n}), {self.area_mm2:.0f} mm²)"


@dataclass(frozen=True)
class AddedHole:
    """An added blind target hole: rim centre on the face (3,) mm, axis out of the material (3,), drill radius
    and depth (mm), 45° rim chamfer (mm), its name (continuing the part's: H10, …)."""

    centre: np.ndarray
    axis: np.ndarray
    radius_mm: float
    depth_mm: float
    chamfer_mm: float
    name: str

    @property
    def rim_radius_mm(self) -> float:
        """The rim the camera sees (mm): drill radius + chamfer."""
        return self.radius_mm + self.chamfer_mm


def added_hole(added: AddedHole, host_face: int = -1, outline: FaceOutline | None = None) -> Hole:
    """The ``Hole`` an added target becomes (rim centre and radius, blind, plain — "chamfered rim" with a
    chamfer), as the feature arrays of the prediction need it before any CAD work."""
    kind = "plain, chamfered rim" if added.chamfer_mm > 0 else "plain"
    return Hole(centre=np.asarray(added.centre, float), axis=np.asarray(added.axis, float),
                radius_mm=added.rim_radius_mm, bore_radius_mm=added.radius_mm, depth_mm=added.depth_mm,
                through=False, kind=kind, host_face=host_face, outline=outline, name=added.name)


def planar_faces(shape: ShapeLike, min_area_mm2: float = 1.0) -> list[PlanarFace]:
    """Every planar face of ``shape`` (a cadquery Shape) of at least ``min_area_mm2``, with its outline in which
    the rims of the part's extracted holes are not keep-outs (they are holes: kept apart by the ligament), and
    the indices of the extracted holes that open into it (``extract_holes`` order)."""
    # lazy: would import OCP at module load
    from cadfeat.cad.features.extraction import _Extractor  # pyright: ignore[reportPrivateUsage]

    ex = _Extractor(shape, None)
    found = [h for g in ex.groups() if (h := ex.hole(g)) is not None]
    rims = set().union(*(edges for _, edges in found)) if found else set()
    holes = extract_holes(shape)
    out = []
    for f in range(len(ex.topo.faces)):
        outline = ex.outline(f, rims)
        if outline is None:
            continue
        area = float(abs(_polygon_area(outline.outer)))
        if area < min_area_mm2:
            continue
        on = tuple(i for i, h in enumerate(holes) if _on_plane(h, outline))
        out.append(PlanarFace(f, outline, area, on))
    return out


def _polygon_area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _on_plane(hole: Hole, outline: FaceOutline, tol_mm: float = 1e-4) -> bool:
    """True if ``hole``'s rim centre lies on the face's plane and its axis is the face's normal."""
    n = outline.normal
    return bool(abs(float((np.asarray(hole.centre) - outline.origin) @ n)) < tol_mm
                and float(np.asarray(hole.axis) @ n) > 1 - 1e-6)


def _tool(added: AddedHole) -> Any:
    """The cutting tool of one added hole: a cylinder from ``OUTSIDE_MM`` outside the face to the depth, fused
    with a 45° cone for the chamfer."""
    import cadquery as cq

    d = -np.asarray(added.axis, float)
    start = cq.Vector(*(np.asarray(added.centre, float) - OUTSIDE_MM * d))
    direction = cq.Vector(*d)
    tool = cq.Solid.makeCylinder(added.radius_mm, added.depth_mm + OUTSIDE_MM, start, direction)
    if added.chamfer_mm > 0:
        cone = cq.Solid.makeCone(added.rim_radius_mm + OUTSIDE_MM, added.radius_mm, added.chamfer_mm + OUTSIDE_MM,
                                 start, direction)
        tool = tool.fuse(cone).clean()
    return tool


def _volume_mm3(added: AddedHole) -> float:
    """Analytic volume (mm³) the hole removes: the bore plus the chamfer's cone frustum outside the bore."""
    r, c, h = added.radius_mm, added.chamfer_mm, added.depth_mm
    frustum = np.pi * c / 3.0 * ((r + c) ** 2 + (r + c) * r + r * r)
    return float(np.pi * r * r * h + frustum - np.pi * r * r * c)


def drill_targets(shape: ShapeLike, added: Sequence[AddedHole], holes_before: Sequence[Hole] | None = None,
                  tol: ModelTolerance | None = None, label: str = "the part",
                  prefer_direction: Sequence[float] | np.ndarray | None = None) -> tuple[Any, list[Hole]]:
    """``shape`` (a cadquery Shape holding one solid) with the ``added`` blind holes cut, verified (module
    docstring); returns (the solid, its holes: the part's holes as before, in their order and names, then
    the added ones named as ``added``). ``holes_before``: the part's holes (default: extracted from ``shape``);
    ``prefer_direction``: the side through holes enter from (the study's view), as ``holes_before`` were extracted.
    Raises ``CadfeatError`` naming ``label`` and the hole when a check fails."""
    from cadfeat.cad.export import check_solid
    from cadfeat.cad.step_parts import _material_in, _single_solid, _unify  # pyright: ignore[reportPrivateUsage]

    tol = tol or ModelTolerance.of_shape(shape)
    solid = _single_solid(shape, label)
    before = list(holes_before) if holes_before is not None else extract_holes(solid, prefer_direction)
    if not added:
        return solid, before
    tools = [_tool(a) for a in added]
    result = _single_solid(_unify(solid.cut(*tools)), f"drilling the added holes into {label}")
    _, removed = _material_in(solid, tools, tol)
    _, left = _material_in(result, tools, tol)
    expected = sum(_volume_mm3(a) for a in added)
    allowed = 2.0 * tol.linear_mm * sum(2 * np.pi * a.rim_radius_mm * (a.depth_mm + 2 * a.rim_radius_mm)
                                        for a in added) + 1e-6 * expected
    names = ", ".join(a.name for a in added)
    if abs(removed - expected) > allowed or left > allowed:
        raise CadfeatError(f"{label}: drilling {names} removed {removed:.6g} mm^3 instead of {expected:.6g} mm^3 "
                           f"(allowed ±{allowed:.3g}): an added hole breaks out of the part or into another feature")
    if (problems := check_solid(result)) and not check_solid(solid):
        raise CadfeatError(f"{label}: drilling {names} gave an invalid solid: {'; '.join(problems[:3])}")
    return result, verify_drilled(result, before, added, tol, label, prefer_direction)


def verify_drilled(shape: ShapeLike, before: Sequence[Hole], added: Sequence[AddedHole],
                   tol: ModelTolerance | None = None,
                   label: str = "the part", prefer_direction: Sequence[float] | np.ndarray | None = None) -> list[Hole]:
    """Re-extract the holes of ``shape`` and find each hole of ``before`` unchanged and each ``added`` hole where
    it was put (centre, axis, rim radius, depth within ``max(1e-3, 10 × tol)`` mm); returns the holes in that
    order (``before``'s names, then the added names). Raises ``CadfeatError`` naming the missing hole."""
    tol = tol or ModelTolerance.of_shape(shape)
    found = extract_holes(shape, prefer_direction=prefer_direction, tol=tol)
    near = max(1e-3, 10 * tol.linear_mm)
    want = list(before) + [added_hole(a) for a in added]
    out: list[Hole] = []
    used: set[int] = set()
    for i, w in enumerate(want):
        k = _match(w, found, used, near)
        if k is None:
            what = "added" if i >= len(before) else "existing"
            raise CadfeatError(f"{label}: after drilling, extraction finds no {what} hole {w.name or i + 1} of rim "
                               f"radius {w.radius_mm:.6g} mm at {np.round(w.centre, 6).tolist()} (it merged with "
                               "another feature or lost its rim)")
        used.add(k)
        out.append(dataclasses.replace(found[k], name=w.name) if w.name else found[k])
    return out


def _match(want: Hole, found: Sequence[Hole], used: set[int], near: float) -> int | None:
    """The index of the found hole at ``want``'s centre (or, for a through hole, on its axis line from either
    end), axis, radius and depth; None if none."""
    for k, h in enumerate(found):
        if k in used:
            continue
        same_axis = abs(float(np.asarray(h.axis) @ np.asarray(want.axis))) > 1 - 1e-6
        d = np.asarray(h.centre) - np.asarray(want.centre)
        if want.through:
            at = float(np.linalg.norm(np.cross(d, want.axis))) <= near
        else:
            at = float(np.linalg.norm(d)) <= near and float(np.asarray(h.axis) @ np.asarray(want.axis)) > 0
        size = abs(h.radius_mm - want.radius_mm) <= near or (want.through and abs(h.bore_radius_mm
                                                                                   - want.bore_radius_mm) <= near)
        deep = want.through or abs(h.depth_mm - want.depth_mm) <= near
        if same_axis and at and size and deep:
            return k
    return None
