"""Pipe flange DN50 PN16 (plate flange with raised face, nominal EN 1092-1 dimensions) with vision targets.

Frame: flange axis = z, back face z = 0, flange face z = 18, raised face z = 18..21.
Outside diameter 165 mm, thickness 18 mm, raised face Ø102 × 3 mm, bore Ø61.5 mm (for a Ø60.3 pipe),
4 × Ø18 mm bolt holes (M16) on the 125 mm bolt circle at 45°, 135°, 225°, 315° (straddling the centre
lines, as flanges are drilled).

Functional / fixed holes: the bore and the 4 bolt holes (they mate with the standard counter-flange).
Free (vision targets, design variables): 2 blind holes, 4 mm deep, in the flange face z = 18 outside the
raised face, diametrically opposite: polar radius target_circle_radius_mm, angles target_angle_rad and
target_angle_rad + π. Their centres are NONLINEAR in target_angle_rad.
"""

import math

import cadquery as cq

DESCRIPTION = "DN50 PN16 raised-face flange: bore + 4 x M16 on 125 mm circle fixed, 2 free target holes"
PARAMETERS = {
    "target_circle_radius_mm": {"default": 66.0, "bounds": (56.0, 72.0), "unit": "mm",
                                "description": "polar radius of the two target holes"},
    "target_angle_rad": {"default": 0.0, "bounds": (-0.5, 0.5), "unit": "rad",
                         "description": "angle of the first target hole from +x"},
    "target_radius_mm": {"default": 3.0, "bounds": (2.0, 4.0), "unit": "mm", "description": "target hole radius"},
}
VIEW_DIRECTION = (0.0, 0.0, 1.0)
FIXED_HOLES = "bore r 30.75; 4 x M16 bolt holes r 9.0 on the 125 mm bolt circle at 45 + k 90 deg"
OUTER_R, THICK, RF_R, RF_H, BORE_R = 82.5, 18.0, 51.0, 3.0, 30.75
BOLT_CIRCLE_R, BOLT_R, TARGET_DEPTH = 62.5, 9.0, 4.0


def bolt_centres():
    return [(BOLT_CIRCLE_R * math.cos(math.radians(a)), BOLT_CIRCLE_R * math.sin(math.radians(a)))
            for a in (45, 135, 225, 315)]


def build(target_circle_radius_mm, target_angle_rad, target_radius_mm):
    body = cq.Solid.makeCylinder(OUTER_R, THICK).fuse(cq.Solid.makeCylinder(RF_R, RF_H, cq.Vector(0, 0, THICK)))
    body = body.clean()
    cuts = [cq.Solid.makeCylinder(BORE_R, THICK + RF_H + 2, cq.Vector(0, 0, -1))]
    cuts += [cq.Solid.makeCylinder(BOLT_R, THICK + 2, cq.Vector(x, y, -1)) for x, y in bolt_centres()]
    for a in (target_angle_rad, target_angle_rad + math.pi):
        r = target_circle_radius_mm
        p = cq.Vector(r * math.cos(a), r * math.sin(a), THICK - TARGET_DEPTH)
        cuts.append(cq.Solid.makeCylinder(target_radius_mm, TARGET_DEPTH + 1, p))
    return cq.Workplane("XY").add(body.cut(*cuts))


def expected_holes(target_circle_radius_mm, target_angle_rad, target_radius_mm):
    up = (0.0, 0.0, 1.0)
    out = [{"centre": (0.0, 0.0, THICK + RF_H), "axis": up, "radius_mm": BORE_R, "fixed": True}]
    out += [{"centre": (x, y, THICK), "axis": up, "radius_mm": BOLT_R, "fixed": True} for x, y in bolt_centres()]
    for a in (target_angle_rad, target_angle_rad + math.pi):
        out.append({"centre": (target_circle_radius_mm * math.cos(a), target_circle_radius_mm * math.sin(a), THICK),
                    "axis": up, "radius_mm": target_radius_mm})
    return out


if "show_object" in globals():  # cq-editor
    show_object(build(**{k: v["default"] for k, v in PARAMETERS.items()}))  # noqa: F821
