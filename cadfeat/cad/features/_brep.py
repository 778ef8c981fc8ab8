"""B-rep primitives of hole extraction (private; ``extraction`` uses them): the face-edge topology, concave
surfaces of revolution and their angular cover, edge and wire sampling, face areas, and the tolerances and
limits the extractor starts from. Units mm and rad, part frame."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from OCP.BRep import BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve, BRepAdaptor_Surface
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
from OCP.BRepGProp import BRepGProp, BRepGProp_Face
from OCP.BRepTools import BRepTools, BRepTools_WireExplorer
from OCP.GCPnts import GCPnts_QuasiUniformDeflection
from OCP.GeomAbs import GeomAbs_Cone, GeomAbs_Cylinder, GeomAbs_Line
from OCP.gp import gp_Dir, gp_Pnt, gp_Vec
from OCP.GProp import GProp_GProps
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_REVERSED, TopAbs_VERTEX
from OCP.TopExp import TopExp
from OCP.TopoDS import TopoDS
from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape, TopTools_IndexedMapOfShape

from cadfeat.cad.features import OUTLINE_CHORD_ERROR_MM

ANGLE_TOL_RAD = 1e-7  # defaults only: the extractor uses the model's ModelTolerance (cadfeat.cad.tolerance)
LINEAR_TOL_MM = 1e-6
CLASSIFY_STEP_MM = 1e-4  # least step beyond an end along the axis for the inside/outside test (10× linear tol)
NEAR_ROUND_MIN_RAD = np.radians(200.0)  # a concave partial cylinder spanning at least this is a near-round hole
CHAMFER_MAX_RATIO = 0.35  # an entrance cone widening the bore by at most max(CHAMFER_MAX_MM, this × bore radius)
CHAMFER_MAX_MM = 1.0      # is a chamfered rim (a 1 × 45° chamfer on an M4 bore), a wider one a countersink;
CHAMFER_MAX_BORE = 0.9    # CHAMFER_MAX_MM at most this × the bore radius: a cone that about doubles the bore's
#                           diameter is a countersink's seat, on a small bore or a small part too (Ø0.25 over Ø0.125)
SAMPLE_DEFLECTION_MM = OUTLINE_CHORD_ERROR_MM / 2
MIN_CURVE_POINTS = 17  # per curved edge, so that a loop's angular gaps stay small
ENCIRCLING_MAX_GAP_RAD = np.pi / 4
AREA_RTOL = 1e-6
OBLIQUE_RIM_MM = 1e-3  # a rim loop spanning more than this along the axis is not perpendicular to it


def _xyz(p: gp_Pnt | gp_Vec | gp_Dir) -> np.ndarray:
    return np.array([p.X(), p.Y(), p.Z()])


class _UnionFind:
    def __init__(self) -> None:
        self.parent: dict[int, int] = {}

    def find(self, a: int) -> int:
        self.parent.setdefault(a, a)
        while self.parent[a] != a:
            self.parent[a] = self.parent[self.parent[a]]
            a = self.parent[a]
        return a

    def union(self, a: int, b: int) -> None:
        ra, rb = self.find(a), self.find(b)
        if ra != rb:
            self.parent[max(ra, rb)] = min(ra, rb)

    def groups(self) -> list[list[int]]:
        out: dict[int, list[int]] = {}
        for a in sorted(self.parent):
            out.setdefault(self.find(a), []).append(a)
        return list(out.values())


@dataclass
class _Topology:
    """Indexed faces/edges/vertices of a shape (0-based, in ``cadquery.Shape.Faces()`` order) and adjacency."""

    faces: list
    edges: list
    edge_faces: list[list[int]]
    face_edges: list[list[int]]
    edge_vertices: list[tuple[int, ...]]
    vertex_points: np.ndarray

    @classmethod
    def build(cls, shape) -> _Topology:
        def indexed(kind):
            m = TopTools_IndexedMapOfShape()
            TopExp.MapShapes_s(shape, kind, m)
            return m

        fmap, emap, vmap = indexed(TopAbs_FACE), indexed(TopAbs_EDGE), indexed(TopAbs_VERTEX)
        faces = [TopoDS.Face_s(fmap.FindKey(i)) for i in range(1, fmap.Extent() + 1)]
        edges = [TopoDS.Edge_s(emap.FindKey(i)) for i in range(1, emap.Extent() + 1)]
        anc = TopTools_IndexedDataMapOfShapeListOfShape()
        TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, anc)
        edge_faces: list[list[int]] = [[] for _ in edges]
        for i in range(1, anc.Extent() + 1):
            e = emap.FindIndex(anc.FindKey(i)) - 1
            edge_faces[e] = sorted({fmap.FindIndex(f) - 1 for f in anc.FindFromIndex(i)})
        face_edges: list[list[int]] = [[] for _ in faces]
        for e, fs in enumerate(edge_faces):
            for f in fs:
                face_edges[f].append(e)
        edge_vertices = [tuple(sorted({vmap.FindIndex(TopExp.FirstVertex_s(e)) - 1,
                                       vmap.FindIndex(TopExp.LastVertex_s(e)) - 1})) for e in edges]
        vertex_points = np.array([_xyz(BRep_Tool.Pnt_s(TopoDS.Vertex_s(vmap.FindKey(i))))
                                  for i in range(1, vmap.Extent() + 1)]).reshape(-1, 3)
        return cls(faces, edges, edge_faces, face_edges, edge_vertices, vertex_points)


def _face_normal_at_mid(face) -> tuple[np.ndarray, np.ndarray, tuple[float, float, float, float]]:
    """Point (3,) and outward unit normal (3,) at the middle of the face's UV box, and the UV box."""
    bounds = BRepTools.UVBounds_s(face)
    u, v = 0.5 * (bounds[0] + bounds[1]), 0.5 * (bounds[2] + bounds[3])
    p, n = gp_Pnt(), gp_Vec()
    BRepGProp_Face(face).Normal(u, v, p, n)
    normal = _xyz(n)
    return _xyz(p), normal / np.linalg.norm(normal), bounds


@dataclass
class _Revolution:
    """A cylindrical or conical face: axis (loc, d), radius r0 at loc growing as ``tan_angle`` along d."""

    face: int
    is_cone: bool
    loc: np.ndarray
    d: np.ndarray
    r0: float
    tan_angle: float
    concave: bool
    x_dir: np.ndarray
    y_dir: np.ndarray
    u_bounds: tuple[float, float]

    def t(self, points: np.ndarray) -> np.ndarray:
        return (points - self.loc) @ self.d

    def radius_at(self, point: np.ndarray) -> float:
        return max(0.0, self.r0 + float(self.t(point)) * self.tan_angle)

    def coaxial(self, other: _Revolution, lin: float = LINEAR_TOL_MM, ang: float = ANGLE_TOL_RAD) -> bool:
        """Same axis line: axes parallel within ``ang`` (rad), ``other``'s axis point within ``lin`` (mm)."""
        return (np.linalg.norm(np.cross(self.d, other.d)) < ang
                and np.linalg.norm(np.cross(other.loc - self.loc, self.d)) < lin)


def _revolution(index: int, face) -> _Revolution | None:
    surf = BRepAdaptor_Surface(face)
    kind = surf.GetType()
    if kind == GeomAbs_Cylinder:
        g = surf.Cylinder()
        r0, tan_angle, is_cone = g.Radius(), 0.0, False
    elif kind == GeomAbs_Cone:
        g = surf.Cone()
        r0, tan_angle, is_cone = g.RefRadius(), float(np.tan(g.SemiAngle())), True
    else:
        return None
    pos = g.Position()
    loc, d = _xyz(pos.Location()), _xyz(pos.Direction())
    p, n, bounds = _face_normal_at_mid(face)
    radial = p - (loc + ((p - loc) @ d) * d)
    return _Revolution(index, is_cone, loc, d, r0, tan_angle, bool(n @ radial < 0.0),
                       _xyz(pos.XDirection()), _xyz(pos.YDirection()), (bounds[0], bounds[1]))


def _perpendicular_frame(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.eye(3)[int(np.argmin(np.abs(d)))]
    e1 = np.cross(d, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(d, e1)


def _covered_angle(cylinders: Sequence[_Revolution], d: np.ndarray, ang: float = ANGLE_TOL_RAD) -> float:
    """Angle (rad, ≤ 2π) covered by the union of the cylinders' angular spans about axis ``d``; spans that
    meet within ``ang`` (split walls written as two 180° faces) join."""
    e1, e2 = _perpendicular_frame(d)
    intervals = []
    for c in cylinders:
        u0, u1 = c.u_bounds
        length = u1 - u0
        if length >= 2 * np.pi - ang:
            return 2 * np.pi
        sense = np.sign(np.cross(c.x_dir, c.y_dir) @ d)
        u_start = u0 if sense > 0 else u1
        w = np.cos(u_start) * c.x_dir + np.sin(u_start) * c.y_dir
        start = float(np.arctan2(w @ e2, w @ e1)) % (2 * np.pi)
        intervals += [(start, start + length), (start + 2 * np.pi, start + 2 * np.pi + length)]
    intervals.sort()
    best, (lo, hi) = 0.0, intervals[0]
    for s, e in intervals[1:]:
        if s > hi + ang:
            best, lo, hi = max(best, hi - lo), s, e
        else:
            hi = max(hi, e)
    return min(2 * np.pi, max(best, hi - lo))


def _closes_full_turn(cylinders: Sequence[_Revolution], d: np.ndarray, ang: float = ANGLE_TOL_RAD) -> bool:
    """Whether the union of the cylinders' angular spans about axis ``d`` covers 360° (within ``ang``)."""
    return _covered_angle(cylinders, d, ang) >= 2 * np.pi - 2 * ang


def _sample_edge(edge, deflection: float = SAMPLE_DEFLECTION_MM, min_points: int = 2) -> np.ndarray:
    """Points (K, 3) along the edge in its parameter order (chord error ≤ deflection); empty if degenerate."""
    if BRep_Tool.Degenerated_s(edge):
        return np.zeros((0, 3))
    curve = BRepAdaptor_Curve(edge)
    u0, u1 = curve.FirstParameter(), curve.LastParameter()
    if curve.GetType() == GeomAbs_Line:
        params = [u0, u1]
    else:
        q = GCPnts_QuasiUniformDeflection(curve, deflection, u0, u1)
        params = [q.Parameter(i) for i in range(1, q.NbPoints() + 1)] if q.IsDone() else []
        if len(params) < max(min_points, MIN_CURVE_POINTS):
            params = np.linspace(u0, u1, max(min_points, MIN_CURVE_POINTS)).tolist()
    return np.array([_xyz(curve.Value(u)) for u in params])


def _face_area(face) -> float:
    """Area (mm²) of a face (GProp)."""
    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(face, props)
    return props.Mass()


def _outer_area(face) -> float:
    """Area (mm²) enclosed by the face's outer wire, i.e. the face with its inner wires filled.

    Used to rank host faces independently of the holes and cut-outs they carry (so that the entrance
    of a through hole does not flip when other holes are added to one side of a plate).
    """
    maker = BRepBuilderAPI_MakeFace(BRep_Tool.Surface_s(face), BRepTools.OuterWire_s(face), True)
    return _face_area(maker.Face()) if maker.IsDone() else _face_area(face)


@dataclass
class _End:
    """An open end of a hole: rim loop, outward sense along the group axis, host face and rim."""

    edges: list[int]
    sense: float
    host: int
    centre: np.ndarray
    axis: np.ndarray
    radius: float
    wall: _Revolution
    area: float = field(default=0.0)
    rim: str = "sharp"
    blend: list[int] = field(default_factory=list)


def _wire_polygon(wire, face, origin: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The wire as a closed polygon (K, 2) in face coordinates (the last point not repeated)."""
    chunks = []
    explorer = BRepTools_WireExplorer(wire, face)
    while explorer.More():
        edge = explorer.Current()
        pts = _sample_edge(edge)
        if len(pts):
            if edge.Orientation() == TopAbs_REVERSED:
                pts = pts[::-1]
            chunks.append(pts[:-1])
        explorer.Next()
    p = np.concatenate(chunks) - origin
    return np.stack([p @ u, p @ v], axis=-1)


def _ccw(poly: np.ndarray) -> np.ndarray:
    x, y = poly[:, 0], poly[:, 1]
    signed_area = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    return poly if signed_area >= 0 else poly[::-1]
