"""Test part for the occlusion tests: a 100 x 40 x 5 mm plate with a 6 mm thick, 15 mm high wall across it
(x = 10 … 16 mm) and one through hole right of the wall at (hole_x, 0). Seen from the left and above, the
wall hides the hole when it is close to the wall."""

PARAMETERS = {
    "hole_x": {"default": 22.0, "bounds": (20.0, 45.0), "unit": "mm", "description": "x of the hole"},
}
VIEW_DIRECTION = (0.0, 0.0, 1.0)
DESCRIPTION = "Plate with a wall that can hide a hole (occlusion tests)."
WALL = ((10.0, 16.0), (-20.0, 20.0), (5.0, 20.0))  # x, y, z ranges of the wall, mm


def build(hole_x=22.0):
    import cadquery as cq

    plate = cq.Workplane("XY").box(100.0, 40.0, 5.0, centered=(True, True, False))
    plate = plate.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0)) \
        .pushPoints([(hole_x, 0.0)]).hole(3.0)
    (x0, x1), (y0, y1), (z0, z1) = WALL
    wall = cq.Workplane("XY").box(x1 - x0, y1 - y0, z1 - z0, centered=False).translate((x0, y0, z0))
    return plate.union(wall)
