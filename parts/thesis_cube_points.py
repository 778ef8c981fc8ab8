"""Thesis object, Fig. 5.1 (c): eight non-coplanar point features on the corners of a cube (§5.2.1, eq. 5.1).

The eight points are the entrance-rim centres of eight small holes at the corners of a cube of edge
``d_mm``: (±d/2, ±d/2, 0) and (±d/2, ±d/2, d). The part is a small "bridge" block: a base plate (top face
z = 0) carries four blind holes (radius 0.125 mm, depth 0.5 mm); a top plate 0.5 mm thick (top face z = d), held
by two side walls over a tunnel along y, carries four through holes (radius 0.25 mm) directly above them, so a
camera looking down sees all eight rims.

d ranges over 1–6 mm: §5.4.3's 2 ≤ d ≤ 6 mm and §5.4.4's reduced range below it (``studies/thesis_combined.toml``:
the thesis's max-min answer d = 1.41 mm is below 2 mm); the holes are small enough to leave d − 0.5 mm of material
between neighbours, 0.5 mm at d = 1 mm. (The thesis's features are points: the radii enter no thesis measure; Λ
counts a hole whose rim is in the image. They were 0.3 and 0.6 mm while d stayed within 2–6 mm.)

Note: eq. 5.1 lists the points as (±d, ±d, ±d), i.e. a cube of edge 2d, while the text calls d "the
length of the edge"; this part follows the text (edge d).

Functional / fixed holes: none.
"""

import cadquery as cq

DESCRIPTION = "Thesis Fig. 5.1(c): eight holes on the corners of a cube of edge d"
PARAMETERS = {
    "d_mm": {"default": 4.0, "bounds": (1.0, 6.0), "unit": "mm", "description": "edge of the cube d"},
}
VIEW_DIRECTION = (0.0, 0.0, 1.0)
FIXED_HOLES = "none"
LOWER_RADIUS_MM, LOWER_DEPTH_MM = 0.125, 0.5
UPPER_RADIUS_MM = 0.25
TOP_PLATE_MM, WALL_MM, MARGIN_MM, BASE_MM = 0.5, 1.0, 2.0, 1.0


def build(d_mm):
    a = d_mm / 2 + MARGIN_MM
    block = cq.Solid.makeBox(2 * a, 2 * a, d_mm + BASE_MM, cq.Vector(-a, -a, -BASE_MM))
    inner = a - WALL_MM
    tunnel = cq.Solid.makeBox(2 * inner, 2 * a + 2, d_mm - TOP_PLATE_MM, cq.Vector(-inner, -a - 1, 0))
    h = d_mm / 2
    xy = [(h, h), (-h, h), (-h, -h), (h, -h)]
    lower = [cq.Solid.makeCylinder(LOWER_RADIUS_MM, LOWER_DEPTH_MM + 0.1, cq.Vector(x, y, -LOWER_DEPTH_MM))
             for x, y in xy]
    # from 0.25 mm below the top plate (inside the tunnel, clear of the base for every d ≥ 1 mm) to above it
    upper = [cq.Solid.makeCylinder(UPPER_RADIUS_MM, TOP_PLATE_MM + 1.0,
                                   cq.Vector(x, y, d_mm - TOP_PLATE_MM - 0.25))
             for x, y in xy]
    return cq.Workplane("XY").add(block.cut(tunnel, *lower, *upper))


def expected_holes(d_mm):
    h, up = d_mm / 2, (0.0, 0.0, 1.0)
    out = []
    for z, r in ((0.0, LOWER_RADIUS_MM), (d_mm, UPPER_RADIUS_MM)):
        out += [{"centre": (sx * h, sy * h, z), "axis": up, "radius_mm": r} for sx in (1, -1) for sy in (1, -1)]
    return out


if "show_object" in globals():  # cq-editor
    show_object(build(**{k: v["default"] for k, v in PARAMETERS.items()}))  # noqa: F821
