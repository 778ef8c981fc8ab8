"""Hole and point features of a part, extracted from its B-rep.

The thesis's feature objects (Shademan 2005, §3.2 and §4.2) are points and circular holes on the
part. This module reads them from the CAD model itself:

- ``extract_holes(shape) -> list[Hole]``: every cylindrical hole (plain, counterbored, countersunk;
  blind or through), with the centre and radius of its *entrance rim*, the axis pointing out of the
  material, its depth, and the outline of the planar host face (for edge-distance constraints).
- ``extract_points(shape) -> (M, 3)``: the vertices of the solid (the thesis's point objects).
- ``holes_to_arrays`` / ``match_holes``: batch arrays for the measures and geometric matching of
  holes across CAD rebuilds (face indices are not stable, docs/design.md "Known pitfalls").

Units: millimetres, part frame. CadQuery/OCP are imported inside functions only, so that
``import cadfeat.cad.features`` stays light.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypeAlias

import numpy as np

from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from cadquery import Shape, Workplane
    from numpy.typing import ArrayLike
    from OCP.gp import gp_Pnt
    from OCP.TopoDS import TopoDS_Shape

    from cadfeat.cad.tolerance import ModelTolerance

ShapeLike: TypeAlias = "Shape | Workplane"
"""A solid as cadfeat's CAD functions take it: a ``cadquery.Shape`` (Solid, Compound, ...) or a ``cadquery.Workplane``
holding one (``as_shape`` gives the ``cadquery.Shape``; it also wraps a raw OCP ``TopoDS_Shape``)."""

__all__ = [
    "FaceOutline",
    "ShapeLike",
    "Hole",
    "as_shape",
    "extract_holes",
    "extract_points",
    "holes_to_arrays",
    "match_holes",
]

#: Largest chord error (mm) of the sampled face outlines.
OUTLINE_CHORD_ERROR_MM = 0.01
_ORDER_DECIMALS = 9  # rounding (1e-9 mm) used only for the deterministic ordering


def _frozen_array(value: ArrayLike, shape: tuple[int, ...] | None = None, name: str = "array") -> np.ndarray:
    """A read-only float64 copy of ``value`` (checked against ``shape``; -1 = any length)."""
    arr = np.array(value, dtype=float)
    if shape is not None and (arr.ndim != len(shape) or any(s not in (-1, a) for s, a in zip(shape, arr.shape,
                                                                                            strict=True))):
        raise CadfeatError(f"{name}: expected an array of shape {shape}, got {arr.shape}")
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True)
class FaceOutline:
    """A planar host face in its own 2-D coordinates (mm).

    ``p = origin + s*u + t*v`` maps face coordinates (s, t) to the part frame; ``u × v`` is the
    outward normal of the face. ``outer`` is the outer boundary, counter-clockwise, curved edges
    sampled with a chord error ≤ ``OUTLINE_CHORD_ERROR_MM``. ``keepouts`` are the inner boundaries that
    are not rims of extracted holes (slots, pockets, boss footprints, non-circular cut-outs), each
    also counter-clockwise.
    """

    origin: np.ndarray
    u: np.ndarray
    v: np.ndarray
    outer: np.ndarray
    keepouts: tuple[np.ndarray, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "origin", _frozen_array(self.origin, (3,), "FaceOutline.origin"))
        object.__setattr__(self, "u", _frozen_array(self.u, (3,), "FaceOutline.u"))
        object.__setattr__(self, "v", _frozen_array(self.v, (3,), "FaceOutline.v"))
        object.__setattr__(self, "outer", _frozen_array(self.outer, (-1, 2), "FaceOutline.outer"))
        object.__setattr__(self, "keepouts", tuple(_frozen_array(k, (-1, 2), "FaceOutline.keepouts")
                                                   for k in self.keepouts))

    @property
    def normal(self) -> np.ndarray:
        """(3,) outward unit normal of the face, ``u × v``."""
        return np.cross(self.u, self.v)

    def to_face(self, points: np.ndarray) -> np.ndarray:
        """Project part-frame points (..., 3) mm onto the face plane: face coordinates (..., 2) mm."""
        d = np.asarray(points, dtype=float) - self.origin
        return np.stack([d @ self.u, d @ self.v], axis=-1)

    def to_3d(self, uv: np.ndarray) -> np.ndarray:
        """Face coordinates (..., 2) mm to part-frame points (..., 3) mm on the face plane."""
        uv = np.asarray(uv, dtype=float)
        return self.origin + uv[..., :1] * self.u + uv[..., 1:2] * self.v

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, FaceOutline):
            return NotImplemented
        return (all(np.array_equal(getattr(self, k), getattr(other, k)) for k in ("origin", "u", "v", "outer"))
                and len(self.keepouts) == len(other.keepouts)
                and all(np.array_equal(a, b) for a, b in zip(self.keepouts, other.keepouts, strict=True)))


@dataclass(frozen=True)
class Hole:
    """A circular hole of the part (mm, part frame).

    ``centre`` is the centre of the entrance rim on the host face, ``axis`` the unit axis pointing out
    of the material (from the hole into free space), ``radius_mm`` the entrance-rim radius (what a
    camera sees on the face: the counterbore / countersink outer radius), ``bore_radius_mm`` the
    narrowest bore, ``depth_mm`` the distance along the axis from the entrance rim to the deepest
    point of the hole (blind) or to the exit rim centre (through). ``host_face`` indexes
    ``as_shape(shape).Faces()`` and is NOT stable across rebuilds (match by geometry with
    ``match_holes``). ``outline`` is the planar host face outline (None for non-planar hosts).
    """

    centre: np.ndarray
    axis: np.ndarray
    radius_mm: float
    bore_radius_mm: float
    depth_mm: float
    through: bool
    kind: str
    host_face: int
    outline: FaceOutline | None
    name: str = ""

    KINDS = ("plain", "counterbore", "countersink")
    RIMS = ("chamfered rim", "filleted rim")
    """Entrance-rim qualifiers: ``kind`` may be ``"<base>, <rim>"`` (e.g. ``"plain, filleted rim"``); the
    centre is then on the host plane the rim blends into and ``radius_mm`` the rim's outer radius there."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "centre", _frozen_array(self.centre, (3,), "Hole.centre"))
        object.__setattr__(self, "axis", _frozen_array(self.axis, (3,), "Hole.axis"))
        base, _, rim = self.kind.partition(", ")
        if base not in self.KINDS or (rim and rim not in self.RIMS):
            raise CadfeatError(f"Hole.kind: {self.kind!r} is not one of {', '.join(self.KINDS)}, optionally "
                               f"followed by ', ' and one of {', '.join(self.RIMS)}")

    @property
    def base_kind(self) -> str:
        """``kind`` without its rim qualifier: plain, counterbore or countersink."""
        return self.kind.partition(", ")[0]

    @property
    def rim(self) -> str:
        """The entrance rim: ``"sharp"``, ``"chamfer"`` or ``"fillet"``."""
        rim = self.kind.partition(", ")[2]
        return {"chamfered rim": "chamfer", "filleted rim": "fillet"}.get(rim, "sharp")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Hole):
            return NotImplemented
        return (np.array_equal(self.centre, other.centre) and np.array_equal(self.axis, other.axis)
                and (self.radius_mm, self.bore_radius_mm, self.depth_mm, self.through, self.kind,
                     self.host_face, self.name)
                == (other.radius_mm, other.bore_radius_mm, other.depth_mm, other.through, other.kind,
                    other.host_face, other.name)
                and self.outline == other.outline)


# ----------------------------------------------------------------------------------------------- arrays


def holes_to_arrays(holes: Sequence[Hole]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Batch arrays of holes: centres (N, 3) mm, axes (N, 3) unit, entrance radii (N,) mm."""
    if len(holes) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    centres = np.stack([h.centre for h in holes])
    axes = np.stack([h.axis for h in holes])
    radii = np.array([h.radius_mm for h in holes], dtype=float)
    return centres, axes, radii


def match_holes(reference: Sequence[Hole], candidates: Sequence[Hole], tol_mm: float = 0.5,
                axis_tol_rad: float = 1e-3) -> np.ndarray:
    """Match holes by geometry: ``idx`` with ``candidates[idx[i]]`` the hole matching ``reference[i]``.

    ``cadfeat.cad.features.identity.pair_holes``: an optimal assignment minimises the sum of
    ``‖Δcentre‖ + |Δradius| + tol_mm·angle(axes)/axis_tol_rad`` (mm). A pair is admissible only if the
    centres and radii differ by at most ``tol_mm`` and the axes by at most ``axis_tol_rad``; a reference
    hole without an admissible candidate raises ``CadfeatError``. Extra candidates are ignored.
    """
    from cadfeat.cad.features.identity import pair_holes  # (identity builds on Hole: imported here)

    return pair_holes(reference, candidates, tol_mm, axis_tol_rad)


# ------------------------------------------------------------------------------------------ shape input


def as_shape(obj: ShapeLike | TopoDS_Shape) -> Shape:
    """The ``cadquery.Shape`` whose faces ``Hole.host_face`` indexes.

    Accepts a ``cadquery.Shape`` (Solid, Compound, ...), a ``cadquery.Workplane`` (its
    ``findSolid()``) or a raw OCP ``TopoDS_Shape``.
    """
    import cadquery as cq
    from OCP.TopoDS import TopoDS_Shape

    if isinstance(obj, cq.Workplane):
        try:
            return obj.findSolid()
        except ValueError as exc:
            raise CadfeatError("extract_holes: the Workplane holds no solid") from exc
    if isinstance(obj, cq.Shape):
        return obj
    if isinstance(obj, TopoDS_Shape):
        return cq.Shape.cast(obj)
    raise CadfeatError(f"expected a cadquery Shape/Workplane or an OCP TopoDS_Shape, got {type(obj).__name__}")


def extract_points(shape: ShapeLike, tol_mm: float = 1e-7) -> np.ndarray:
    """The vertices of ``shape`` (M, 3) mm: the thesis's point objects.

    Vertices closer than ``tol_mm`` are merged (the first kept); the order is lexicographic in the
    coordinates rounded to 1e-9 mm (x, then y, then z), so it does not depend on the construction order.
    """
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_VERTEX
    from OCP.TopExp import TopExp
    from OCP.TopoDS import TopoDS
    from OCP.TopTools import TopTools_IndexedMapOfShape
    from scipy.spatial import cKDTree

    vmap = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(as_shape(shape).wrapped, TopAbs_VERTEX, vmap)
    pts = np.array([_xyz(BRep_Tool.Pnt_s(TopoDS.Vertex_s(vmap.FindKey(i)))) for i in range(1, vmap.Extent() + 1)])
    if len(pts) == 0:
        return np.zeros((0, 3))
    keep = np.ones(len(pts), dtype=bool)
    for i, j in sorted(cKDTree(pts).query_pairs(tol_mm)):
        if keep[i]:
            keep[j] = False
    pts = pts[keep]
    r = np.round(pts, _ORDER_DECIMALS)
    return pts[np.lexsort((r[:, 2], r[:, 1], r[:, 0]))]


def extract_holes(shape: ShapeLike, prefer_direction: Sequence[float] | np.ndarray | None = None,
                  tol: ModelTolerance | None = None) -> list[Hole]:
    """All circular holes of ``shape`` (algorithm in ``cadfeat.cad.features.extraction``).

    A hole is a connected set of coaxial concave cylinders and cones (plus the annular steps and flat
    bottoms between them) containing a cylinder that closes over 360°; convex cylinders (bosses,
    pins) and partial cylinders (fillets, slot ends) are not holes.

    Entrance rim: a blind hole's open end. A through hole has two open ends; the entrance is chosen by,
    in turn: (1) the larger rim radius (the counterbore / countersink side), (2) if
    ``prefer_direction`` is given, the end whose outward axis points more along it, (3) the host face
    enclosing the larger area within its outer boundary (inner wires filled, so other holes on a face
    do not flip the choice; relative tolerance 1e-6), (4) the outward axis that is larger in (z, y, x)
    lexicographic order (e.g. +z for a vertical hole through a plate).

    Holes are sorted by (axis, centre) rounded to 1e-9 and named ``H1``, ``H2``, … in that order (never
    unnamed: ``Part.holes`` / STEP parts rename them to keep a physical hole's name); values keep full precision.

    Tolerances (coaxial faces, equal radii, parallel normals) are ``tol`` (a ``cadfeat.cad.tolerance.
    ModelTolerance``), by default scaled to the model (its size and B-rep tolerances), so that real exports
    whose faces of one hole are 1e-6..4e-6 mm / 3e-7..8e-7 rad apart group into one hole. An entrance rim
    blended by a fillet puts the centre on the plane the fillet blends into (kind ``"..., filleted rim"``); a
    small entrance cone is a chamfer (``"..., chamfered rim"``), a large one a countersink.
    """
    # lazy: import cycle (cadfeat.cad.features.extraction imports cadfeat.cad.features)
    from cadfeat.cad.features import extraction

    return extraction.extract_holes(as_shape(shape), prefer_direction, tol)


def _xyz(p: gp_Pnt) -> np.ndarray:
    return np.array([p.X(), p.Y(), p.Z()])
