"""Thesis object, Fig. 5.1 (b): four coplanar point features NOT on a square (Shademan 2005, §5.2.1).

As Fig. 5.1 (a) but "the fourth feature point is twice farther": three entrance centres at
(side/2, side/2, 0), (-side/2, side/2, 0), (-side/2, -side/2, 0) and the fourth at (side, -side, 0),
twice as far from the centre as the corner it replaces. Small through holes in a fixed 20 × 20 × 2 mm
plate (top face z = 0). The thesis studies 2 mm ≤ d ≤ 3 mm and 2 mm ≤ d ≤ 6 mm (§5.4.3).

Functional / fixed holes: none.
"""

import cadquery as cq

DESCRIPTION = "Thesis Fig. 5.1(b): four coplanar holes, the fourth twice as far out (not a square)"
PARAMETERS = {
    "side_mm": {"default": 4.0, "bounds": (2.0, 6.0), "unit": "mm", "description": "side d of the base square"},
    "hole_radius_mm": {"default": 0.4, "bounds": (0.2, 0.8), "unit": "mm", "description": "radius of each hole"},
}
VIEW_DIRECTION = (0.0, 0.0, 1.0)
FIXED_HOLES = "none"
PLATE_MM = (20.0, 20.0, 2.0)


def centres(side_mm):
    h = side_mm / 2
    return [(h, h, 0.0), (-h, h, 0.0), (-h, -h, 0.0), (2 * h, -2 * h, 0.0)]


def build(side_mm, hole_radius_mm):
    sx, sy, sz = PLATE_MM
    plate = cq.Solid.makeBox(sx, sy, sz, cq.Vector(-sx / 2, -sy / 2, -sz))
    drills = [cq.Solid.makeCylinder(hole_radius_mm, sz + 2, cq.Vector(x, y, -sz - 1)) for x, y, _ in centres(side_mm)]
    return cq.Workplane("XY").add(plate.cut(*drills))


def expected_holes(side_mm, hole_radius_mm):
    h = side_mm / 2
    drawing = [(h, h), (-h, h), (-h, -h), (side_mm, -side_mm)]
    return [{"centre": (x, y, 0.0), "axis": (0.0, 0.0, 1.0), "radius_mm": hole_radius_mm} for x, y in drawing]


if "show_object" in globals():  # cq-editor
    show_object(build(**{k: v["default"] for k, v in PARAMETERS.items()}))  # noqa: F821
