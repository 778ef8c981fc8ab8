"""Thesis object, Fig. 5.6: a one-dimensional array of equal holes (Shademan 2005, §5.2.2).

``hole_count`` through holes of radius 2.5 mm, pitch 8.57 mm, along x and centred on the origin: hole k
at x = (k - (n-1)/2)·pitch, y = 0, on the top face z = 0 of a bar 80 × 16 × 4 mm.

Functional / fixed holes: none.
"""

import cadquery as cq

DESCRIPTION = "Thesis Fig. 5.6: 1-D array of holes, pitch 8.57 mm, radius 2.5 mm"
PARAMETERS = {
    "pitch_mm": {"default": 8.57, "bounds": (6.5, 12.0), "unit": "mm", "description": "distance between centres"},
    "radius_mm": {"default": 2.5, "bounds": (1.0, 3.0), "unit": "mm", "description": "hole radius"},
    "hole_count": {"default": 4, "bounds": (2, 6), "unit": "", "description": "number of holes"},
}
VIEW_DIRECTION = (0.0, 0.0, 1.0)
FIXED_HOLES = "none"
BAR_MM = (80.0, 16.0, 4.0)


def build(pitch_mm, radius_mm, hole_count):
    sx, sy, sz = BAR_MM
    bar = cq.Solid.makeBox(sx, sy, sz, cq.Vector(-sx / 2, -sy / 2, -sz))
    xs = [(k - (hole_count - 1) / 2) * pitch_mm for k in range(hole_count)]
    drills = [cq.Solid.makeCylinder(radius_mm, sz + 2, cq.Vector(x, 0, -sz - 1)) for x in xs]
    return cq.Workplane("XY").add(bar.cut(*drills))


def expected_holes(pitch_mm, radius_mm, hole_count):
    first = -(hole_count - 1) * pitch_mm / 2
    return [{"centre": (first + k * pitch_mm, 0.0, 0.0), "axis": (0.0, 0.0, 1.0), "radius_mm": radius_mm}
            for k in range(hole_count)]


if "show_object" in globals():  # cq-editor
    show_object(build(**{k: v["default"] for k, v in PARAMETERS.items()}))  # noqa: F821
