"""Thesis object, Fig. 5.5: a circular pattern of holes, like a wheel hub (Shademan 2005, §5.2.2).

A disc of radius 22 mm and thickness 6 mm (top face z = 0) with a centre through hole of radius 5.0 mm
and ``hole_count`` small through holes of radius 2.5 mm on a bolt circle of radius 9.65 mm; hole k is
at angle phase_rad + 2πk/n from +x. The hole positions are NONLINEAR in ``phase_rad`` (a rotation) and
linear in the bolt-circle radius.

Functional / fixed holes: the centre hole (axle / pilot) is functional and fixed.
"""

import math

import cadquery as cq

DESCRIPTION = "Thesis Fig. 5.5: hub with a centre hole and a bolt circle of small holes"
PARAMETERS = {
    "bolt_circle_radius_mm": {"default": 9.65, "bounds": (8.5, 16.0), "unit": "mm",
                              "description": "radius of the circle through the small hole centres"},
    "phase_rad": {"default": 0.0, "bounds": (-0.6, 0.6), "unit": "rad",
                  "description": "angle of the first small hole from +x"},
    "small_hole_radius_mm": {"default": 2.5, "bounds": (1.0, 3.0), "unit": "mm",
                             "description": "radius of the small holes"},
    "centre_hole_radius_mm": {"default": 5.0, "bounds": (3.0, 5.5), "unit": "mm",
                              "description": "radius of the centre hole (functional)"},
    "hole_count": {"default": 5, "bounds": (3, 8), "unit": "", "description": "number of small holes"},
}
VIEW_DIRECTION = (0.0, 0.0, 1.0)
FIXED_HOLES = "the centre hole (radius centre_hole_radius_mm) is the axle seat"
DISC_RADIUS_MM = 22.0
THICKNESS_MM = 6.0


def build(bolt_circle_radius_mm, phase_rad, small_hole_radius_mm, centre_hole_radius_mm, hole_count):
    t = THICKNESS_MM
    disc = cq.Solid.makeCylinder(DISC_RADIUS_MM, t, cq.Vector(0, 0, -t))
    drills = [cq.Solid.makeCylinder(centre_hole_radius_mm, t + 2, cq.Vector(0, 0, -t - 1))]
    for k in range(hole_count):
        a = phase_rad + 2 * math.pi * k / hole_count
        p = cq.Vector(bolt_circle_radius_mm * math.cos(a), bolt_circle_radius_mm * math.sin(a), -t - 1)
        drills.append(cq.Solid.makeCylinder(small_hole_radius_mm, t + 2, p))
    return cq.Workplane("XY").add(disc.cut(*drills))


def expected_holes(bolt_circle_radius_mm, phase_rad, small_hole_radius_mm, centre_hole_radius_mm, hole_count):
    up = (0.0, 0.0, 1.0)
    out = [{"centre": (0.0, 0.0, 0.0), "axis": up, "radius_mm": centre_hole_radius_mm, "fixed": True}]
    for k in range(hole_count):
        a = phase_rad + 2 * math.pi * k / hole_count
        out.append({"centre": (bolt_circle_radius_mm * math.cos(a), bolt_circle_radius_mm * math.sin(a), 0.0),
                    "axis": up, "radius_mm": small_hole_radius_mm})
    return out


if "show_object" in globals():  # cq-editor
    show_object(build(**{k: v["default"] for k, v in PARAMETERS.items()}))  # noqa: F821
