"""Parts given as STEP files: import, hole selection, and re-drilling holes at new places and sizes.

A STEP part has no parameters, so a redesign changes it directly on the B-rep (DESIGN.md, "Data flow"):
each chosen hole is FILLED with the solid of revolution of its own profile (read from the hole's faces:
plain bore, counterbore steps, countersink cones, drill points), the filled faces are merged back into
their neighbours (``ShapeUpgrade_UnifySameDomain``), and the hole is CUT again at its new centre on the
same host face plane with its new radius. Everything else of the solid is left as it was.

The input file is only read. CadQuery/OCP are imported inside the functions.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    import cadquery as cq

    from cadfeat.cad.features import Hole

__all__ = [
    "HoleMove",
    "HoleProfile",
    "StepPart",
    "fill_holes",
    "hole_profile",
    "load_step",
    "redrill",
]

PLANE_TOL_MM = 1e-6
"""A new hole centre must lie within this distance of its host face plane."""
AXIS_TOL = 1e-9
"""Parallelism tolerance (sine of the angle) between a face's axis and the hole's axis."""
LINE_TOL_MM = 1e-6
"""A face belongs to a hole when its axis passes within this distance of the hole's axis line."""
VOLUME_RTOL = 1e-6
"""Relative tolerance of the volume checks of the fill and cut steps."""


# ------------------------------------------------------------------------------------------ STEP parts
@dataclass(frozen=True)
class StepPart:
    """A part read from a STEP file: one solid (mm) and its holes, named ``H1``, ``H2``... in order."""

    name: str
    path: Path
    shape: Any  # cadquery.Solid
    holes: tuple[Hole, ...] = field(repr=False)

    def select(self, spec: int | str | Sequence[float], tol_mm: float = 0.01) -> Hole:
        """One hole by 1-based index (``2``), name (``"H2"``, ``"2"``) or position.

        A position is a point (3,) in mm (or the string ``"x,y,z"``): the hole whose entrance-rim centre
        is nearest, if it is within ``tol_mm``. Raises ``CadfeatError`` listing the available holes
        otherwise.
        """
        if isinstance(spec, str) and "," in spec:
            try:
                spec = [float(x) for x in spec.split(",")]
            except ValueError:
                raise CadfeatError(f"{self.path}: hole position {spec!r} is not 'x,y,z' in mm; "
                                   f"available holes: {self.describe_holes()}") from None
        if isinstance(spec, int | np.integer | str):
            return self._by_name(spec)
        return self._by_position(np.asarray(spec, dtype=float), tol_mm)

    def describe_holes(self) -> str:
        """``"H1 (x, y, z) r=R mm, H2 ..."``: the holes, for error messages and listings."""
        if not self.holes:
            return "none (the part has no holes)"
        return ", ".join(f"{h.name} ({', '.join(f'{x:.6g}' for x in h.centre)}) r={h.radius_mm:.6g} mm"
                         for h in self.holes)

    def _by_name(self, spec: int | str) -> Hole:
        key = str(spec).strip()
        key = key[1:] if key[:1] in ("H", "h") else key
        if key.isdigit() and 1 <= int(key) <= len(self.holes):
            return self.holes[int(key) - 1]
        raise CadfeatError(f"{self.path}: no hole {spec!r}; available holes: {self.describe_holes()}")

    def _by_position(self, point: np.ndarray, tol_mm: float) -> Hole:
        if point.shape != (3,) or not np.all(np.isfinite(point)):
            raise CadfeatError(f"{self.path}: a hole position must be 3 finite numbers (mm), got {point.tolist()}")
        if not self.holes:
            raise CadfeatError(f"{self.path}: no hole near {point.tolist()}: the part has no holes")
        centres = np.array([h.centre for h in self.holes], dtype=float)
        dist = np.linalg.norm(centres - point, axis=-1)
        best = int(np.argmin(dist))
        if dist[best] > tol_mm:
            raise CadfeatError(f"{self.path}: no hole within {tol_mm:g} mm of {point.tolist()} (nearest "
                               f"{self.holes[best].name} at {dist[best]:.6g} mm); available holes: "
                               f"{self.describe_holes()}")
        return self.holes[best]


def load_step(path: str | os.PathLike[str], prefer_direction: Sequence[float] | None = None) -> StepPart:
    """Read a STEP part: exactly one solid, its holes extracted and named ``H1``, ``H2``... in the
    deterministic order of ``features.extract_holes``. ``prefer_direction`` (e.g. the side the camera looks
    from) picks the entrance end of through holes of equal end radii (see ``extract_holes``).

    Raises ``CadfeatError`` naming the file if it is missing, not STEP, holds no solid or several solids.
    The file is only read.
    """
    import cadquery as cq

    from cadfeat.cad.export import import_step
    from cadfeat.cad.features import extract_holes

    path = Path(path)
    shape = import_step(path)
    solids = shape.Solids()
    if len(solids) != 1:
        what = "no solid" if not solids else f"{len(solids)} solids"
        raise CadfeatError(f"{path}: holds {what}; a STEP part must hold exactly one solid")
    solid = cq.Solid(solids[0].wrapped)
    found = extract_holes(solid, prefer_direction)
    holes = tuple(dataclasses.replace(h, name=f"H{i + 1}") for i, h in enumerate(found))
    return StepPart(name=path.stem, path=path, shape=solid, holes=holes)


# ------------------------------------------------------------------------------------------- profiles
@dataclass(frozen=True)
class HoleProfile:
    """The wall of a hole of revolution as axial segments (mm).

    ``segments[k] = (t0, t1, r0, r1)``: from depth ``t0`` to ``t1`` (measured from the entrance rim into
    the material, along −axis) the radius goes linearly from ``r0`` to ``r1``. Cylinders have r0 = r1,
    cones (countersinks, drill points) r0 ≠ r1; a step between segments is a flat annulus
    (counterbore floor). ``conical[k]`` says which segments are cones.
    """

    segments: np.ndarray  # (S, 4)
    conical: np.ndarray   # (S,) bool

    @property
    def depth_mm(self) -> float:
        return float(self.segments[-1, 1])

    @property
    def volume_mm3(self) -> float:
        """Volume enclosed by the wall: Σ π h (r0² + r0 r1 + r1²) / 3 (frustums)."""
        t0, t1, r0, r1 = self.segments.T
        return float(np.sum(np.pi * (t1 - t0) * (r0 * r0 + r0 * r1 + r1 * r1) / 3.0))

    def scaled(self, factor: float) -> HoleProfile:
        """The profile with every radius times ``factor``: cones keep their angle (their length scales,
        e.g. a 90° countersink stays 90°); cylinders keep the depth where they end (counterbore depth,
        total depth). Raises ``CadfeatError`` if a scaled cone would run past the next step."""
        segments = self.segments.copy()
        segments[:, 2:] *= factor
        t = 0.0
        for k in range(len(segments)):  # segments of one hole: a handful
            t0, t1 = self.segments[k, :2]
            end = t + factor * (t1 - t0) if self.conical[k] else t1
            if end <= t:
                raise CadfeatError(f"scaling the hole by {factor:g} makes its cone run past depth {t1:.6g} mm")
            segments[k, :2] = (t, end)
            t = end
        return HoleProfile(segments, self.conical.copy())

    def polygon(self) -> np.ndarray:
        """Closed half-section (K, 2) of (radius, depth) points, starting and ending on the axis."""
        points = [(0.0, 0.0)]
        for t0, t1, r0, r1 in self.segments:
            points += [(r0, t0), (r1, t1)]
        points.append((0.0, self.depth_mm))
        pts = np.array(points)
        keep = np.ones(len(pts), dtype=bool)
        keep[1:] = np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-12
        return pts[keep]


def _vec(p: Any) -> np.ndarray:
    return np.array([p.X(), p.Y(), p.Z()], dtype=float)


def _coaxial(location: Any, direction: Any, centre: np.ndarray, axis: np.ndarray) -> bool:
    d = _vec(direction)
    return (np.linalg.norm(np.cross(d, axis)) <= AXIS_TOL
            and np.linalg.norm(np.cross(_vec(location) - centre, axis)) <= LINE_TOL_MM)


def _face_levels(face: Any, hole: Hole, label: str) -> list[tuple[float, float]]:
    """(depth, radius) of each circular boundary of a hole's wall face (and its cone apex, radius 0).

    Raises ``CadfeatError`` if the face is bounded by anything else than coaxial circles perpendicular
    to the axis (an oblique entrance/exit, or another feature cutting into the wall).
    """
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.GeomAbs import GeomAbs_Circle
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    centre, axis = np.asarray(hole.centre, float), np.asarray(hole.axis, float)
    levels = []
    explorer = TopExp_Explorer(face, TopAbs_EDGE)
    while explorer.More():
        edge = TopoDS.Edge_s(explorer.Current())
        explorer.Next()
        if BRep_Tool.Degenerated_s(edge) or BRep_Tool.IsClosed_s(edge, face):
            continue  # cone apex / seam
        curve = BRepAdaptor_Curve(edge)
        if curve.GetType() != GeomAbs_Circle or not _coaxial(curve.Circle().Location(),
                                                              curve.Circle().Axis().Direction(), centre, axis):
            raise CadfeatError(f"{label}: its wall meets a face that is not perpendicular to its axis (oblique "
                               "entrance/exit, or another feature cuts into it); re-drilling supports holes "
                               "that start and end on planes perpendicular to their axis")
        circle = curve.Circle()
        levels.append((float(np.dot(centre - _vec(circle.Location()), axis)), float(circle.Radius())))
    return levels


def _wall_segment(face: Any, hole: Hole, label: str) -> tuple[float, float, float, float, bool, float] | None:
    """(t0, t1, r0, r1, conical, area) of a face if it is part of ``hole``'s wall, else None."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_Cone, GeomAbs_Cylinder

    centre, axis = np.asarray(hole.centre, float), np.asarray(hole.axis, float)
    surface = BRepAdaptor_Surface(face)
    kind = surface.GetType()
    if kind == GeomAbs_Cylinder:
        ax = surface.Cylinder().Axis()
    elif kind == GeomAbs_Cone:
        ax = surface.Cone().Axis()
    else:
        return None
    if not _coaxial(ax.Location(), ax.Direction(), centre, axis):
        return None
    levels = _face_levels(face, hole, label)
    if kind == GeomAbs_Cone:
        apex = surface.Cone().Apex()
        if len({round(t, 9) for t, _ in levels}) == 1:  # a drill point: one rim, then the apex
            levels.append((float(np.dot(centre - _vec(apex), axis)), 0.0))
    if not levels:
        return None
    levels.sort()
    (t0, r0), (t1, r1) = levels[0], levels[-1]
    if t0 < -LINE_TOL_MM or t0 > hole.depth_mm + LINE_TOL_MM or r0 > hole.radius_mm + LINE_TOL_MM:
        return None  # another coaxial feature (e.g. a boss on the far side)
    return t0, t1, r0, r1, kind == GeomAbs_Cone, _face_area(face)


def _face_area(face: Any) -> float:
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(face, props)
    return float(props.Mass())


def hole_profile(shape: Any, hole: Hole) -> HoleProfile:
    """The wall profile of ``hole`` read from the faces of ``shape`` (exact B-rep geometry).

    Collects the cylindrical and conical faces coaxial with the hole that start between its entrance rim
    and its depth, groups split faces (their areas must add up to the full 360° wall) and checks that the
    segments follow each other from the entrance rim (depth 0, radius ``hole.radius_mm``) down.
    Raises ``CadfeatError`` naming the hole if the wall is not such a stack of surfaces of revolution.
    """
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp
    from OCP.TopoDS import TopoDS
    from OCP.TopTools import TopTools_IndexedMapOfShape

    label = _label(hole)
    occ = shape.wrapped if hasattr(shape, "wrapped") else shape
    faces = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(occ, TopAbs_FACE, faces)
    groups: dict[tuple[float, float], list[tuple[float, float, float, float, bool, float]]] = {}
    for i in range(1, faces.Extent() + 1):
        segment = _wall_segment(TopoDS.Face_s(faces.FindKey(i)), hole, label)
        if segment is not None:
            groups.setdefault((round(segment[0], 6), round(segment[1], 6)), []).append(segment)
    if not groups:
        raise CadfeatError(f"{label}: no wall face coaxial with the hole found in the shape")
    segments, conical = [], []
    for key in sorted(groups):
        parts = groups[key]
        t0, t1, r0, r1, cone, _ = parts[0]
        full = np.pi * (r0 + r1) * math.hypot(t1 - t0, r1 - r0)  # lateral area of the whole frustum
        if abs(sum(p[5] for p in parts) - full) > 1e-6 * full:
            raise CadfeatError(f"{label}: its wall between depths {t0:.6g} and {t1:.6g} mm is not a full "
                               "circle (a slot or another feature cuts into it)")
        segments.append((t0, t1, r0, r1))
        conical.append(cone)
    profile = HoleProfile(np.array(segments, dtype=float), np.array(conical, dtype=bool))
    _check_profile(profile, hole, label)
    return profile


def _check_profile(profile: HoleProfile, hole: Hole, label: str) -> None:
    seg = profile.segments
    if abs(seg[0, 0]) > LINE_TOL_MM or abs(seg[0, 2] - hole.radius_mm) > LINE_TOL_MM:
        raise CadfeatError(f"{label}: its wall does not start at the entrance rim (depth {seg[0, 0]:.6g} mm, "
                           f"radius {seg[0, 2]:.6g} mm, expected 0 and {hole.radius_mm:.6g} mm)")
    gaps = np.abs(seg[1:, 0] - seg[:-1, 1])
    if np.any(gaps > LINE_TOL_MM):
        k = int(np.argmax(gaps))
        raise CadfeatError(f"{label}: its wall has a gap between depths {seg[k, 1]:.6g} and {seg[k + 1, 0]:.6g} mm")


def _label(hole: Hole) -> str:
    c = np.asarray(hole.centre, dtype=float)
    name = getattr(hole, "name", "") or "hole"
    return f"hole {name} at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}) mm"


def _revolved(profile: HoleProfile, centre: np.ndarray, axis: np.ndarray) -> cq.Solid:
    """Solid of revolution of ``profile`` about the line (centre, axis); depth runs along −axis."""
    import cadquery as cq

    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    radial = np.cross(axis, helper)
    radial /= np.linalg.norm(radial)
    section = profile.polygon()
    points = centre + section[:, :1] * radial - section[:, 1:] * axis
    wire = cq.Wire.makePolygon([cq.Vector(*p) for p in points], close=True)
    face = cq.Face.makeFromWires(wire)
    return cq.Solid.revolve(face, 360.0, cq.Vector(*centre), cq.Vector(*(centre + axis)))


# ----------------------------------------------------------------------------------------- re-drilling
@dataclass(frozen=True)
class HoleMove:
    """Re-drill ``hole`` with its entrance-rim centre at ``centre`` (mm, on the same host face plane) and
    entrance radius ``radius_mm`` (the whole profile scales with it, see ``HoleProfile.scaled``)."""

    hole: Hole
    centre: np.ndarray
    radius_mm: float

    def __post_init__(self) -> None:
        centre = np.asarray(self.centre, dtype=float)
        if centre.shape != (3,) or not np.all(np.isfinite(centre)):
            raise CadfeatError(f"{_label(self.hole)}: new centre must be 3 finite numbers (mm), got {self.centre!r}")
        if not (math.isfinite(self.radius_mm) and self.radius_mm > 0):
            raise CadfeatError(f"{_label(self.hole)}: new radius_mm must be > 0, got {self.radius_mm!r}")
        object.__setattr__(self, "centre", centre)
        object.__setattr__(self, "radius_mm", float(self.radius_mm))


def _host_normal(hole: Hole) -> np.ndarray:
    """Outward normal of the hole's host face plane (from its outline, else the hole axis)."""
    outline = getattr(hole, "outline", None)
    if outline is not None:
        n = np.cross(np.asarray(outline.u, float), np.asarray(outline.v, float))
        return n / np.linalg.norm(n)
    return np.asarray(hole.axis, dtype=float)


def _check_on_host_plane(move: HoleMove) -> None:
    offset = float(np.dot(move.centre - np.asarray(move.hole.centre, float), _host_normal(move.hole)))
    if abs(offset) > PLANE_TOL_MM:
        raise CadfeatError(f"{_label(move.hole)}: new centre {move.centre.tolist()} is {offset:.3g} mm off its "
                           f"host face plane (allowed {PLANE_TOL_MM:g} mm)")


def _unify(shape: Any) -> cq.Shape:
    """Merge same-domain faces and edges (``ShapeUpgrade_UnifySameDomain``)."""
    import cadquery as cq
    from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain

    unify = ShapeUpgrade_UnifySameDomain(shape.wrapped, True, True, False)
    unify.AllowInternalEdges(False)
    unify.Build()
    return cq.Shape.cast(unify.Shape())


def _single_solid(shape: Any, what: str) -> cq.Solid:
    import cadquery as cq

    solids = shape.Solids()
    if len(solids) != 1:
        raise CadfeatError(f"{what} gave {len(solids)} solids instead of one")
    return cq.Solid(solids[0].wrapped)


def fill_holes(shape: Any, holes: Sequence[Hole]) -> cq.Solid:
    """``shape`` with ``holes`` filled: fused with the solid of revolution of each hole's own profile,
    then same-domain faces unified so the filled host faces merge back into one face.

    Checks that the volume grew by exactly the filled profiles' volume (rel ``VOLUME_RTOL``).
    """
    return _fill(shape, holes, [hole_profile(shape, h) for h in holes])


def _fill(shape: Any, holes: Sequence[Hole], profiles: Sequence[HoleProfile]) -> cq.Solid:
    """``fill_holes`` with the holes' profiles already read."""
    from cadfeat.cad.export import shape_volume_mm3

    if not holes:
        return _single_solid(shape, "the part")
    plugs = [_revolved(p, np.asarray(h.centre, float), np.asarray(h.axis, float)) for p, h in zip(profiles, holes,
                                                                                                   strict=True)]
    filled = _single_solid(_unify(shape.fuse(*plugs)), "filling the holes")
    added = shape_volume_mm3(filled) - shape_volume_mm3(shape)
    expected = sum(p.volume_mm3 for p in profiles)
    if abs(added - expected) > VOLUME_RTOL * expected:
        raise CadfeatError(f"filling {', '.join(_label(h) for h in holes)} added {added:.9g} mm^3 instead of the "
                           f"holes' {expected:.9g} mm^3 (holes overlap each other or another feature)")
    return filled


def redrill(shape: Any, moves: Sequence[HoleMove]) -> cq.Solid:
    """Re-drill holes of ``shape``: fill each ``move.hole`` (``fill_holes``), then cut it again at
    ``move.centre`` with entrance radius ``move.radius_mm`` (profile scaled, same axis direction and depth),
    then unify same-domain faces. The rest of the solid is untouched.

    Validates before any CAD work that each new centre lies on its hole's host face plane (≤ 1e-6 mm).
    Afterwards checks that the cut removed exactly the new holes' volume (they lie inside the material
    and do not overlap), that through holes still come out at the same depth (the part is as thick at
    the new centre), and that the solid is valid.
    Raises ``CadfeatError`` naming the hole otherwise.
    """
    from cadfeat.cad.export import check_solid, shape_volume_mm3

    moves = list(moves)
    if not moves:
        return _single_solid(shape, "the part")
    for move in moves:
        _check_on_host_plane(move)
    old_profiles = [hole_profile(shape, m.hole) for m in moves]
    profiles = [p.scaled(m.radius_mm / m.hole.radius_mm) for p, m in zip(old_profiles, moves, strict=True)]
    filled = _fill(shape, [m.hole for m in moves], old_profiles)
    tools = [_revolved(p, m.centre, np.asarray(m.hole.axis, float)) for p, m in zip(profiles, moves, strict=True)]
    result = _single_solid(_unify(filled.cut(*tools)), "re-drilling the holes")
    removed = shape_volume_mm3(filled) - shape_volume_mm3(result)
    expected = sum(p.volume_mm3 for p in profiles)
    if abs(removed - expected) > VOLUME_RTOL * expected:
        raise CadfeatError(f"re-drilling {', '.join(_label(m.hole) for m in moves)} removed {removed:.9g} mm^3 "
                           f"instead of {expected:.9g} mm^3: a new hole breaks out of the part or overlaps "
                           "another hole")
    for profile, move in zip(profiles, moves, strict=True):
        if move.hole.through:
            _check_through(filled, move, profile.depth_mm)
    if problems := check_solid(result):
        raise CadfeatError(f"re-drilling gave an invalid solid: {'; '.join(problems[:5])}")
    return result


def _check_through(filled: Any, move: HoleMove, depth_mm: float) -> None:
    """A through hole must still exit at ``depth_mm``: material just above the exit, none just below."""
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.gp import gp_Pnt
    from OCP.TopAbs import TopAbs_IN, TopAbs_OUT

    axis = np.asarray(move.hole.axis, float)
    eps = min(1e-3, 0.25 * depth_mm)
    states = []
    for depth in (depth_mm - eps, depth_mm + eps):
        p = move.centre - depth * axis
        classifier = BRepClass3d_SolidClassifier(filled.wrapped, gp_Pnt(*p), 1e-9)
        states.append(classifier.State())
    if states != [TopAbs_IN, TopAbs_OUT]:
        raise CadfeatError(f"{_label(move.hole)}: the part is not {depth_mm:.6g} mm thick at the new centre "
                           f"{move.centre.tolist()}, so the through hole would not come out there")
