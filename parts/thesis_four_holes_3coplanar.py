"""Thesis object, Fig. 5.3: four equal holes, three of them coplanar (Shademan 2005, §5.2.2).

Three through holes in a base plate (top face z = 0) at (-d, -d, 0), (d, -d, 0), (-d, d, 0); the fourth,
blind, on top of a square pedestal at (d, d, height). All radii equal R; the thesis example has
d = 6.79 mm and R = 3.10 mm. The base plate (4 mm thick) grows with d and R (half side d + R + 4 mm); the
pedestal's half side is R + 1.5 mm.

Functional / fixed holes: none.
"""

import cadquery as cq

DESCRIPTION = "Thesis Fig. 5.3: four holes of radius R, three coplanar, one raised (d = 6.79, R = 3.10)"
PARAMETERS = {
    "d_mm": {"default": 6.79, "bounds": (5.0, 12.0), "unit": "mm", "description": "distance parameter d"},
    "radius_mm": {"default": 3.10, "bounds": (1.0, 3.5), "unit": "mm", "description": "hole radius R"},
    "height_mm": {"default": 5.0, "bounds": (2.0, 10.0), "unit": "mm",
                  "description": "height of the fourth hole's face above the other three"},
}
VIEW_DIRECTION = (0.0, 0.0, 1.0)
FIXED_HOLES = "none"
PLATE_T_MM = 4.0


def build(d_mm, radius_mm, height_mm):
    e, t = d_mm + radius_mm + 4.0, PLATE_T_MM
    body = cq.Solid.makeBox(2 * e, 2 * e, t, cq.Vector(-e, -e, -t))
    p = radius_mm + 1.5
    pedestal = cq.Solid.makeBox(2 * p, 2 * p, height_mm, cq.Vector(d_mm - p, d_mm - p, 0))
    body = body.fuse(pedestal).clean()
    drills = [cq.Solid.makeCylinder(radius_mm, t + 2, cq.Vector(x, y, -t - 1))
              for x, y in ((-d_mm, -d_mm), (d_mm, -d_mm), (-d_mm, d_mm))]
    drills.append(cq.Solid.makeCylinder(radius_mm, height_mm + 3, cq.Vector(d_mm, d_mm, -2.0)))
    return cq.Workplane("XY").add(body.cut(*drills))


def expected_holes(d_mm, radius_mm, height_mm):
    up = (0.0, 0.0, 1.0)
    pts = [(-d_mm, -d_mm, 0.0), (d_mm, -d_mm, 0.0), (-d_mm, d_mm, 0.0), (d_mm, d_mm, height_mm)]
    return [{"centre": c, "axis": up, "radius_mm": radius_mm} for c in pts]


if "show_object" in globals():  # cq-editor
    show_object(build(**{k: v["default"] for k, v in PARAMETERS.items()}))  # noqa: F821
