"""Fig. 1.2-style industrial plate: assembly holes, some functional (fixed), four re-designable holes.

After the thesis's Fig. 1.2 (Shademan 2005, §1.3): a plate whose holes assemble other parts to it; four
of them are free to be re-designed for vision-guided manipulation (the arrows of Fig. 1.2 (c)).
Plate 120 × 80 × 10 mm, top face z = 0 (the plate spans z in [-10, 0]), frame at the plate centre.

Functional / fixed holes (they assemble the mating parts; do not move):
- 4 × M6 clearance through holes, Ø6.6 mm, at (±50, ±30): bolts to the machine frame;
- the central bearing seat: Ø24 mm through bore with a Ø32 mm × 4 mm counterbore at (0, 0);
- 2 × Ø6 mm dowel-pin holes, blind 8 mm deep, at (±25, 0): locate the mating part.
Free holes (design variables, for a vision target): 4 × through holes of radius ``target_radius_mm`` at
(target_k_x_mm, target_k_y_mm), k = 1..4 (one per quadrant by default).
"""

import cadquery as cq

DESCRIPTION = "Fig. 1.2-style plate: 4 corner bolts, bearing seat, 2 dowels (fixed) + 4 free target holes"
_TARGETS = {1: (-35.0, 18.0), 2: (35.0, 18.0), 3: (-35.0, -18.0), 4: (35.0, -18.0)}
PARAMETERS = {}
for _k, (_x, _y) in _TARGETS.items():
    _sx, _sy = (1 if _x > 0 else -1), (1 if _y > 0 else -1)
    PARAMETERS[f"target_{_k}_x_mm"] = {"default": _x, "bounds": tuple(sorted((_sx * 8.0, _sx * 54.0))),
                                       "unit": "mm", "description": f"target hole {_k}: centre x"}
    PARAMETERS[f"target_{_k}_y_mm"] = {"default": _y, "bounds": tuple(sorted((_sy * 6.0, _sy * 34.0))),
                                       "unit": "mm", "description": f"target hole {_k}: centre y"}
PARAMETERS["target_radius_mm"] = {"default": 2.5, "bounds": (1.5, 4.0), "unit": "mm",
                                  "description": "radius of the four target holes"}
VIEW_DIRECTION = (0.0, 0.0, 1.0)
FIXED_HOLES = ("4 x M6 clearance (r 3.3) at (+-50, +-30); bearing bore r 12 with counterbore r 16 x 4 at (0, 0); "
               "2 dowels r 3 x 8 deep at (+-25, 0)")
PLATE_MM = (120.0, 80.0, 10.0)
BOLT_R, BORE_R, CBORE_R, CBORE_DEPTH, DOWEL_R, DOWEL_DEPTH = 3.3, 12.0, 16.0, 4.0, 3.0, 8.0


def build(**p):
    sx, sy, sz = PLATE_MM
    plate = cq.Solid.makeBox(sx, sy, sz, cq.Vector(-sx / 2, -sy / 2, -sz))

    def through(x, y, r):
        return cq.Solid.makeCylinder(r, sz + 2, cq.Vector(x, y, -sz - 1))

    cuts = [through(x, y, BOLT_R) for x in (-50, 50) for y in (-30, 30)]
    cuts += [through(0, 0, BORE_R), cq.Solid.makeCylinder(CBORE_R, CBORE_DEPTH + 1, cq.Vector(0, 0, -CBORE_DEPTH))]
    cuts += [cq.Solid.makeCylinder(DOWEL_R, DOWEL_DEPTH + 1, cq.Vector(x, 0, -DOWEL_DEPTH)) for x in (-25, 25)]
    cuts += [through(p[f"target_{k}_x_mm"], p[f"target_{k}_y_mm"], p["target_radius_mm"]) for k in _TARGETS]
    return cq.Workplane("XY").add(plate.cut(*cuts))


def expected_holes(**p):
    up = (0.0, 0.0, 1.0)
    out = [{"centre": (x, y, 0.0), "axis": up, "radius_mm": BOLT_R, "fixed": True}
           for x in (-50, 50) for y in (-30, 30)]
    out.append({"centre": (0.0, 0.0, 0.0), "axis": up, "radius_mm": CBORE_R, "fixed": True})
    out += [{"centre": (x, 0.0, 0.0), "axis": up, "radius_mm": DOWEL_R, "fixed": True} for x in (-25.0, 25.0)]
    out += [{"centre": (p[f"target_{k}_x_mm"], p[f"target_{k}_y_mm"], 0.0), "axis": up,
             "radius_mm": p["target_radius_mm"]} for k in _TARGETS]
    return out


if "show_object" in globals():  # cq-editor
    show_object(build(**{k: v["default"] for k, v in PARAMETERS.items()}))  # noqa: F821
