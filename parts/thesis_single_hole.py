"""Thesis object, Fig. 5.2: a single hole of radius 3.70 mm (Shademan 2005, §5.2.2).

A 30 × 30 × 5 mm plate, top face z = 0, with one through hole whose entrance centre is
(hole_x_mm, hole_y_mm, 0). The thesis places the camera at [0, 0, 28] mm above the object frame.

Functional / fixed holes: none (the single hole is the vision feature).
"""

import cadquery as cq

DESCRIPTION = "Thesis Fig. 5.2: single through hole, radius 3.70 mm"
PARAMETERS = {
    "radius_mm": {"default": 3.70, "bounds": (1.0, 6.0), "unit": "mm", "description": "hole radius"},
    "hole_x_mm": {"default": 0.0, "bounds": (-6.0, 6.0), "unit": "mm", "description": "hole centre x"},
    "hole_y_mm": {"default": 0.0, "bounds": (-6.0, 6.0), "unit": "mm", "description": "hole centre y"},
}
VIEW_DIRECTION = (0.0, 0.0, 1.0)
FIXED_HOLES = "none"
PLATE_MM = (30.0, 30.0, 5.0)


def build(radius_mm, hole_x_mm, hole_y_mm):
    sx, sy, sz = PLATE_MM
    plate = cq.Solid.makeBox(sx, sy, sz, cq.Vector(-sx / 2, -sy / 2, -sz))
    drill = cq.Solid.makeCylinder(radius_mm, sz + 2, cq.Vector(hole_x_mm, hole_y_mm, -sz - 1))
    return cq.Workplane("XY").add(plate.cut(drill))


def expected_holes(radius_mm, hole_x_mm, hole_y_mm):
    return [{"centre": (hole_x_mm, hole_y_mm, 0.0), "axis": (0.0, 0.0, 1.0), "radius_mm": radius_mm}]


if "show_object" in globals():  # cq-editor
    show_object(build(**{k: v["default"] for k, v in PARAMETERS.items()}))  # noqa: F821
