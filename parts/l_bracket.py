"""L-bracket (angle bracket) with countersunk, counterbored and vision-target holes on two faces.

Frame: upright flange y in [0, 6], z in [0, 50], x in [-30, 30]; base flange y in [-44, 6], z in [0, 6];
inner corner filleted (radius 4 mm, a concave fillet: not a hole). Upright front face y = 0 (normal -y),
base top face z = 6 (normal +z): two perpendicular planes.

Functional / fixed holes: 2 × M6 counterbored holes in the upright, bore Ø6.6, counterbore Ø11 × 3 mm deep,
at (±15, 0, 35) (they take the mating part's screws).
Movable: 2 × M5 countersunk holes (90°, Ø10.4 at the surface, bore Ø5.5) in the base at
(±base_hole_spacing_mm/2, base_hole_y_mm, 6): the bracket's own fixing to the table.
Free (vision targets): a blind hole in the upright at (target_upright_x_mm, 0, target_upright_z_mm) and one in
the base top at (target_base_x_mm, -30, 6), radius target_radius_mm, 3 mm deep.
"""

import cadquery as cq

DESCRIPTION = "L-bracket: fixed counterbored M6 in the upright, movable countersunk M5 in the base, 2 targets"
PARAMETERS = {
    "base_hole_spacing_mm": {"default": 36.0, "bounds": (30.0, 44.0), "unit": "mm",
                             "description": "distance between the two countersunk base holes"},
    "base_hole_y_mm": {"default": -22.0, "bounds": (-36.0, -14.0), "unit": "mm",
                       "description": "y of the countersunk base holes"},
    "target_upright_x_mm": {"default": 0.0, "bounds": (-6.0, 6.0), "unit": "mm", "description": "upright target x"},
    "target_upright_z_mm": {"default": 22.0, "bounds": (16.0, 44.0), "unit": "mm", "description": "upright target z"},
    "target_base_x_mm": {"default": 0.0, "bounds": (-5.0, 5.0), "unit": "mm", "description": "base target x"},
    "target_radius_mm": {"default": 2.0, "bounds": (1.0, 3.0), "unit": "mm", "description": "target hole radius"},
}
VIEW_DIRECTION = (0.0, -1.0, 1.0)
FIXED_HOLES = "2 x M6 counterbored (bore r 3.3, counterbore r 5.5 x 3) in the upright at (+-15, 0, 35)"
W, T, H, D, FILLET = 60.0, 6.0, 50.0, 44.0, 4.0
CB_BORE_R, CB_R, CB_DEPTH, CB_Z = 3.3, 5.5, 3.0, 35.0
CS_BORE_R, CS_R = 2.75, 5.2
TARGET_DEPTH, TARGET_BASE_Y = 3.0, -30.0


def build(base_hole_spacing_mm, base_hole_y_mm, target_upright_x_mm, target_upright_z_mm, target_base_x_mm,
          target_radius_mm):
    body = cq.Solid.makeBox(W, T, H, cq.Vector(-W / 2, 0, 0)).fuse(
        cq.Solid.makeBox(W, D + T, T, cq.Vector(-W / 2, -D, 0))).clean()
    corner = [e for e in body.Edges() if (e.Center() - cq.Vector(0, 0, T)).Length < 1e-6]
    body = body.fillet(FILLET, corner)
    y_dir, down = cq.Vector(0, 1, 0), cq.Vector(0, 0, -1)
    cuts = []
    for sx in (-1, 1):
        cuts.append(cq.Solid.makeCylinder(CB_BORE_R, T + 2, cq.Vector(sx * 15.0, -1, CB_Z), y_dir))
        cuts.append(cq.Solid.makeCylinder(CB_R, CB_DEPTH + 1, cq.Vector(sx * 15.0, -1, CB_Z), y_dir))
        x = sx * base_hole_spacing_mm / 2
        cuts.append(cq.Solid.makeCylinder(CS_BORE_R, T + 2, cq.Vector(x, base_hole_y_mm, -1)))
        cuts.append(cq.Solid.makeCone(CS_R, CS_BORE_R, CS_R - CS_BORE_R, cq.Vector(x, base_hole_y_mm, T), down))
        cuts.append(cq.Solid.makeCylinder(CS_R, 1.0, cq.Vector(x, base_hole_y_mm, T)))
    cuts.append(cq.Solid.makeCylinder(target_radius_mm, TARGET_DEPTH + 1,
                                      cq.Vector(target_upright_x_mm, -1, target_upright_z_mm), y_dir))
    cuts.append(cq.Solid.makeCylinder(target_radius_mm, TARGET_DEPTH + 1,
                                      cq.Vector(target_base_x_mm, TARGET_BASE_Y, T - TARGET_DEPTH)))
    return cq.Workplane("XY").add(body.cut(*cuts))


def expected_holes(base_hole_spacing_mm, base_hole_y_mm, target_upright_x_mm, target_upright_z_mm, target_base_x_mm,
                   target_radius_mm):
    front, up = (0.0, -1.0, 0.0), (0.0, 0.0, 1.0)
    out = [{"centre": (sx * 15.0, 0.0, CB_Z), "axis": front, "radius_mm": CB_R, "kind": "counterbore", "fixed": True}
           for sx in (-1, 1)]
    out += [{"centre": (sx * base_hole_spacing_mm / 2, base_hole_y_mm, T), "axis": up, "radius_mm": CS_R,
             "kind": "countersink"} for sx in (-1, 1)]
    out.append({"centre": (target_upright_x_mm, 0.0, target_upright_z_mm), "axis": front,
                "radius_mm": target_radius_mm, "kind": "plain"})
    out.append({"centre": (target_base_x_mm, TARGET_BASE_Y, T), "axis": up, "radius_mm": target_radius_mm,
                "kind": "plain"})
    return out


if "show_object" in globals():  # cq-editor
    show_object(build(**{k: v["default"] for k, v in PARAMETERS.items()}))  # noqa: F821
