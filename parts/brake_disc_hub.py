"""Brake-disc-like wheel hub (cf. thesis Fig. 5.4): disc, raised hub, stud circle, targets on three surfaces.

Frame: axis z; disc radius 70 mm on z in [0, 8] (disc face z = 8), hub boss radius 35 mm on z in [8, 28]
(hub face z = 28), centre bore radius 20 mm through everything.

Functional / fixed holes: the centre bore (r 20, on the axle) and 5 wheel-stud holes, Ø13 mm, on the
100 mm pitch circle at 90° + k·72° (5 × 100 wheel pattern), through the disc.
Free (vision targets, design variables):
- ``target_count`` blind holes (4 mm deep) in the disc face on a circle of radius target_circle_radius_mm,
  the first at target_phase_rad (centres NONLINEAR in the phase);
- one blind radial hole (6 mm deep) in the hub's cylindrical side at height radial_target_z_mm, pointing
  along +x: its host face is curved (the rim centre is where the axis meets the cylinder, (35, 0, z)).
All of radius target_radius_mm.
"""

import math

import cadquery as cq

DESCRIPTION = "Brake-disc-like hub: bore + 5 x 100 stud holes fixed; disc-face and radial hub target holes"
PARAMETERS = {
    "target_circle_radius_mm": {"default": 61.0, "bounds": (60.0, 64.0), "unit": "mm",
                                "description": "radius of the circle of disc-face target holes"},
    "target_phase_rad": {"default": 0.0, "bounds": (-0.5, 0.5), "unit": "rad",
                         "description": "angle of the first disc-face target hole from +x"},
    "target_count": {"default": 3, "bounds": (2, 4), "unit": "", "description": "number of disc-face targets"},
    "radial_target_z_mm": {"default": 18.0, "bounds": (13.0, 23.0), "unit": "mm",
                           "description": "height of the radial target hole in the hub side"},
    "target_radius_mm": {"default": 2.5, "bounds": (1.5, 3.5), "unit": "mm", "description": "target hole radius"},
}
VIEW_DIRECTION = (0.3, 0.0, 1.0)
FIXED_HOLES = "centre bore r 20; 5 x wheel-stud holes r 6.5 on the 100 mm pitch circle at 90 + k 72 deg"
DISC_R, DISC_T, HUB_R, HUB_TOP, BORE_R = 70.0, 8.0, 35.0, 28.0, 20.0
STUD_PCD_R, STUD_R, FACE_DEPTH, RADIAL_DEPTH = 50.0, 6.5, 4.0, 6.0


def studs():
    return [(STUD_PCD_R * math.cos(math.radians(90 + 72 * k)), STUD_PCD_R * math.sin(math.radians(90 + 72 * k)))
            for k in range(5)]


def targets(target_circle_radius_mm, target_phase_rad, target_count):
    return [(target_circle_radius_mm * math.cos(target_phase_rad + 2 * math.pi * k / target_count),
             target_circle_radius_mm * math.sin(target_phase_rad + 2 * math.pi * k / target_count))
            for k in range(target_count)]


def build(target_circle_radius_mm, target_phase_rad, target_count, radial_target_z_mm, target_radius_mm):
    profile = [(BORE_R, 0), (DISC_R, 0), (DISC_R, DISC_T), (HUB_R, DISC_T), (HUB_R, HUB_TOP), (BORE_R, HUB_TOP)]
    body = cq.Workplane("XZ").polyline(profile).close().revolve(360, (0, 0, 0), (0, 1, 0)).val()
    cuts = [cq.Solid.makeCylinder(STUD_R, DISC_T + 2, cq.Vector(x, y, -1)) for x, y in studs()]
    cuts += [cq.Solid.makeCylinder(target_radius_mm, FACE_DEPTH + 1, cq.Vector(x, y, DISC_T - FACE_DEPTH))
             for x, y in targets(target_circle_radius_mm, target_phase_rad, target_count)]
    cuts.append(cq.Solid.makeCylinder(target_radius_mm, RADIAL_DEPTH + 2,
                                      cq.Vector(HUB_R + 2, 0, radial_target_z_mm), cq.Vector(-1, 0, 0)))
    return cq.Workplane("XY").add(body.cut(*cuts))


def expected_holes(target_circle_radius_mm, target_phase_rad, target_count, radial_target_z_mm, target_radius_mm):
    up = (0.0, 0.0, 1.0)
    out = [{"centre": (0.0, 0.0, HUB_TOP), "axis": up, "radius_mm": BORE_R, "fixed": True}]
    out += [{"centre": (x, y, DISC_T), "axis": up, "radius_mm": STUD_R, "fixed": True} for x, y in studs()]
    out += [{"centre": (x, y, DISC_T), "axis": up, "radius_mm": target_radius_mm}
            for x, y in targets(target_circle_radius_mm, target_phase_rad, target_count)]
    out.append({"centre": (HUB_R, 0.0, radial_target_z_mm), "axis": (1.0, 0.0, 0.0), "radius_mm": target_radius_mm})
    return out


if "show_object" in globals():  # cq-editor
    show_object(build(**{k: v["default"] for k, v in PARAMETERS.items()}))  # noqa: F821
