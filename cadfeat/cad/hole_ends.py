"""How a shop makes a blind hole's end: a twist drill leaves a 118° cone, an end mill a flat floor.

The CAD models cadfeat reads usually give blind holes flat floors (the modeller's "hole" feature without a drill
point). The camera sees the difference: a flat machined floor mirrors a light near the lens, a drill point's
cone sends it off to the walls. ``with_hole_ends(shape, holes, "drilled")`` cuts a drill point into each blind
hole's floor; ``"milled"`` and ``"as_modelled"`` leave the shape as it is (a flat floor is what a mill leaves).

A drill point of included angle 2θ (θ = 59° for the standard 118° point) on a bore of radius r is a cone of base
radius r on the floor plane, its apex h = r / tan θ deeper along the axis; it removes π r² h / 3 (mm³).
The floor is at ``Hole.depth_mm`` below the entrance rim along the hole's axis (a flat floor: its deepest point);
a hole whose floor already ends in a point would get a second one — ``drill_points`` is for flat floors.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from cadfeat.cell.defaults import HOLE_ENDS
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cad.features import Hole, ShapeLike

__all__ = ["DRILL_POINT_DEG", "HOLE_ENDS", "drill_point_depth_mm", "drill_point_volume_mm3", "drill_points",
           "with_hole_ends"]

#: Included angle of a standard twist drill's point (degrees).
DRILL_POINT_DEG = 118.0


def drill_point_depth_mm(radius_mm: float, point_deg: float = DRILL_POINT_DEG) -> float:
    """Height h (mm) of the drill point's cone on a bore of ``radius_mm``: r / tan(point / 2)."""
    return radius_mm / math.tan(math.radians(point_deg) / 2.0)


def drill_point_volume_mm3(radius_mm: float, point_deg: float = DRILL_POINT_DEG) -> float:
    """Volume (mm³) a drill point removes below a flat floor: π r² h / 3."""
    return math.pi * radius_mm ** 2 * drill_point_depth_mm(radius_mm, point_deg) / 3.0


def drill_points(shape: ShapeLike, holes: Sequence[Hole], point_deg: float = DRILL_POINT_DEG) -> Any:
    """``shape`` (a cadquery Shape or Workplane) with a ``point_deg`` drill point cut into the floor of every blind
    hole of ``holes`` (through holes are left alone); a ``cadquery.Shape``. One boolean cut of all the cones."""
    import cadquery as cq

    from cadfeat.cad.features import as_shape

    if not 0.0 < point_deg < 180.0:
        raise CadfeatError(f"point_deg: {point_deg} is not allowed; allowed: a number in (0, 180)")
    solid = as_shape(shape)
    cones = [_cone(h, point_deg) for h in holes if not h.through]
    if not cones:
        return solid
    tool = cones[0] if len(cones) == 1 else cq.Compound.makeCompound(cones)
    result = solid.cut(tool).clean()
    if not result.isValid():
        raise CadfeatError("drill points: the cut gave an invalid solid (a hole floor on another face?)")
    return result


def _cone(hole: Hole, point_deg: float) -> Any:
    """The drill point of ``hole``: base radius = its bore on the floor plane, apex deeper along −axis."""
    import cadquery as cq

    axis = -hole.axis / float((hole.axis ** 2).sum() ** 0.5)           # into the material
    floor = hole.centre + axis * hole.depth_mm
    r = hole.bore_radius_mm
    return cq.Solid.makeCone(r, 0.0, drill_point_depth_mm(r, point_deg), cq.Vector(*floor), cq.Vector(*axis))


def with_hole_ends(shape: ShapeLike, holes: Sequence[Hole], hole_ends: str) -> Any:
    """``shape`` with its blind holes' ends as ``hole_ends`` says (module docstring)."""
    if hole_ends not in HOLE_ENDS:
        raise CadfeatError(f"hole_ends: {hole_ends!r} is not allowed; allowed: {', '.join(HOLE_ENDS)}")
    return drill_points(shape, holes) if hole_ends == "drilled" else shape
