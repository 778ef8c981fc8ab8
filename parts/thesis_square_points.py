"""Thesis object, Fig. 5.1 (a): four coplanar point features on a square (Shademan 2005, §5.2.1).

The four points are realised as four small through holes whose entrance-rim centres (on the top face,
z = 0) are the corners of a square of side ``side_mm`` centred on the origin:
(±side/2, ±side/2, 0). The thesis varies the side within 2 mm ≤ d ≤ 6 mm (§5.4.3).

Functional / fixed holes: none (all four are vision features). The plate (16 × 16 × 2 mm) is fixed.
"""

import cadquery as cq

DESCRIPTION = "Thesis Fig. 5.1(a): four holes on a square of side d (point features)"
PARAMETERS = {
    "side_mm": {"default": 4.0, "bounds": (2.0, 6.0), "unit": "mm", "description": "side of the square d"},
    "hole_radius_mm": {"default": 0.4, "bounds": (0.2, 0.8), "unit": "mm", "description": "radius of each hole"},
}
VIEW_DIRECTION = (0.0, 0.0, 1.0)
FIXED_HOLES = "none"
PLATE_MM = (16.0, 16.0, 2.0)


def corners(side_mm):
    """The four hole centres (x, y, z) mm, counter-clockwise from (+, +)."""
    h = side_mm / 2
    return [(h, h, 0.0), (-h, h, 0.0), (-h, -h, 0.0), (h, -h, 0.0)]


def build(side_mm, hole_radius_mm):
    sx, sy, sz = PLATE_MM
    plate = cq.Solid.makeBox(sx, sy, sz, cq.Vector(-sx / 2, -sy / 2, -sz))
    drills = [cq.Solid.makeCylinder(hole_radius_mm, sz + 2, cq.Vector(x, y, -sz - 1)) for x, y, _ in corners(side_mm)]
    return cq.Workplane("XY").add(plate.cut(*drills))


def expected_holes(side_mm, hole_radius_mm):
    """From the drawing: entrance centres on z = 0, axis +z, radius as given."""
    return [{"centre": c, "axis": (0.0, 0.0, 1.0), "radius_mm": hole_radius_mm} for c in corners(side_mm)]


if "show_object" in globals():  # cq-editor
    show_object(build(**{k: v["default"] for k, v in PARAMETERS.items()}))  # noqa: F821
