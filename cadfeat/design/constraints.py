"""Mechanical (kept) functional requirements F_1..F_n (thesis §2.2.2) as constraint margins ≥ 0.

Two independent forms:

- ``constraint_margins`` / ``ConstraintSet``: the fast 2-D form the optimiser uses, batched over designs.
  Each moving hole's centre is projected into its host face's 2-D frame (``FaceOutline``, from the reference
  holes) and measured against the face's outer polygon and keep-out polygons:

  * ``edge``:     signed distance(centre, outer polygon) − r − edge_distance_mm (inside positive);
  * ``keepout``:  distance(centre, keep-out polygon) − r − keepout_mm (outside positive);
  * ``ligament``: ‖c_i − c_j‖ − r_i − r_j − ligament_mm for hole pairs on the same host face (at least one
    moving);
  * ``symmetry``: symmetry_tol_mm − (‖mirror(c_i) − c_j‖ + |r_i − r_j|) for declared mirror pairs;
  * ``volume``:   max_frac · V0 − |Σ π (r² − r0²) depth| (cylindrical approximation of each hole's volume).

  Bounds, fixed holes (no variables), standard sizes and patterns are handled by the design space.

- ``verify_on_brep``: the same requirements measured on the REAL rebuilt solid: holes re-extracted,
  distances between the rim circle edges and the host face's wires by OCCT ``BRepExtrema_DistShapeShape``.
  It shares no code with the 2-D form.

Units: mm; margins positive = satisfied.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.cad.export import shape_volume_mm3
from cadfeat.cad.features import Hole, as_shape, extract_holes, holes_to_arrays, match_holes
from cadfeat.cad.features.identity import hole_name
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    import cadquery as cq
    from OCP.TopoDS import TopoDS_Edge, TopoDS_Face, TopoDS_Shape

    from cadfeat.cad.features import ShapeLike
    from cadfeat.cad.outline_motion import OutlineRates
    from cadfeat.results import RequirementData

__all__ = [
    "ConstraintCheck",
    "ConstraintConfig",
    "ConstraintSet",
    "SymmetryPair",
    "constraint_margins",
    "point_polygon_distance",
    "verify_on_brep",
]


@dataclass(frozen=True)
class SymmetryPair:
    """Holes ``i`` and ``j`` mirror each other in the plane through ``point`` (3,) mm with ``normal`` (3,)."""

    i: int
    j: int
    point: tuple[float, float, float] = (0.0, 0.0, 0.0)
    normal: tuple[float, float, float] = (1.0, 0.0, 0.0)

    def reflect(self, p: np.ndarray) -> np.ndarray:
        n = np.asarray(self.normal, float) / np.linalg.norm(self.normal)
        d = (np.asarray(p, float) - np.asarray(self.point, float)) @ n
        return p - 2.0 * d[..., None] * n


@dataclass(frozen=True)
class ConstraintConfig:
    """Kept requirements (mm). ``keepout_mm`` defaults to ``ligament_mm``; ``volume_change_max_frac`` needs
    ``part_volume_mm3`` (V0); ``symmetry`` lists mirror pairs checked to ``symmetry_tol_mm``."""

    edge_distance_mm: float = 1.0
    ligament_mm: float = 1.0
    keepout_mm: float | None = None
    volume_change_max_frac: float | None = None
    part_volume_mm3: float | None = None
    symmetry: tuple[SymmetryPair, ...] = ()
    symmetry_tol_mm: float = 1e-3
    fixed_tol_mm: float = 1e-6

    def __post_init__(self) -> None:
        for key in ("edge_distance_mm", "ligament_mm"):
            if not np.isfinite(getattr(self, key)) or getattr(self, key) < 0:
                raise CadfeatError(f"constraints.{key}: must be a number ≥ 0 (mm), got {getattr(self, key)!r}")
        if self.volume_change_max_frac is not None and not (0 <= self.volume_change_max_frac):
            raise CadfeatError("constraints.volume_change_max_frac: must be ≥ 0, got "
                               f"{self.volume_change_max_frac!r}")
        object.__setattr__(self, "symmetry", tuple(self.symmetry))

    @property
    def keepout(self) -> float:
        return self.ligament_mm if self.keepout_mm is None else float(self.keepout_mm)


@dataclass(frozen=True)
class ConstraintCheck:
    """One kept requirement measured on a design: ``margin = value − required`` (for "≤" requirements,
    ``required − value``), ``ok = margin ≥ −tolerance``."""

    name: str
    holes: list[str]
    required: float
    value: float
    margin: float
    unit: str
    ok: bool

    def to_dict(self) -> RequirementData:
        return {"name": self.name, "holes": list(self.holes), "required": float(self.required),
                "value": float(self.value), "margin": float(self.margin), "unit": self.unit, "ok": bool(self.ok)}


# --------------------------------------------------------------------------------------- 2-D geometry
def _pad_polygons(polygons: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Segments of K closed polygons padded to the longest: starts (K,S,2), ends (K,S,2), valid (K,S)."""
    s_max = max((len(p) for p in polygons), default=0)
    k = len(polygons)
    a = np.zeros((k, s_max, 2))
    b = np.zeros((k, s_max, 2))
    valid = np.zeros((k, s_max), dtype=bool)
    for i, p in enumerate(polygons):  # set-up only, once per problem
        p = np.asarray(p, dtype=float)
        a[i, :len(p)] = p
        b[i, :len(p)] = np.roll(p, -1, axis=0)
        valid[i, :len(p)] = True
    return a, b, valid


def _pad_rates(rates: Sequence[np.ndarray | None], valid: np.ndarray, P: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertex rates (S_k, 2, P) of K polygons (None: fixed) padded like ``_pad_polygons``: for the segment starts
    (K, S, 2, P) and ends (K, S, 2, P)."""
    k, s_max = valid.shape
    a = np.zeros((k, s_max, 2, P))
    b = np.zeros((k, s_max, 2, P))
    for i, r in enumerate(rates):
        if r is not None:
            a[i, :len(r)] = r
            b[i, :len(r)] = np.roll(r, -1, axis=0)
    return a, b


def point_polygon_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray,
                           valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (..., K) mm from points (..., K, 2) to polygon k's boundary, and inside (..., K) bool.

    ``a``, ``b``, ``valid`` from ``_pad_polygons``. Inside by the even–odd crossing rule.
    """
    p = points[..., None, :]  # (..., K, 1, 2)
    ab = b - a
    len2 = np.maximum(np.sum(ab * ab, axis=-1), 1e-300)
    t = np.clip(np.sum((p - a) * ab, axis=-1) / len2, 0.0, 1.0)
    d = np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)
    d = np.where(valid, d, np.inf).min(axis=-1)
    px, py = p[..., 0], p[..., 1]
    ay, by = a[..., 1], b[..., 1]
    straddle = (ay > py) != (by > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = a[..., 0] + (py - ay) * ab[..., 0] / np.where(straddle, by - ay, 1.0)
    crossings = np.sum(straddle & (px < x_cross) & valid, axis=-1)
    return d, crossings % 2 == 1


def _same_face(h1: Hole, h2: Hole, tol: float = 1e-6) -> bool:
    """The two holes are on one host face: the same face index, or coplanar outlines with the same outer
    boundary (outlines of different faces may have any number of points: a 6-point tongue and a 316-point
    plate of one plane are two faces, not an error)."""
    if h1.host_face == h2.host_face:
        return True
    if h1.outline is None or h2.outline is None:
        return False
    n1, n2 = h1.outline.normal, h2.outline.normal
    o1, o2 = np.asarray(h1.outline.outer), np.asarray(h2.outline.outer)
    return bool(np.dot(n1, n2) > 1 - 1e-9 and abs(np.dot(h2.outline.origin - h1.outline.origin, n1)) < tol
                and o1.shape == o2.shape and np.allclose(o1, o2))


def _label(holes: Sequence[Hole], i: int) -> str:
    return hole_name(holes[i], i)


class ConstraintSet:
    """The 2-D constraints of one problem, compiled once (index arrays, padded polygons) and then evaluated
    batched: ``margins(centres (...,N,3), radii (...,N)) -> {name: (..., M_name)}``."""

    def __init__(self, holes: Sequence[Hole], config: ConstraintConfig, fixed_mask: Sequence[bool] | np.ndarray,
                 radii0: Sequence[float] | np.ndarray | None = None,
                 outline_rates: Sequence[OutlineRates | None] | None = None,
                 x_anchor: Sequence[float] | None = None):
        """``holes``: the reference holes (host face outlines, depths, names); ``radii0`` (N,) mm: the original
        part's radii for the volume requirement (default: the reference holes'); ``outline_rates`` (per hole,
        ``outline_motion.OutlineRates`` or None) with ``x_anchor`` (P,): host-face outlines that move with the
        design x (``margins(..., X=x)``), exact for a face whose size is linear in x (issue 16)."""
        self.holes = list(holes)
        self.config = config
        fixed = np.asarray(fixed_mask, dtype=bool).reshape(-1)
        if fixed.size != len(self.holes):
            raise CadfeatError(f"fixed_mask has {fixed.size} entries for {len(self.holes)} holes")
        self.fixed = fixed
        moving = [i for i in range(len(self.holes)) if not fixed[i]]
        self._c0, _, self._r0 = holes_to_arrays(self.holes)
        if radii0 is not None:
            self._r0 = np.asarray(radii0, dtype=float).reshape(-1)
        # edge: moving holes on planar faces
        self.edge_idx = np.array([i for i in moving if self.holes[i].outline is not None], dtype=int)
        outlines = [self.holes[i].outline for i in self.edge_idx]
        self._edge_poly = _pad_polygons([o.outer for o in outlines])
        self._edge_frames = self._frames(outlines)
        # keep-outs: (hole, keep-out polygon) pairs
        ko = [(i, k) for i in self.edge_idx for k in range(len(self.holes[i].outline.keepouts))]
        self.keepout_idx = np.array([i for i, _ in ko], dtype=int)
        self._ko_poly = _pad_polygons([self.holes[i].outline.keepouts[k] for i, k in ko])
        self._ko_frames = self._frames([self.holes[i].outline for i, _ in ko])
        # outline motion: vertex rates padded like the polygons (None: fixed outlines)
        self._x_anchor = None if x_anchor is None else np.asarray(x_anchor, dtype=float).reshape(-1)
        rates = list(outline_rates) if outline_rates is not None else [None] * len(self.holes)
        self._edge_rates = self._ko_rates = None
        if self._x_anchor is not None and any(r is not None and r.moves for r in rates):
            P = self._x_anchor.size
            self._edge_rates = _pad_rates([None if rates[i] is None else rates[i].outer for i in self.edge_idx],
                                          self._edge_poly[2], P)
            self._ko_rates = _pad_rates([None if rates[i] is None else rates[i].keepouts[k] for i, k in ko],
                                        self._ko_poly[2], P)
        # ligaments
        n = len(self.holes)
        pairs = [(i, j) for i in range(n) for j in range(i + 1, n)
                 if not (fixed[i] and fixed[j]) and _same_face(self.holes[i], self.holes[j])]
        self.pairs = np.array(pairs, dtype=int).reshape(-1, 2)
        self._depth = np.array([h.depth_mm for h in self.holes], dtype=float)
        if config.volume_change_max_frac is not None and not config.part_volume_mm3:
            raise CadfeatError("constraints.volume_change_max_frac needs the part volume (part_volume_mm3)")
        for s in config.symmetry:
            if not (0 <= s.i < n and 0 <= s.j < n):
                raise CadfeatError(f"constraints.symmetry: pair ({s.i}, {s.j}) outside holes 0..{n - 1}")

    @staticmethod
    def _frames(outlines: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not outlines:
            return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3))
        return (np.stack([o.origin for o in outlines]), np.stack([o.u for o in outlines]),
                np.stack([o.v for o in outlines]))

    @staticmethod
    def _to_face(points: np.ndarray, frames: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
        origin, u, v = frames
        d = points - origin
        return np.stack([np.sum(d * u, axis=-1), np.sum(d * v, axis=-1)], axis=-1)

    def labels(self) -> dict[str, list[list[str]]]:
        """Hole names of each margin entry, per constraint kind (same order as ``margins``)."""
        h = self.holes
        out = {"edge": [[_label(h, i)] for i in self.edge_idx],
               "keepout": [[_label(h, i)] for i in self.keepout_idx],
               "ligament": [[_label(h, i), _label(h, j)] for i, j in self.pairs],
               "symmetry": [[_label(h, s.i), _label(h, s.j)] for s in self.config.symmetry]}
        if self.config.volume_change_max_frac is not None:
            out["volume"] = [[]]
        return out

    def _polygons(self, poly: tuple, rates: tuple | None, X: np.ndarray | None) -> tuple:
        """The padded polygons (a, b, valid), moved to the designs X (..., P) when the outlines move."""
        if rates is None or X is None:
            return poly
        dX = np.asarray(X, dtype=float) - self._x_anchor
        a, b, valid = poly
        ra, rb = rates
        return (a + np.einsum("ksdp,...p->...ksd", ra, dX), b + np.einsum("ksdp,...p->...ksd", rb, dX), valid)

    def margins(self, centres: np.ndarray, radii: np.ndarray, X: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Margins (mm or mm³) ≥ 0 feasible, each (..., M_kind), for centres (..., N, 3), radii (..., N); ``X``
        (..., P): the designs, for outlines that move with the design (``outline_rates``)."""
        centres = np.asarray(centres, dtype=float)
        radii = np.asarray(radii, dtype=float)
        cfg = self.config
        out: dict[str, np.ndarray] = {}
        if self.edge_idx.size:
            st = self._to_face(centres[..., self.edge_idx, :], self._edge_frames)
            d, inside = point_polygon_distance(st, *self._polygons(self._edge_poly, self._edge_rates, X))
            out["edge"] = np.where(inside, d, -d) - radii[..., self.edge_idx] - cfg.edge_distance_mm
        else:
            out["edge"] = np.zeros(radii.shape[:-1] + (0,))
        if self.keepout_idx.size:
            st = self._to_face(centres[..., self.keepout_idx, :], self._ko_frames)
            d, inside = point_polygon_distance(st, *self._polygons(self._ko_poly, self._ko_rates, X))
            out["keepout"] = np.where(inside, -d, d) - radii[..., self.keepout_idx] - cfg.keepout
        else:
            out["keepout"] = np.zeros(radii.shape[:-1] + (0,))
        i, j = self.pairs[:, 0], self.pairs[:, 1]
        out["ligament"] = (np.linalg.norm(centres[..., i, :] - centres[..., j, :], axis=-1)
                           - radii[..., i] - radii[..., j] - cfg.ligament_mm)
        if cfg.symmetry:
            si = np.array([s.i for s in cfg.symmetry])
            sj = np.array([s.j for s in cfg.symmetry])
            mirrored = np.stack([s.reflect(centres[..., s.i, :]) for s in cfg.symmetry], axis=-2)
            err = np.linalg.norm(mirrored - centres[..., sj, :], axis=-1) + np.abs(radii[..., si] - radii[..., sj])
            out["symmetry"] = cfg.symmetry_tol_mm - err
        else:
            out["symmetry"] = np.zeros(radii.shape[:-1] + (0,))
        if cfg.volume_change_max_frac is not None:
            dv = np.sum(np.pi * (radii ** 2 - self._r0 ** 2) * self._depth, axis=-1)
            out["volume"] = (cfg.volume_change_max_frac * cfg.part_volume_mm3 - np.abs(dv))[..., None]
        return out

    def stacked(self, centres: np.ndarray, radii: np.ndarray, X: np.ndarray | None = None) -> np.ndarray:
        """All margins concatenated (..., M) (``X``: as ``margins``)."""
        return np.concatenate(list(self.margins(centres, radii, X).values()), axis=-1)


def constraint_margins(centres: np.ndarray, radii: np.ndarray, holes: Sequence[Hole], config: ConstraintConfig,
                       fixed_mask: Sequence[bool] | np.ndarray) -> dict[str, np.ndarray]:
    """The 2-D constraint margins (see module docstring) of a design: ``{kind: (..., M_kind)}``.

    ``holes`` are the reference holes (host face outlines, depths, names); ``centres`` (..., N, 3) mm and
    ``radii`` (..., N) mm the design's features in the same order. For repeated calls build a
    ``ConstraintSet`` once."""
    return ConstraintSet(holes, config, fixed_mask).margins(centres, radii)


# ------------------------------------------------------------------------------------ B-rep verification
@dataclass
class _RealHole:
    hole: Hole
    rim_edges: list[TopoDS_Edge] = field(default_factory=list["TopoDS_Edge"])


def _face_circles(face: TopoDS_Face) -> Iterator[tuple[TopoDS_Edge, np.ndarray, float]]:
    """(edge, centre mm (3,), radius mm) of every circular edge of ``face`` (OCP)."""
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.GeomAbs import GeomAbs_Circle
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    exp = TopExp_Explorer(face, TopAbs_EDGE)
    while exp.More():
        edge = TopoDS.Edge_s(exp.Current())
        curve = BRepAdaptor_Curve(edge)
        if curve.GetType() == GeomAbs_Circle:
            circ = curve.Circle()
            loc = circ.Location()
            yield edge, np.array([loc.X(), loc.Y(), loc.Z()]), circ.Radius()
        exp.Next()


def _circle_edges(face: TopoDS_Face, centre: np.ndarray, radius: float, tol: float) -> list[TopoDS_Edge]:
    """The circular edges of ``face`` (OCP) with centre ``centre`` and ``radius`` (the hole's rim)."""
    return [e for e, c, r in _face_circles(face) if np.linalg.norm(c - centre) < tol and abs(r - radius) < tol]


def _is_hole_wire(wire: cq.Wire, holes: Sequence[Hole], tol: float = 1e-5) -> bool:
    """True if every edge of ``wire`` (cadquery Wire) is a circle centred on some hole's axis line (a rim
    or exit of a hole, not a keep-out)."""
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.GeomAbs import GeomAbs_Circle

    for edge in wire.Edges():
        curve = BRepAdaptor_Curve(edge.wrapped)
        if curve.GetType() != GeomAbs_Circle:
            return False
        loc = curve.Circle().Location()
        c = np.array([loc.X(), loc.Y(), loc.Z()])
        if not any(np.linalg.norm(np.cross(c - h.centre, h.axis)) < tol for h in holes):
            return False
    return True


def _min_distance(shapes_a: Sequence[TopoDS_Shape], shapes_b: Sequence[TopoDS_Shape]) -> float:
    """Minimum distance (mm) between two sets of OCP shapes (``BRepExtrema_DistShapeShape``)."""
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape

    best = np.inf
    for a in shapes_a:
        for b in shapes_b:
            dist = BRepExtrema_DistShapeShape(a, b)
            if not dist.IsDone():
                raise CadfeatError("verify_on_brep: OCCT distance computation failed")
            best = min(best, dist.Value())
    return float(best)


def _axis_circle_edges(face: TopoDS_Face, hole: Hole, tol: float = 1e-5) -> list[TopoDS_Edge]:
    """Circular edges of ``face`` (OCP) of the hole's radius centred on its axis line, between its entrance and
    its depth: its rim on its host face, or its exit rim on the far face of a through hole (not the rim of a
    coaxial hole in another wall further along the line: the two plates of a clevis)."""
    axis = np.asarray(hole.axis, float)
    depth = float(getattr(hole, "depth_mm", np.inf))
    slack = max(tol, 1e-3)
    return [e for e, c, r in _face_circles(face)
            if np.linalg.norm(np.cross(c - hole.centre, axis)) < tol and abs(r - hole.radius_mm) < tol
            and -depth - slack <= float((c - hole.centre) @ axis) <= slack]


def _shared_face_distance(faces: Sequence[cq.Face], a: Hole, b: Hole) -> float | None:
    """Rim-to-rim distance (mm) of two holes on a face they both open into, or None if they share none.

    A through hole opens into two faces; extraction without a preferred direction may report it from either
    end, so the host faces of both holes are tried (issue 13: a blind hole on the face where a through hole
    exits had no ligament check)."""
    best = None
    for f in dict.fromkeys((a.host_face, b.host_face)):
        face = faces[f].wrapped
        ea, eb = _axis_circle_edges(face, a), _axis_circle_edges(face, b)
        if ea and eb:
            d = _min_distance(ea, eb)
            best = d if best is None else min(best, d)
    return best


def _check(name: str, holes: list[str], required: float, value: float, unit: str, tol: float,
           at_most: bool = False) -> ConstraintCheck:
    margin = (required - value) if at_most else (value - required)
    return ConstraintCheck(name, holes, float(required), float(value), float(margin), unit, bool(margin >= -tol))


def verify_on_brep(shape: ShapeLike, design_holes: Sequence[Hole], config: ConstraintConfig,
                   fixed_mask: Sequence[bool] | np.ndarray,
                   reference: Sequence[Hole] | None = None, *, match_tol_mm: float = 1e-3,
                   reference_shape: ShapeLike | None = None, tol_mm: float = 1e-6,
                   prefer_direction: Sequence[float] | np.ndarray | None = None) -> list[ConstraintCheck]:
    """Measure the kept requirements on the real solid ``shape`` (independent of the 2-D form).

    Holes are re-extracted from ``shape`` (a through hole entering on the side of ``prefer_direction``, the
    study's view, as ``design_holes`` were extracted) and matched to ``design_holes`` by geometry
    (``match_tol_mm``).
    Per moving hole: ``edge`` — OCCT distance from its rim circle edge(s) to its host face's outer wire,
    ≥ edge_distance_mm (a hole that breaks out of the face gets 0); ``keepout`` — to the face's inner
    wires that are not hole rims. Per pair on one face (one moving): ``ligament`` — rim-to-rim distance
    ≥ ligament_mm. With ``reference`` (the original holes, same order): ``fixed`` — fixed holes unchanged
    (centre and radius error ≤ ``config.fixed_tol_mm``). ``symmetry`` pairs on the extracted holes.
    ``volume`` — |V − V0| / V0 ≤ max_frac with ``reference_shape``. A missing hole gives a failed
    ``holes_match`` check. ``tol_mm`` is the numerical tolerance of ``ok``.
    """
    solid = as_shape(shape)
    design_holes = list(design_holes)
    fixed = np.asarray(fixed_mask, dtype=bool)
    names = [_label(design_holes, i) for i in range(len(design_holes))]
    real = extract_holes(solid, prefer_direction=prefer_direction)
    try:
        idx = match_holes(design_holes, real, tol_mm=match_tol_mm)
    except CadfeatError as exc:
        return [ConstraintCheck("holes_match", names, 0.0, float("inf"), -float("inf"), "mm", False)
                ] + [ConstraintCheck("holes_match_error", [str(exc)], 0.0, 0.0, 0.0, "", False)]
    holes = [real[k] for k in idx]
    c_d, _, r_d = holes_to_arrays(design_holes)
    c_r, _, r_r = holes_to_arrays(holes)
    err = float(np.max(np.linalg.norm(c_r - c_d, axis=1) + np.abs(r_r - r_d), initial=0.0))
    checks = [_check("holes_match", names, match_tol_mm, err, "mm", 0.0, at_most=True)]
    faces = solid.Faces()
    rims = [_circle_edges(faces[h.host_face].wrapped, h.centre, h.radius_mm, 1e-5) for h in holes]
    for i, h in enumerate(holes):
        if fixed[i] or h.outline is None:
            continue
        face = faces[h.host_face]
        if not rims[i]:
            checks.append(ConstraintCheck("edge", [names[i]], config.edge_distance_mm, 0.0,
                                          -config.edge_distance_mm, "mm", False))
            continue
        value = _min_distance(rims[i], [face.outerWire().wrapped])
        checks.append(_check("edge", [names[i]], config.edge_distance_mm, value, "mm", tol_mm))
        inner = [w.wrapped for w in face.innerWires() if not _is_hole_wire(w, real)]
        if inner:
            value = _min_distance(rims[i], inner)
            checks.append(_check("keepout", [names[i]], config.keepout, value, "mm", tol_mm))
    for i in range(len(holes)):
        for j in range(i + 1, len(holes)):
            if fixed[i] and fixed[j]:
                continue
            value = _shared_face_distance(faces, holes[i], holes[j])
            if value is not None:
                checks.append(_check("ligament", [names[i], names[j]], config.ligament_mm, value, "mm", tol_mm))
    if reference is not None:
        c0, _, r0 = holes_to_arrays(list(reference))
        for i in np.flatnonzero(fixed):
            e = float(np.linalg.norm(c_r[i] - c0[i]) + abs(r_r[i] - r0[i]))
            checks.append(_check("fixed", [names[i]], config.fixed_tol_mm, e, "mm", 0.0, at_most=True))
    for s in config.symmetry:
        e = float(np.linalg.norm(s.reflect(c_r[s.i]) - c_r[s.j]) + abs(r_r[s.i] - r_r[s.j]))
        checks.append(_check("symmetry", [names[s.i], names[s.j]], config.symmetry_tol_mm, e, "mm", tol_mm,
                             at_most=True))
    if config.volume_change_max_frac is not None and reference_shape is not None:
        v0 = shape_volume_mm3(as_shape(reference_shape))
        frac = abs(shape_volume_mm3(solid) - v0) / v0
        checks.append(_check("volume", [], config.volume_change_max_frac, frac, "fraction", 1e-9, at_most=True))
    return checks
