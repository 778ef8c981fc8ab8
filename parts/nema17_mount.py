"""NEMA 17 stepper-motor mount: an L-shaped bracket, motor face vertical, base flange horizontal.

Frame: base flange on z in [0, 5] spanning x in [-35, 35], y in [0, 70]; the motor plate (5 mm) stands on
it at y in [0, 5], up to z = 58. The motor's front face is the plate face y = 0 (normal -y), the motor
axis is at (x, z) = (0, 30) along y; the motor body sits behind the plate, over the base flange.

Functional / fixed holes (NEMA 17 interface, ISO/NEMA ICS 16): the 22 mm pilot bore (radius 11.0 mm)
and 4 × M3 clearance holes (Ø3.4 mm) on the 31 mm square around the motor axis; two fixed Ø5.5 mm
adjustment slots in the base flange at x = ±29 (y 12..32; not holes: partial cylinders — keep-outs).
Movable: 2 × M5 clearance (Ø5.5 mm) base mounting holes at (±base_hole_x_mm, base_hole_y_mm).
Free (vision targets, design variables): a blind hole in the motor face at (target_face_x_mm, 0,
target_face_z_mm), and a blind hole in the base flange top at (target_base_x_mm, target_base_y_mm, 5);
both of radius target_radius_mm, target_depth_mm deep (default 2 mm; 1–4 mm leaves at least 1 mm of the 5 mm
plate under the bottom), with a 45° rim chamfer of target_chamfer_mm (default 0: a sharp rim; up to 0.8 mm, a
deburring chamfer — the rim the camera sees then has radius target_radius_mm + target_chamfer_mm). A shallow,
chamfered rim images as a clean ellipse; a deep narrow bore seen obliquely shows its wall (issue 17). The two
faces are perpendicular: non-coplanar features.
"""

import cadquery as cq

DESCRIPTION = "NEMA 17 L-mount: fixed motor pattern + pilot, movable base holes, two vision target holes"
PARAMETERS = {
    "base_hole_x_mm": {"default": 29.0, "bounds": (25.0, 31.0), "unit": "mm",
                       "description": "base mounting holes at x = +-this"},
    "base_hole_y_mm": {"default": 45.0, "bounds": (40.0, 64.0), "unit": "mm", "description": "base mounting holes y"},
    "target_face_x_mm": {"default": 28.0, "bounds": (24.0, 31.0), "unit": "mm",
                         "description": "motor-face target hole x (outside the motor outline)"},
    "target_face_z_mm": {"default": 45.0, "bounds": (10.0, 52.0), "unit": "mm",
                         "description": "motor-face target hole height z"},
    "target_base_x_mm": {"default": 0.0, "bounds": (-15.0, 15.0), "unit": "mm", "description": "base target hole x"},
    "target_base_y_mm": {"default": 60.0, "bounds": (56.0, 64.0), "unit": "mm", "description": "base target hole y"},
    "target_radius_mm": {"default": 2.0, "bounds": (1.0, 3.0), "unit": "mm", "description": "target hole radius"},
    "target_depth_mm": {"default": 2.0, "bounds": (1.0, 4.0), "unit": "mm",
                        "description": "target hole depth (blind; >= 1 mm of the 5 mm plate stays under it)"},
    "target_chamfer_mm": {"default": 0.0, "bounds": (0.0, 0.8), "unit": "mm",
                          "description": "45 deg chamfer of the target holes' rims (0: sharp)"},
}
VIEW_DIRECTION = (0.0, -1.0, 1.0)
FIXED_HOLES = "pilot bore r 11.0 and 4 x M3 clearance (r 1.7) on the 31 mm square; base slots at x = +-29"
W, D, T, H, MOTOR_Z = 70.0, 70.0, 5.0, 58.0, 30.0
PILOT_R, M3_R, M3_HALF, M5_R = 11.0, 1.7, 15.5, 2.75
OUTSIDE = 1.0  # the cutting tools start this far outside the face (no coplanar boolean)
SLOT = (29.0, 12.0, 32.0)  # x, y from, y to


def _face_holes():
    yield (0.0, MOTOR_Z), PILOT_R
    for sx in (-1, 1):
        for sz in (-1, 1):
            yield (sx * M3_HALF, MOTOR_Z + sz * M3_HALF), M3_R


def _target(point, inward, radius, depth, chamfer):
    """The cutting tool of a blind target hole entering the face at ``point`` along ``inward``: a drill of
    ``radius`` to ``depth`` and, when ``chamfer`` > 0, a 45° cone widening the rim to ``radius + chamfer``."""
    p, d = cq.Vector(*point), cq.Vector(*inward)
    start = p - d * OUTSIDE
    tool = cq.Solid.makeCylinder(radius, depth + OUTSIDE, start, d)
    if chamfer > 0:
        tool = tool.fuse(cq.Solid.makeCone(radius + chamfer + OUTSIDE, radius, chamfer + OUTSIDE, start, d))
    return tool


def build(base_hole_x_mm, base_hole_y_mm, target_face_x_mm, target_face_z_mm, target_base_x_mm, target_base_y_mm,
          target_radius_mm, target_depth_mm=2.0, target_chamfer_mm=0.0):
    profile = [(0, 0), (D, 0), (D, T), (T, T), (T, H), (0, H)]  # (y, z) of the L section
    body = cq.Workplane("YZ", origin=(-W / 2, 0, 0)).polyline(profile).close().extrude(W).val()
    y_dir = cq.Vector(0, 1, 0)
    cuts = [cq.Solid.makeCylinder(r, T + 2, cq.Vector(x, -1, z), y_dir) for (x, z), r in _face_holes()]
    cuts.append(_target((target_face_x_mm, 0, target_face_z_mm), (0, 1, 0), target_radius_mm, target_depth_mm,
                        target_chamfer_mm))
    cuts += [cq.Solid.makeCylinder(M5_R, T + 2, cq.Vector(sx * base_hole_x_mm, base_hole_y_mm, -1)) for sx in (-1, 1)]
    cuts.append(_target((target_base_x_mm, target_base_y_mm, T), (0, 0, -1), target_radius_mm, target_depth_mm,
                        target_chamfer_mm))
    x, y0, y1 = SLOT
    slots = (cq.Workplane("XY", origin=(0, 0, -1)).pushPoints([(-x, (y0 + y1) / 2), (x, (y0 + y1) / 2)])
             .slot2D(y1 - y0 + 2 * M5_R, 2 * M5_R, angle=90).extrude(T + 2))
    cuts += slots.vals()
    return cq.Workplane("XY").add(body.cut(*cuts))


def expected_holes(base_hole_x_mm, base_hole_y_mm, target_face_x_mm, target_face_z_mm, target_base_x_mm,
                   target_base_y_mm, target_radius_mm, target_depth_mm=2.0, target_chamfer_mm=0.0):
    front, up = (0.0, -1.0, 0.0), (0.0, 0.0, 1.0)
    rim = target_radius_mm + target_chamfer_mm
    out = [{"centre": (x, 0.0, z), "axis": front, "radius_mm": r, "fixed": True} for (x, z), r in _face_holes()]
    out.append({"centre": (target_face_x_mm, 0.0, target_face_z_mm), "axis": front, "radius_mm": rim,
                "depth_mm": target_depth_mm})
    out += [{"centre": (sx * base_hole_x_mm, base_hole_y_mm, T), "axis": up, "radius_mm": M5_R} for sx in (-1, 1)]
    out.append({"centre": (target_base_x_mm, target_base_y_mm, T), "axis": up, "radius_mm": rim,
                "depth_mm": target_depth_mm})
    return out


if "show_object" in globals():  # cq-editor
    show_object(build(**{k: v["default"] for k, v in PARAMETERS.items()}))  # noqa: F821
