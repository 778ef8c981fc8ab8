"""The wall of a hole of revolution read from a B-rep, its resizing, and the solid it encloses.

A hole's wall is a stack of axial segments: cylinders, cones (countersinks, chamfers, drill points) and an
optional entrance fillet (a quarter torus blending the wall into the host plane). Real exports write one
wall as several partial faces (SolidWorks: two 180° halves) whose axes are a few 1e-6 mm / 1e-7 rad apart;
the faces are grouped with the model's tolerances (``cadfeat.cad.tolerance.ModelTolerance``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.cad.tolerance import ModelTolerance
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    import os

    import cadquery as cq
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.gp import gp_Dir, gp_Pnt, gp_Vec
    from OCP.TopoDS import TopoDS_Face, TopoDS_Shape

    from cadfeat.cad.features import Hole, ShapeLike
    from cadfeat.cad.tolerance import ModelTolerance

__all__ = ["CYLINDER", "CONE", "FILLET", "HoleProfile", "hole_profile", "hole_label", "revolved"]

CYLINDER, CONE, FILLET = 0, 1, 2
AREA_RTOL = 1e-4
"""Split wall faces must add up to the full 360° frustum area within this (relative) plus the model tolerance."""


@dataclass(frozen=True)
class HoleProfile:
    """The wall of a hole of revolution as axial segments (mm).

    ``segments[k] = (t0, t1, r0, r1)``: from depth ``t0`` to ``t1`` (from the entrance rim on the host plane
    into the material, along −axis) the radius goes from ``r0`` to ``r1``: linearly for a cylinder (r0 = r1)
    or a cone, along a quarter circle for a fillet of radius ρ = t1 − t0 = |r1 − r0| with centre (max r, depth
    of the smaller r): an entrance fillet (r0 > r1, centre (r0, t1)) or, on a through hole, an exit fillet
    blending the bore into the far face (r1 > r0, centre (r1, t0)). A step
    between segments is a flat annulus (counterbore floor). ``types[k]`` is ``CYLINDER``, ``CONE`` or
    ``FILLET``.
    """

    segments: np.ndarray  # (S, 4)
    types: np.ndarray     # (S,) int

    @property
    def conical(self) -> np.ndarray:
        """(S,) bool: which segments are cones."""
        return self.types == CONE

    @property
    def depth_mm(self) -> float:
        return float(self.segments[-1, 1])

    @property
    def volume_mm3(self) -> float:
        """Volume enclosed by the wall (mm³): Σ π h (r0² + r0 r1 + r1²) / 3 over cylinders and cones (frustums);
        an entrance fillet of radius ρ on a bore r encloses π r² ρ + 2π (r + x̄) ρ² (1 − π/4) with
        x̄ = ρ (5/6 − π/4) / (1 − π/4) (Pappus: the corner region the fillet takes away, about the axis)."""
        t0, t1, r0, r1 = self.segments.T
        h = t1 - t0
        frustum = np.pi * h * (r0 * r0 + r0 * r1 + r1 * r1) / 3.0
        rho = h
        xbar = rho * (5.0 / 6.0 - np.pi / 4.0) / (1.0 - np.pi / 4.0)
        bore = np.minimum(r0, r1)  # an exit fillet is the entrance one mirrored
        fillet = np.pi * bore * bore * rho + 2 * np.pi * (bore + xbar) * rho * rho * (1.0 - np.pi / 4.0)
        return float(np.sum(np.where(self.types == FILLET, fillet, frustum)))

    @property
    def lateral_area_mm2(self) -> float:
        """Area of the wall (mm², fillets counted as their cone), for volume tolerances."""
        t0, t1, r0, r1 = self.segments.T
        return float(np.sum(np.pi * (r0 + r1) * np.hypot(t1 - t0, r1 - r0)))

    def scaled(self, factor: float) -> HoleProfile:
        """Every radius times ``factor``: cones keep their angle (their length scales, a 90° countersink stays
        90°), fillets keep their radius, cylinders keep the depth where they end. Raises ``CadfeatError`` if a
        scaled cone would run past the next step."""
        segments = self.segments.copy()
        segments[:, 2:] *= factor
        for k in np.flatnonzero(self.types == FILLET):  # fillet radius kept: its outer radius follows the bore
            rho = self.segments[k, 1] - self.segments[k, 0]
            if self.segments[k, 2] >= self.segments[k, 3]:
                segments[k, 2] = segments[k, 3] + rho
            else:
                segments[k, 3] = segments[k, 2] + rho
        return self._restacked(segments)

    def resized(self, entrance_radius_mm: float, kind: str) -> HoleProfile:
        """The profile with its visible entrance radius set to ``entrance_radius_mm``.

        Plain holes (sharp, chamfered or filleted rim): the whole profile scales with the entrance (cones keep
        their angle, fillets their radius). Counterbores: only the counterbore (and its rim) widens or narrows,
        the screw bore below keeps its radius and depth. Countersinks: the cone keeps its angle and reaches
        the new entrance radius, the bore keeps its radius and its end depth. Raises ``CadfeatError`` if the
        new entrance would not be wider than the bore it leads into.
        """
        old = float(self.segments[0, 2])
        base = kind.partition(", ")[0]
        if base == "plain":
            if self.types[0] == FILLET:
                delta = entrance_radius_mm - old
                segments = self.segments.copy()
                segments[:, 2:] += np.where(segments[:, 2:] > 0, delta, 0.0)
                if np.any(segments[:, 2:] < 0) or segments[0, 3] <= 0:
                    raise CadfeatError(f"an entrance radius of {entrance_radius_mm:.6g} mm leaves no bore under "
                                       f"the {self.segments[0, 1]:.6g} mm fillet")
                return self._restacked(segments, keep_cone_ends=False)
            return self.scaled(entrance_radius_mm / old)
        radii = self.segments[self.types != FILLET][:, 2:]
        bore = float(np.min(radii[radii > 0]))
        if entrance_radius_mm <= bore:
            raise CadfeatError(f"a {base} entrance radius of {entrance_radius_mm:.6g} mm is not wider than its "
                               f"bore ({bore:.6g} mm); allowed: more than {bore:.6g} mm")
        segments = self.segments.copy()
        if base == "counterbore":
            radii = segments[:, 2:]
            radii += np.where(radii > bore + 1e-9, entrance_radius_mm - old, 0.0)
            return self._restacked(segments, keep_cone_ends=False)
        # countersink: the entrance cone from the new radius down to the radius it ends at, same angle
        k = int(np.flatnonzero(self.types == CONE)[0]) if np.any(self.types == CONE) else 0
        t0, t1, r0, r1 = self.segments[k]
        slope = (t1 - t0) / (r0 - r1) if r0 != r1 else 0.0
        segments[:k, 2:] += entrance_radius_mm - old
        segments[k, 2] = entrance_radius_mm
        segments[k, 1] = segments[k, 0] + slope * (entrance_radius_mm - r1)
        if k + 1 < len(segments) and segments[k, 1] >= segments[k + 1, 1]:
            raise CadfeatError(f"a countersink entrance radius of {entrance_radius_mm:.6g} mm makes its cone run "
                               f"past depth {segments[k + 1, 1]:.6g} mm")
        if k + 1 < len(segments):
            segments[k + 1, 0] = segments[k, 1]
        return HoleProfile(segments, self.types.copy())

    def _restacked(self, segments: np.ndarray, keep_cone_ends: bool = True) -> HoleProfile:
        """Segments re-chained from depth 0: cones (and fillets) take the length their radii need, the others
        keep the depth where they end."""
        t = 0.0
        out = segments.copy()
        for k in range(len(out)):  # segments of one hole: a handful
            t0, t1 = self.segments[k, :2]
            if self.types[k] == CONE and keep_cone_ends:
                r0, r1 = self.segments[k, 2:]
                ratio = (out[k, 2] - out[k, 3]) / (r0 - r1) if r0 != r1 else 1.0
                end = t + ratio * (t1 - t0)
            elif self.types[k] == FILLET:
                end = t + (t1 - t0)
            else:
                end = t1
            if end <= t:
                raise CadfeatError(f"resizing the hole makes its cone run past depth {t1:.6g} mm")
            out[k, :2] = (t, end)
            t = end
        for k in range(1, len(out)):  # a cone widening with depth (exit chamfer) keeps where it ends
            if self.types[k] == CONE and self.segments[k, 3] > self.segments[k, 2] and keep_cone_ends:
                length = out[k, 1] - out[k, 0]
                out[k, :2] = (self.segments[k, 1] - length, self.segments[k, 1])
                out[k - 1, 1] = out[k, 0]
                if out[k - 1, 1] <= out[k - 1, 0]:
                    raise CadfeatError(f"resizing the hole makes its exit cone run past depth {out[k - 1, 0]:.6g} mm")
        return HoleProfile(out, self.types.copy())


# --------------------------------------------------------------------------------------------- reading
def _vec(p: gp_Pnt | gp_Dir | gp_Vec) -> np.ndarray:
    return np.array([p.X(), p.Y(), p.Z()], dtype=float)


def hole_label(hole: Hole, path: str | os.PathLike[str] | None = None) -> str:
    """``"<file>: hole H2 at (x, y, z) mm"``, for error messages."""
    c = np.asarray(hole.centre, dtype=float)
    name = getattr(hole, "name", "") or "hole"
    where = f"{path}: " if path else ""
    return f"{where}hole {name} at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}) mm"


class _Reader:
    """Reads one hole's wall from the faces of a shape, with the model's tolerances."""

    def __init__(self, occ: TopoDS_Shape, hole: Hole, tol: ModelTolerance, label: str) -> None:
        self.occ, self.hole, self.label = occ, hole, label
        self.lin, self.ang = tol.linear_mm, tol.angular_rad
        self.centre = np.asarray(hole.centre, float)
        self.axis = np.asarray(hole.axis, float)

    def coaxial(self, location: gp_Pnt, direction: gp_Dir) -> bool:
        d = _vec(direction)
        return (np.linalg.norm(np.cross(d, self.axis)) <= self.ang
                and np.linalg.norm(np.cross(_vec(location) - self.centre, self.axis)) <= self.lin)

    def depth(self, p: np.ndarray) -> float:
        return float(np.dot(self.centre - p, self.axis))

    def levels(self, face: TopoDS_Face) -> tuple[list[tuple[float, float]], bool]:
        """(depth, radius) of each circular boundary of a wall face, and whether it has another boundary
        (an oblique entrance or exit, another feature cutting into it; ``self.span`` is then the depth range
        of those other boundaries). Straight edges in a plane through the axis (the seams between split wall
        faces) are skipped."""
        from OCP.BRep import BRep_Tool
        from OCP.BRepAdaptor import BRepAdaptor_Curve
        from OCP.GeomAbs import GeomAbs_Circle, GeomAbs_Line
        from OCP.TopAbs import TopAbs_EDGE
        from OCP.TopExp import TopExp_Explorer
        from OCP.TopoDS import TopoDS

        levels, other, span = [], False, (math.inf, -math.inf)
        explorer = TopExp_Explorer(face, TopAbs_EDGE)
        while explorer.More():
            edge = TopoDS.Edge_s(explorer.Current())
            explorer.Next()
            if BRep_Tool.Degenerated_s(edge) or BRep_Tool.IsClosed_s(edge, face):
                continue  # cone apex / seam
            curve = BRepAdaptor_Curve(edge)
            kind = curve.GetType()
            if kind == GeomAbs_Circle and self.coaxial(curve.Circle().Location(), curve.Circle().Axis().Direction()):
                circle = curve.Circle()
                levels.append((self.depth(_vec(circle.Location())), float(circle.Radius())))
                continue
            if kind == GeomAbs_Line and self._generator(curve):
                continue
            if kind not in (GeomAbs_Circle, GeomAbs_Line):  # B-spline trimming curves (Rhino writes every edge so)
                sampled = self._sampled(curve)
                if sampled == "seam":
                    continue
                if sampled is not None:
                    levels.append(sampled)
                    continue
            other = True
            ends = [self.depth(_vec(curve.Value(x))) for x in np.linspace(curve.FirstParameter(),
                                                                           curve.LastParameter(), 5)]
            span = (min(span[0], *ends), max(span[1], *ends))
        self.span = span
        return levels, other

    def _sampled(self, curve: BRepAdaptor_Curve, n: int = 9) -> tuple[float, float] | str | None:
        """A free-form edge that is a coaxial circle within the tolerance: its (depth, radius); a straight seam
        in a plane through the axis: ``"seam"``; anything else: None. From ``n`` points along the edge."""
        u = np.linspace(curve.FirstParameter(), curve.LastParameter(), n)
        pts = np.array([_vec(curve.Value(float(x))) for x in u])
        d = pts - self.centre
        t = d @ self.axis
        radial = d - np.outer(t, self.axis)
        r = np.linalg.norm(radial, axis=1)
        if np.ptp(t) <= self.lin and np.ptp(r) <= self.lin:
            return float(-t.mean()), float(r.mean())
        chord = pts[-1] - pts[0]
        length = float(np.linalg.norm(chord))
        if length > self.lin and r.min() > self.lin:
            off = np.linalg.norm(np.cross(pts - pts[0], chord / length), axis=1)
            normal = np.cross(self.axis, radial[n // 2] / r[n // 2])
            if off.max() <= self.lin and np.abs(d @ normal).max() <= self.lin + self.ang * length:
                return "seam"
        return None

    def _oblique(self) -> CadfeatError:
        return CadfeatError(f"{self.label}: its wall meets a face that is not perpendicular to its axis (oblique "
                            "entrance/exit, or another feature cuts into it); re-drilling supports holes that start "
                            "and end on planes perpendicular to their axis")

    def concave(self, face: TopoDS_Face) -> bool:
        """The face bounds the material from outside (a hole wall), not a boss, pin or outer rounded edge:
        its outward normal points towards the axis."""
        from OCP.BRepGProp import BRepGProp_Face
        from OCP.BRepTools import BRepTools
        from OCP.gp import gp_Pnt, gp_Vec

        u0, u1, v0, v1 = BRepTools.UVBounds_s(face)
        p, n = gp_Pnt(), gp_Vec()
        BRepGProp_Face(face).Normal(0.5 * (u0 + u1), 0.5 * (v0 + v1), p, n)
        d = _vec(p) - self.centre
        radial = d - (d @ self.axis) * self.axis
        return float(_vec(n) @ radial) < 0.0

    def _generator(self, curve: BRepAdaptor_Curve) -> bool:
        """A straight edge lying in a plane through the axis (a split seam of a cylinder or cone)."""
        a = _vec(curve.Value(curve.FirstParameter()))
        b = _vec(curve.Value(curve.LastParameter()))
        d = b - a
        mid = 0.5 * (a + b) - self.centre
        radial = mid - (mid @ self.axis) * self.axis
        if np.linalg.norm(d) < self.lin or np.linalg.norm(radial) < self.lin:
            return False
        normal = np.cross(self.axis, radial / np.linalg.norm(radial))
        return abs(float(d @ normal)) <= self.lin + self.ang * float(np.linalg.norm(d))

    def segment(self, face: TopoDS_Face) -> tuple[float, float, float, float, int, float] | None:
        """(t0, t1, r0, r1, type, area) of a face if it is part of the hole's wall, else None."""
        from OCP.BRepAdaptor import BRepAdaptor_Surface
        from OCP.GeomAbs import GeomAbs_Cone, GeomAbs_Cylinder, GeomAbs_Torus

        surface = BRepAdaptor_Surface(face)
        kind = surface.GetType()
        if kind == GeomAbs_Cylinder:
            ax, typ = surface.Cylinder().Axis(), CYLINDER
        elif kind == GeomAbs_Cone:
            ax, typ = surface.Cone().Axis(), CONE
        elif kind == GeomAbs_Torus:
            ax, typ = surface.Torus().Axis(), FILLET
        else:
            return None
        if not self.coaxial(ax.Location(), ax.Direction()):
            return None
        if typ == CYLINDER and surface.Cylinder().Radius() > self.hole.radius_mm + self.lin:
            return None  # a wider coaxial feature (a cradle, the outer wall of a lug)
        if typ != FILLET and not self.concave(face):
            return None  # a convex face round the hole: a boss, a lug's outer chamfer
        levels, other = self.levels(face)
        if other and typ != FILLET and (self.span[0] < -self.lin < self.lin < self.span[1] or not levels and (
                self.span[0] < self.hole.depth_mm - self.lin and self.span[1] > self.lin)):
            raise self._oblique()  # the hole's own wall runs past its entrance (an oblique rim) or has no round end
        if typ == CONE:
            apex = surface.Cone().Apex()
            if len({round(t / max(self.lin, 1e-12)) for t, _ in levels}) == 1:  # drill point: one rim + apex
                levels.append((self.depth(_vec(apex)), 0.0))
        if not levels:
            return None
        levels.sort()
        (t0, r0), (t1, r1) = levels[0], levels[-1]
        if typ == FILLET:
            entrance = abs(t0) <= self.lin and r0 <= self.hole.radius_mm + self.lin and r0 > r1
            exit_ = self.hole.through and abs(t1 - self.hole.depth_mm) <= self.lin and r1 > r0
            if not (entrance and self.hole.kind.endswith("filleted rim") or exit_):
                return None  # a fillet elsewhere on the axis
        elif (start := min(t0, self.span[0]) if other else t0) < -self.lin or start > self.hole.depth_mm - self.lin \
                or r0 > self.hole.radius_mm + self.lin:
            return None  # another coaxial feature (e.g. a boss on the far side, a cavity the hole opens into)
        if other:
            raise self._oblique()
        depth = self.hole.depth_mm
        if (typ != FILLET and self.hole.through and t1 > depth + self.lin
                and any(abs(t - depth) <= self.lin for t, _ in levels)):
            # the face runs on past the hole's exit plane (a sliver of the same cylinder above a plate, where
            # another wall is tangent to it): the hole's wall is the part of the face within its depth
            r1 = r0 + (r1 - r0) * (depth - t0) / (t1 - t0)
            return t0, depth, r0, r1, typ, self._area_within(face, t0, depth, max(r0, r1))
        return t0, t1, r0, r1, typ, _face_area(face)

    def _area_within(self, face: TopoDS_Face, t0: float, t1: float, radius: float) -> float:
        """Area (mm²) of the part of ``face`` between depths ``t0`` and ``t1`` (a Boolean common with a coaxial
        cylinder a little wider than the face)."""
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Common
        from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder
        from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt

        base = self.centre - t1 * self.axis  # the slab's far end; it grows back towards the entrance
        slab = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(*map(float, base)), gp_Dir(*map(float, self.axis))),
                                        2.0 * radius + 1.0, t1 - t0).Shape()
        common = BRepAlgoAPI_Common(face, slab)
        common.Build()
        if not common.IsDone():
            raise CadfeatError(f"{self.label}: could not cut its wall face at depth {t1:.6g} mm (OCCT Boolean failed)")
        return _face_area(common.Shape())


def _face_area(face: TopoDS_Shape) -> float:
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(face, props)
    return float(props.Mass())


def hole_profile(shape: ShapeLike, hole: Hole, tol: ModelTolerance | None = None,
                 path: str | os.PathLike[str] | None = None) -> HoleProfile:
    """The wall profile of ``hole`` read from the faces of ``shape`` (exact B-rep geometry).

    Collects the cylindrical and conical faces (and the entrance fillet of a ``"..., filleted rim"`` hole)
    coaxial with the hole within ``tol`` (default: scaled to ``shape``) that start between its entrance rim
    and its depth, groups split faces (their areas must add up to the full 360° wall) and checks that the
    segments follow each other from the entrance rim (depth 0, radius ``hole.radius_mm``) down.
    Raises ``CadfeatError`` naming the file (``path``) and the hole if the wall is not such a stack.
    """
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp
    from OCP.TopoDS import TopoDS
    from OCP.TopTools import TopTools_IndexedMapOfShape

    occ = shape.wrapped if hasattr(shape, "wrapped") else shape
    tol = tol or ModelTolerance.of_shape(occ)
    label = hole_label(hole, path)
    reader = _Reader(occ, hole, tol, label)
    faces = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(occ, TopAbs_FACE, faces)
    found = [s for i in range(1, faces.Extent() + 1) if (s := reader.segment(TopoDS.Face_s(faces.FindKey(i))))]
    if not found:
        raise CadfeatError(f"{label}: no wall face coaxial with the hole found in the shape")
    found.sort()
    groups: list[list[tuple[float, float, float, float, int, float]]] = []
    for seg in found:  # split faces of one segment: same depths within the tolerance
        if groups and abs(seg[0] - groups[-1][0][0]) <= tol.linear_mm and abs(seg[1] - groups[-1][0][1]) <= \
                tol.linear_mm and seg[4] == groups[-1][0][4]:
            groups[-1].append(seg)
        else:
            groups.append([seg])
    segments, types = [], []
    for parts in groups:
        t0, t1, r0, r1, typ, _ = parts[0]
        if typ == FILLET:
            rho = t1 - t0
            full = 2 * np.pi * rho * (np.pi / 2 * (min(r0, r1) + rho) - rho)  # quarter torus: 2π ∫ r ds
        else:
            full = np.pi * (r0 + r1) * math.hypot(t1 - t0, r1 - r0)
        got = sum(p[5] for p in parts)
        if abs(got - full) > AREA_RTOL * full + 2 * np.pi * max(r0, r1) * tol.linear_mm:
            raise CadfeatError(f"{label}: its wall between depths {t0:.6g} and {t1:.6g} mm is not a full circle "
                               f"({got / full * 360:.0f}° of 360°: a slot or another feature cuts into it)")
        segments.append((t0, t1, r0, r1))
        types.append(typ)
    profile = HoleProfile(np.array(segments, dtype=float), np.array(types, dtype=int))
    _check_profile(profile, hole, label, tol.linear_mm)
    return profile


def _check_profile(profile: HoleProfile, hole: Hole, label: str, lin: float) -> None:
    seg = profile.segments
    if abs(seg[0, 0]) > lin or abs(seg[0, 2] - hole.radius_mm) > lin:
        raise CadfeatError(f"{label}: its wall does not start at the entrance rim (depth {seg[0, 0]:.6g} mm, "
                           f"radius {seg[0, 2]:.6g} mm, expected 0 and {hole.radius_mm:.6g} mm)")
    gaps = np.abs(seg[1:, 0] - seg[:-1, 1])
    if np.any(gaps > lin):
        k = int(np.argmax(gaps))
        raise CadfeatError(f"{label}: its wall has a gap between depths {seg[k, 1]:.6g} and {seg[k + 1, 0]:.6g} mm")


# -------------------------------------------------------------------------------------------- solids
def revolved(profile: HoleProfile, centre: np.ndarray, axis: np.ndarray) -> cq.Solid:
    """Solid of revolution of ``profile`` about the line (centre, axis); depth runs along −axis. Fillet
    segments are exact quarter circles (the solid's face there is a torus, like the original)."""
    import cadquery as cq

    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    radial = np.cross(axis, helper)
    radial /= np.linalg.norm(radial)

    def at(r: float, t: float) -> cq.Vector:
        return cq.Vector(*(centre + r * radial - t * axis))

    edges = []
    cursor = (0.0, 0.0)
    for (t0, t1, r0, r1), typ in zip(profile.segments, profile.types, strict=True):
        for target in ((r0, t0),):
            if np.hypot(target[0] - cursor[0], target[1] - cursor[1]) > 1e-12:
                edges.append(cq.Edge.makeLine(at(*cursor), at(*target)))
                cursor = target
        if typ == FILLET:
            rho = t1 - t0
            r_c, t_c, t_plane = (r0, t1, t0) if r0 > r1 else (r1, t0, t1)  # entrance / exit fillet
            mid = (r_c - rho * math.sqrt(0.5), t_c + (t_plane - t_c) * math.sqrt(0.5))
            edges.append(cq.Edge.makeThreePointArc(at(r0, t0), at(*mid), at(r1, t1)))
        elif np.hypot(r1 - r0, t1 - t0) > 1e-12:
            edges.append(cq.Edge.makeLine(at(r0, t0), at(r1, t1)))
        cursor = (r1, t1)
    end = (0.0, profile.depth_mm)
    if np.hypot(end[0] - cursor[0], end[1] - cursor[1]) > 1e-12:
        edges.append(cq.Edge.makeLine(at(*cursor), at(*end)))
    edges.append(cq.Edge.makeLine(at(*end), at(0.0, 0.0)))
    face = cq.Face.makeFromWires(cq.Wire.assembleEdges(edges))
    return cq.Solid.revolve(face, 360.0, cq.Vector(*centre), cq.Vector(*(centre + axis)))
