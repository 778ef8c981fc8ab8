"""Hole extraction from an OCCT B-rep (imported lazily by ``cadfeat.cad.features.extract_holes``); its B-rep
primitives (topology, surfaces of revolution, sampling, areas, tolerances) are the private ``_brep`` module,
re-exported here.

Algorithm (docs/design.md "Known pitfalls"):

1. Classify every face: cylinders and cones are *concave* when the material lies outside them, i.e.
   the orientation-aware face normal (``BRepGProp_Face``, pointing out of the material) points towards
   the axis. Convex cylinders (bosses, pins, outer fillets) are dropped.
2. Union concave cylinders/cones that share an edge and are coaxial (OCCT may split one cylinder into
   several faces, with axes pointing either way). Planar faces perpendicular to that axis whose every
   edge is shared with such faces (counterbore steps, flat bottoms) join the group.
3. A group is a hole if its cylinders of one radius close over 360° (the union of their angular
   spans), so partial cylinders (fillets, slot ends) are not holes.
4. The group's boundary edges (shared with faces outside the group) form loops; loops that go round
   the axis are the hole's ends. An end is *open* when the point on the axis just beyond it is outside
   the solid (``BRepClass3d_SolidClassifier``). One open end: blind; two: through (the entrance is
   chosen as documented in ``extract_holes``). The axis is oriented from the hole out of the material.
5. The host face of an end is the outside face sharing most of its loop length; the centre is where
   the axis meets the host surface; the outline of planar host faces is sampled from the B-rep.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from OCP.BRep import BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Surface
from OCP.BRepClass3d import BRepClass3d_SolidClassifier
from OCP.BRepTools import BRepTools
from OCP.Geom import Geom_Line
from OCP.GeomAbs import GeomAbs_Plane, GeomAbs_Torus
from OCP.GeomAPI import GeomAPI_IntCS
from OCP.gp import gp_Dir, gp_Lin, gp_Pnt
from OCP.TopAbs import TopAbs_EDGE, TopAbs_OUT, TopAbs_WIRE
from OCP.TopExp import TopExp
from OCP.TopoDS import TopoDS
from OCP.TopTools import TopTools_IndexedMapOfShape

from cadfeat.cad.features import FaceOutline, Hole
from cadfeat.cad.features._brep import (
    ANGLE_TOL_RAD,
    AREA_RTOL,
    CHAMFER_MAX_BORE,
    CHAMFER_MAX_MM,
    CHAMFER_MAX_RATIO,
    CLASSIFY_STEP_MM,
    ENCIRCLING_MAX_GAP_RAD,
    LINEAR_TOL_MM,
    MIN_CURVE_POINTS,
    NEAR_ROUND_MIN_RAD,
    OBLIQUE_RIM_MM,
    SAMPLE_DEFLECTION_MM,
    _ccw,
    _covered_angle,
    _End,
    _face_normal_at_mid,
    _outer_area,
    _perpendicular_frame,
    _Revolution,
    _revolution,
    _sample_edge,
    _Topology,
    _UnionFind,
    _wire_polygon,
    _xyz,
)
from cadfeat.cad.features.identity import named
from cadfeat.cad.tolerance import ModelTolerance

__all__ = ["ANGLE_TOL_RAD", "AREA_RTOL", "CHAMFER_MAX_BORE", "CHAMFER_MAX_MM", "CHAMFER_MAX_RATIO", "CLASSIFY_STEP_MM",
           "ENCIRCLING_MAX_GAP_RAD", "LINEAR_TOL_MM", "MIN_CURVE_POINTS", "NEAR_ROUND_MIN_RAD", "OBLIQUE_RIM_MM",
           "SAMPLE_DEFLECTION_MM", "SkippedHole", "extract_holes", "extract_holes_and_skipped"]


STEP_WALL_MIN_RAD = np.radians(300.0)
"""Least angle the wider wall of a counterbore must close round the axis for its floor to be a step of the hole."""


@dataclass(frozen=True)
class SkippedHole:
    """A hole-like opening that is not extracted (mm): a concave partial cylinder of ``span_deg`` < 360°
    (3-D-printing teardrop, D-bore, keyed bore), with its axis, a point on the axis and the reason."""

    centre: np.ndarray
    axis: np.ndarray
    radius_mm: float
    span_deg: float
    reason: str


class _Extractor:
    def __init__(self, shape, prefer_direction: Sequence[float] | np.ndarray | None, tol=None) -> None:
        self.shape = shape.wrapped
        self.topo = _Topology.build(self.shape)
        self.tol = tol if tol is not None else ModelTolerance.of_shape(self.shape)
        self.lin, self.ang = self.tol.linear_mm, self.tol.angular_rad
        self.skipped: list[SkippedHole] = []
        self.prefer = None if prefer_direction is None else np.asarray(prefer_direction, dtype=float)
        self.samples: dict[int, np.ndarray] = {}
        self.areas: dict[int, float] = {}
        self.classifier = BRepClass3d_SolidClassifier(self.shape)
        self.revs = {i: r for i, f in enumerate(self.topo.faces) if (r := _revolution(i, f)) is not None}

    # -------------------------------------------------------------------------------------- helpers
    def edge_points(self, e: int) -> np.ndarray:
        if e not in self.samples:
            self.samples[e] = _sample_edge(self.topo.edges[e])
        return self.samples[e]

    def area(self, f: int) -> float:
        """Outer-wire area of face f (mm², cached)."""
        if f not in self.areas:
            self.areas[f] = _outer_area(self.topo.faces[f])
        return self.areas[f]

    def is_outside(self, point: np.ndarray) -> bool:
        self.classifier.Perform(gp_Pnt(*map(float, point)), min(1e-7, 0.1 * self.lin))
        return self.classifier.State() == TopAbs_OUT

    # ------------------------------------------------------------------------------------- grouping
    def groups(self) -> list[list[int]]:
        """Connected sets of coaxial concave cylinders/cones plus their perpendicular planar steps."""
        concave = {i: r for i, r in self.revs.items() if r.concave}
        uf = _UnionFind()
        for i in concave:
            uf.find(i)
        for fs in self.topo.edge_faces:
            for a in fs:
                for b in fs:
                    if a < b and a in concave and b in concave and concave[a].coaxial(concave[b], self.lin, self.ang):
                        uf.union(a, b)
        for f, face in enumerate(self.topo.faces):
            if f not in self.revs and BRepAdaptor_Surface(face).GetType() == GeomAbs_Plane:
                self._join_planar_step(f, face, concave, uf)
        return [g for g in uf.groups() if any(f in concave for f in g)]

    def _join_planar_step(self, f: int, face, concave: dict[int, _Revolution], uf: _UnionFind) -> None:
        """Join a planar annulus (counterbore floor, flat bottom) to the coaxial concave faces around it; the
        other half of an annulus written as two faces (split walls) may share its seam edges."""
        neighbours = set()
        halves = set()
        crowded = False  # the face also meets other features (slots, pockets cut into the step)
        p, normal, _ = _face_normal_at_mid(face)
        for e in self.topo.face_edges[f]:
            if BRep_Tool.Degenerated_s(self.topo.edges[e]):
                continue
            others = [g for g in self.topo.edge_faces[e] if g != f]
            if not others:
                return
            for g in others:
                if g in concave:
                    neighbours.add(g)
                elif self._coplanar(g, p, normal):
                    halves.add(g)
                else:
                    crowded = True
        if not neighbours:
            return
        revs = [concave[g] for g in sorted(neighbours)]
        if crowded:
            wide = max((r for r in revs if not r.is_cone), key=lambda r: r.r0, default=revs[0])
            revs = [r for r in revs if wide.coaxial(r, self.lin, self.ang)]
            if not self._is_step_between(f, p, normal, revs):
                return
        if (np.linalg.norm(np.cross(normal, revs[0].d)) > self.ang
                or not all(revs[0].coaxial(r, self.lin, self.ang) for r in revs[1:])):
            return
        if not self._outer_wall_closes(revs, concave, uf):
            return
        for r in revs:
            uf.union(f, r.face)
        for g in halves:
            uf.union(f, g)

    def _outer_wall_closes(self, revs: list[_Revolution], concave: dict[int, _Revolution], uf: _UnionFind) -> bool:
        """A step between cylinders of two radii is a counterbore floor only if the wider wall closes at least
        ``STEP_WALL_MIN_RAD`` round the axis (a slot cutting a narrow gap into a counterbore leaves it one). A
        seat whose wall is open over more (it breaks out of a side face: a Ø5.9 seat closing 266°; a bearing
        seat with twelve notches closing 272°) is another feature the hole opens into: the plane is then the
        hole's end, not a step of it, and the hole reads as through, as deep as its own bore."""
        cylinders = [r for r in revs if not r.is_cone]
        if len(cylinders) < 2:
            return True
        r_min = min(c.r0 for c in cylinders)
        r_max = max(c.r0 for c in cylinders)
        if r_max <= r_min + self.lin:
            return True
        # the whole wall: the plane may be one half of a split annulus, touching one half of a split wall
        roots = {uf.find(c.face) for c in cylinders if c.r0 >= r_max - self.lin}
        wide = [r for f, r in concave.items() if not r.is_cone and abs(r.r0 - r_max) <= self.lin
                and uf.find(f) in roots]
        return _covered_angle(wide, wide[0].d, self.ang) >= STEP_WALL_MIN_RAD

    def _is_step_between(self, f: int, p: np.ndarray, normal: np.ndarray, revs: list[_Revolution]) -> bool:
        """A plane that also meets other features is still the step of a stepped bore if it meets coaxial
        concave cylinders of at least two radii, the wider ones wholly on its outward side and the narrowest
        wholly on its inner side (a groove around a hole on a face does not qualify)."""
        cylinders = [r for r in revs if not r.is_cone]
        if len(cylinders) < 2 or not all(cylinders[0].coaxial(r, self.lin, self.ang) for r in cylinders[1:]):
            return False
        r_min, r_max = min(c.r0 for c in cylinders), max(c.r0 for c in cylinders)
        if r_max <= r_min + self.lin:
            return False
        for c in cylinders:
            pts = np.concatenate([self.edge_points(e) for e in self.topo.face_edges[c.face]])
            side = (pts - p) @ normal
            if c.r0 >= r_max - self.lin and side.min() < -self.lin:
                return False
            if c.r0 <= r_min + self.lin and side.max() > self.lin:
                return False
        return True

    def _coplanar(self, g: int, p: np.ndarray, normal: np.ndarray) -> bool:
        """Face g is a plane through point p with the same normal (within the model tolerance)."""
        face = self.topo.faces[g]
        if BRepAdaptor_Surface(face).GetType() != GeomAbs_Plane:
            return False
        q, n, _ = _face_normal_at_mid(face)
        return np.linalg.norm(np.cross(n, normal)) <= self.ang and abs(float((q - p) @ normal)) <= self.lin

    # --------------------------------------------------------------------------------------- a hole
    def hole(self, group: list[int]) -> tuple[Hole, set[int]] | None:
        """The hole of a face group (None if it is not a hole) and the edges of all its open rims."""
        revs = [self.revs[f] for f in group if f in self.revs]
        cylinders = [r for r in revs if not r.is_cone]
        if not cylinders:
            return None
        by_radius: dict[float, list[_Revolution]] = {}
        for c in cylinders:
            key = next((k for k in by_radius if abs(k - c.r0) < self.lin), c.r0)
            by_radius.setdefault(key, []).append(c)
        ref = cylinders[0]
        covered = {k: _covered_angle(cs, ref.d, self.ang) for k, cs in by_radius.items()}
        if not any(a >= 2 * np.pi - 2 * self.ang for a in covered.values()):
            self._note_near_round(by_radius, covered, ref)
            return None
        members = set(group)
        face_edges = sorted({e for f in group for e in self.topo.face_edges[f]})
        rim = [e for e in face_edges if any(g not in members for g in self.topo.edge_faces[e])]
        pts = [self.edge_points(e) for e in face_edges]
        vidx = sorted({v for e in face_edges for v in self.topo.edge_vertices[e]})
        all_pts = np.concatenate(pts + [self.topo.vertex_points[vidx]])
        t_mid = float(ref.t(all_pts).mean())
        ends = [end for loop in self._loops(rim, ref) if (end := self._open_end(loop, ref, t_mid, members))]
        if not ends:
            return None
        entrance = self._entrance(ends)
        exits = [e for e in ends if e.sense != entrance.sense]
        depth = self._depth(entrance, exits, ref, all_pts)
        bore = min(c.r0 for c in cylinders)
        # a hole is empty inside: not an annular groove round a boss (material at half its radius)
        mid = entrance.centre - 0.5 * depth * entrance.axis
        e1, _ = _perpendicular_frame(ref.d)
        if not all(self.is_outside(mid + k * 0.5 * bore * e1) for k in (1.0, -1.0)):
            return None
        kind = self._kind(entrance, revs, bore)
        hole = Hole(centre=entrance.centre + 0.0, axis=entrance.axis + 0.0, radius_mm=entrance.radius,
                    bore_radius_mm=bore, depth_mm=depth, through=bool(exits), kind=kind,
                    host_face=entrance.host, outline=None)
        return hole, {e for end in ends for e in end.edges}

    def _kind(self, entrance: _End, revs: list[_Revolution], bore: float) -> str:
        """plain / counterbore / countersink, with ", chamfered rim" or ", filleted rim" when the entrance
        rim is a small cone (widening the bore under it by at most max(min(``CHAMFER_MAX_MM``, ``CHAMFER_MAX_BORE``
        × its radius), ``CHAMFER_MAX_RATIO`` × its radius): a 1 × 45° chamfer on a Ø4 bore, 0.5 × 45° on Ø8; a Ø6
        countersink on Ø3.4 is wider, and so are Ø3.8 over Ø1.8 and Ø0.25 over Ø0.125: a small bore's 1 mm is less) or a
        fillet (torus) blending into the host face."""
        if entrance.wall.is_cone:
            below = [r for r in revs if not r.is_cone]
            # the cylinder the entrance cone leads into: the widest one narrower than the cone's rim
            under = max((c.r0 for c in below if c.r0 < entrance.radius - self.lin), default=bore)
            chamfer_max = max(min(CHAMFER_MAX_MM, CHAMFER_MAX_BORE * under), CHAMFER_MAX_RATIO * under)
            if entrance.radius - under <= chamfer_max + self.lin:
                base = "counterbore" if under > bore + self.lin else "plain"
                return f"{base}, chamfered rim"
            return "countersink"
        base = "counterbore" if entrance.wall.r0 > bore + self.lin else "plain"
        return f"{base}, filleted rim" if entrance.rim == "fillet" else base

    def _note_near_round(self, by_radius: dict[float, list[_Revolution]], covered: dict[float, float],
                         ref: _Revolution) -> None:
        """Record the group as a skipped near-round hole if a radius of it covers ≥ ``NEAR_ROUND_MIN_RAD``."""
        radius = max(covered, key=lambda k: covered[k])
        angle = covered[radius]
        if angle < NEAR_ROUND_MIN_RAD:
            return
        wall = by_radius[radius][0]
        pts = np.concatenate([self.edge_points(e) for f in (c.face for c in by_radius[radius])
                              for e in self.topo.face_edges[f]])
        t = wall.t(pts)
        centre = wall.loc + 0.5 * (t.min() + t.max()) * wall.d
        self.skipped.append(SkippedHole(centre, wall.d + 0.0, float(radius), float(np.degrees(angle)),
                                        f"near-round: its wall closes {np.degrees(angle):.0f}° of 360° (a "
                                        "3-D-printing teardrop, D-bore or keyed bore); only round holes are "
                                        "extracted"))

    def _loops(self, rim: list[int], ref: _Revolution) -> list[list[int]]:
        """Rim edges joined by shared vertices; only loops that go round the axis are kept."""
        uf = _UnionFind()
        by_vertex: dict[int, int] = {}
        for e in rim:
            uf.find(e)
            for v in self.topo.edge_vertices[e]:
                if v in by_vertex:
                    uf.union(e, by_vertex[v])
                by_vertex[v] = e
        e1, e2 = _perpendicular_frame(ref.d)
        loops = []
        for loop in uf.groups():
            p = np.concatenate([self.edge_points(e) for e in loop]) - ref.loc
            if len(p) < 3:
                continue
            angles = np.sort(np.arctan2(p @ e2, p @ e1))
            gaps = np.diff(np.append(angles, angles[0] + 2 * np.pi))
            if gaps.max() < ENCIRCLING_MAX_GAP_RAD:
                loops.append(loop)
        return loops

    def _open_end(self, loop: list[int], ref: _Revolution, t_mid: float, members: set[int]) -> _End | None:
        p = np.concatenate([self.edge_points(e) for e in loop])
        t = ref.t(p)
        sense = 1.0 if t.mean() >= t_mid else -1.0
        t_extreme = float(t.max() if sense > 0 else t.min())
        step = max(CLASSIFY_STEP_MM, 10 * self.lin)
        beyond = ref.loc + (t_extreme + sense * step) * ref.d
        if not self.is_outside(beyond):
            return None
        # the rim's own disc must be open too, not only the axis (the outer wall of a groove round a hole)
        radial = p - ref.loc - np.outer(ref.t(p), ref.d)
        r_rim = float(np.linalg.norm(radial, axis=1).min())
        if r_rim > 10 * self.lin and not self.is_outside(beyond + 0.9 * r_rim * radial[0] / np.linalg.norm(radial[0])):
            return None
        weights: dict[int, float] = {}
        walls: set[int] = set()
        for e in loop:
            q = self.edge_points(e)
            length = float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum()) if len(q) > 1 else 0.0
            for g in self.topo.edge_faces[e]:
                if g in members:
                    walls.add(g)
                else:
                    weights[g] = weights.get(g, 0.0) + length
        host = min(weights, key=lambda g: (-weights[g], g))
        wall = self._end_wall(walls, members, ref, t_extreme)
        blend = self._fillet_blend(host, ref, members)
        if blend is not None:
            plane, outer_edges, radius = blend
            centre = self._axis_meets_face(plane, ref, p)
            return _End(loop + outer_edges, sense, plane, centre, sense * ref.d, radius, wall, self.area(plane),
                        rim="fillet", blend=[host])
        curved = BRepAdaptor_Surface(self.topo.faces[host]).GetType() != GeomAbs_Plane
        if curved and float(np.ptp(t)) > OBLIQUE_RIM_MM + self.lin and sense * (t_extreme - ref.t(
                self._axis_meets_face(host, ref, p))) > self.lin:
            # a saddle rim on a curved host whose wall runs out past where the axis meets it (a passage or a
            # radial hole opening into a bore): the end is where the wall ends along the axis
            centre = ref.loc + t_extreme * ref.d
        else:
            centre = self._axis_meets_face(host, ref, p)
        return _End(loop, sense, host, centre, sense * ref.d, wall.radius_at(centre), wall, self.area(host))

    def _end_wall(self, walls: set[int], members: set[int], ref: _Revolution, t_end: float) -> _Revolution:
        """The cylinder or cone of the hole at an end: one the rim loop runs along, else (the loop runs along a
        planar step of the group only) the member nearest the end along the axis."""
        if on_loop := [w for w in walls if w in self.revs]:
            return self.revs[min(on_loop)]

        def distance(f: int) -> float:
            pts = np.concatenate([self.edge_points(e) for e in self.topo.face_edges[f]])
            return float(np.min(np.abs(ref.t(pts) - t_end)))

        return self.revs[min((m for m in members if m in self.revs), key=lambda m: (distance(m), m))]

    def _fillet_blend(self, f: int, ref: _Revolution, members: set[int]) -> tuple[int, list[int], float] | None:
        """If face ``f`` is a fillet (torus coaxial with the hole) between the hole wall and a plane
        perpendicular to the axis: (that plane, the fillet's edges on it, their radius mm); else None."""
        surf = BRepAdaptor_Surface(self.topo.faces[f])
        if surf.GetType() != GeomAbs_Torus:
            return None
        ax = surf.Torus().Position()
        loc, d = _xyz(ax.Location()), _xyz(ax.Direction())
        if (np.linalg.norm(np.cross(d, ref.d)) > self.ang
                or np.linalg.norm(np.cross(loc - ref.loc, ref.d)) > self.lin):
            return None
        weights: dict[int, float] = {}
        edges: dict[int, list[int]] = {}
        for e in self.topo.face_edges[f]:
            q = self.edge_points(e)
            length = float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum()) if len(q) > 1 else 0.0
            for g in self.topo.edge_faces[e]:
                if g != f and g not in members:
                    weights[g] = weights.get(g, 0.0) + length
                    edges.setdefault(g, []).append(e)
        planes = [g for g in weights if BRepAdaptor_Surface(self.topo.faces[g]).GetType() == GeomAbs_Plane]
        if not planes:
            return None
        plane = max(planes, key=lambda g: (weights[g], -g))
        _, normal, _ = _face_normal_at_mid(self.topo.faces[plane])
        if np.linalg.norm(np.cross(normal, ref.d)) > self.ang:
            return None
        pts = np.concatenate([self.edge_points(e) for e in edges[plane]])
        radial = pts - ref.loc - np.outer(ref.t(pts), ref.d)
        return plane, edges[plane], float(np.linalg.norm(radial, axis=1).mean())

    def _axis_meets_face(self, f: int, ref: _Revolution, rim_points: np.ndarray) -> np.ndarray:
        """Where the hole axis meets the host surface (nearest the rim); the rim's mean axis point otherwise."""
        face = self.topo.faces[f]
        t_rim = float(ref.t(rim_points).mean())
        if BRepAdaptor_Surface(face).GetType() == GeomAbs_Plane:
            p, n, _ = _face_normal_at_mid(face)
            dn = float(ref.d @ n)
            if abs(dn) > self.ang:
                return ref.loc + ((p - ref.loc) @ n / dn) * ref.d
        inter = GeomAPI_IntCS(Geom_Line(gp_Lin(gp_Pnt(*ref.loc), gp_Dir(*ref.d))), BRep_Tool.Surface_s(face))
        if inter.IsDone() and inter.NbPoints() > 0:
            cands = np.array([_xyz(inter.Point(i)) for i in range(1, inter.NbPoints() + 1)])
            return cands[int(np.argmin(np.abs(ref.t(cands) - t_rim)))]
        return ref.loc + t_rim * ref.d

    def _entrance(self, ends: list[_End]) -> _End:
        """The entrance rim: larger radius, then prefer_direction, then not inside another bore, then larger host
        area, then (z, y, x)."""
        best = ends[0]
        for other in ends[1:]:
            if self._better(other, best):
                best = other
        return best

    def _inside_a_bore(self, end: _End) -> bool:
        """The end opens into another hole's bore or a concave cavity (its host is a concave cylinder or cone,
        e.g. a radial set-screw hole's inner end on the shaft bore): no drill or camera enters there."""
        rev = self.revs.get(end.host)
        return rev is not None and rev.concave

    def _better(self, a: _End, b: _End) -> bool:
        if abs(a.radius - b.radius) > self.lin:
            return a.radius > b.radius
        if self.prefer is not None:
            da, db = float(a.axis @ self.prefer), float(b.axis @ self.prefer)
            if abs(da - db) > self.ang:
                return da > db
        if (inside_a := self._inside_a_bore(a)) != self._inside_a_bore(b):
            return not inside_a  # before the host area: a shaft bore's wall is larger than a nut-slot face
        if abs(a.area - b.area) > AREA_RTOL * max(a.area, b.area):
            return a.area > b.area
        ka = tuple(np.round(a.axis[::-1], _ORDER))
        kb = tuple(np.round(b.axis[::-1], _ORDER))
        return ka > kb

    def _depth(self, entrance: _End, exits: list[_End], ref: _Revolution, all_pts: np.ndarray) -> float:
        """Along the axis from the entrance centre to the farthest point of the wall: the exit plane of a
        through hole with a perpendicular exit, where the wall ends at an oblique or saddle exit (the axial
        length of the wall), the deepest point of a blind hole.

        A wall face that runs on past a perpendicular planar exit (a sliver of the same cylinder continuing
        above a plate where another wall is tangent to it) is not the hole: its depth stops at the exit plane."""
        t_c = float(ref.t(entrance.centre))
        planes = [abs(t_c - float(ref.t(e.centre))) for e in exits]  # an exit fillet's plane
        if exits and all(self._perpendicular_plane(e.host, ref) for e in exits):
            return max(planes)
        wall = float(np.max(entrance.sense * (t_c - ref.t(all_pts))))
        return max([wall] + planes)

    def _perpendicular_plane(self, f: int, ref: _Revolution) -> bool:
        """Face f is a plane perpendicular to the axis of ``ref``."""
        face = self.topo.faces[f]
        if BRepAdaptor_Surface(face).GetType() != GeomAbs_Plane:
            return False
        _, n, _ = _face_normal_at_mid(face)
        return float(np.linalg.norm(np.cross(n, ref.d))) <= self.ang

    # ------------------------------------------------------------------------------------- outlines
    def outline(self, f: int, rim_edges: set[int]) -> FaceOutline | None:
        """Outline of a planar face; inner wires made only of extracted holes' rim edges are left out."""
        face = self.topo.faces[f]
        surf = BRepAdaptor_Surface(face)
        if surf.GetType() != GeomAbs_Plane:
            return None
        plane = surf.Plane()
        origin = _xyz(plane.Location())
        _, n, _ = _face_normal_at_mid(face)
        x = _xyz(plane.Position().XDirection())
        u = x - (x @ n) * n
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        outer_wire = BRepTools.OuterWire_s(face)
        wmap = TopTools_IndexedMapOfShape()
        TopExp.MapShapes_s(face, TopAbs_WIRE, wmap)
        emap = TopTools_IndexedMapOfShape()
        TopExp.MapShapes_s(self.shape, TopAbs_EDGE, emap)
        outer, keepouts = None, []
        for i in range(1, wmap.Extent() + 1):
            wire = TopoDS.Wire_s(wmap.FindKey(i))
            poly = _ccw(_wire_polygon(wire, face, origin, u, v))
            if wire.IsSame(outer_wire):
                outer = poly
                continue
            wire_edges = TopTools_IndexedMapOfShape()
            TopExp.MapShapes_s(wire, TopAbs_EDGE, wire_edges)
            ids = {emap.FindIndex(wire_edges.FindKey(j)) - 1 for j in range(1, wire_edges.Extent() + 1)}
            if not ids <= rim_edges:
                keepouts.append(poly)
        keepouts.sort(key=lambda k: tuple(np.round(k.mean(axis=0), _ORDER)))
        return FaceOutline(origin=origin, u=u, v=v, outer=outer, keepouts=tuple(keepouts))


_ORDER = 9


def extract_holes(shape, prefer_direction: Sequence[float] | np.ndarray | None = None, tol=None) -> list[Hole]:
    """See ``cadfeat.cad.features.extract_holes``; ``shape`` is a ``cadquery.Shape``."""
    return extract_holes_and_skipped(shape, prefer_direction, tol)[0]


def extract_holes_and_skipped(shape, prefer_direction: Sequence[float] | np.ndarray | None = None,
                              tol=None) -> tuple[list[Hole], list[SkippedHole]]:
    """The holes (as ``extract_holes``, named ``H1`` … in their order) and the skipped near-round openings, with
    tolerances ``tol`` (``ModelTolerance``; default: scaled to ``shape``)."""
    ex = _Extractor(shape, prefer_direction, tol)
    found = [h for g in ex.groups() if (h := ex.hole(g)) is not None]
    rim_edges = set().union(*(edges for _, edges in found)) if found else set()
    outlines: dict[int, FaceOutline | None] = {}
    holes = []
    for hole, _ in found:
        if hole.host_face not in outlines:
            outlines[hole.host_face] = ex.outline(hole.host_face, rim_edges)
        holes.append(_with_outline(hole, outlines[hole.host_face]))
    holes.sort(key=lambda h: (tuple(np.round(h.axis, _ORDER)), tuple(np.round(h.centre, _ORDER))))
    holes = named(holes)  # a hole is named from extraction on: H1 … in this order (identity.DEFAULT_NAME)
    skipped: list[SkippedHole] = []
    for h in sorted(ex.skipped, key=lambda h: -h.radius_mm):  # one entry per axis line (stepped teardrops)
        if not any(np.linalg.norm(np.cross(h.axis, k.axis)) < ex.ang
                   and np.linalg.norm(np.cross(h.centre - k.centre, k.axis)) < ex.lin for k in skipped):
            skipped.append(h)
    skipped.sort(key=lambda h: (tuple(np.round(h.axis, 6)), tuple(np.round(h.centre, 6))))
    return holes, skipped


def _with_outline(hole: Hole, outline: FaceOutline | None) -> Hole:
    return replace(hole, outline=outline)
