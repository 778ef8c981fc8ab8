"""Test part for the study tests: a 60 x 40 x 6 mm plate with a row of ``count`` through holes.

Hole i (0-based) is at x = x0 + i * pitch, y = y0 on the top face (z = 6); a fixed functional hole of
diameter 4 mm sits at (-22, -12). ``count`` is an integer parameter.
"""

PARAMETERS = {
    "x0": {"default": -10.0, "bounds": (-20.0, 0.0), "unit": "mm", "description": "x of the first hole"},
    "y0": {"default": 5.0, "bounds": (-10.0, 12.0), "unit": "mm", "description": "y of the hole row"},
    "pitch": {"default": 10.0, "bounds": (6.0, 14.0), "unit": "mm", "description": "hole spacing"},
    "diameter": {"default": 4.0, "bounds": (2.0, 6.0), "unit": "mm", "description": "hole diameter"},
    "count": {"default": 3, "bounds": (2, 4), "unit": "", "description": "number of holes in the row"},
}
FIXED_HOLES = "the 4 mm hole at (-22, -12) is a dowel hole and may not move"
VIEW_DIRECTION = (0.0, 0.0, 1.0)
DESCRIPTION = "Plate with a row of holes (study tests)."


def build(x0=-10.0, y0=5.0, pitch=10.0, diameter=4.0, count=3):
    import cadquery as cq

    plate = cq.Workplane("XY").box(60.0, 40.0, 6.0, centered=(True, True, False))
    pts = [(x0 + i * pitch, y0) for i in range(int(count))]
    plate = plate.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0)).pushPoints(pts).hole(diameter)
    plate = plate.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0)) \
        .pushPoints([(-22.0, -12.0)]).hole(4.0)
    return plate


if "show_object" in globals():  # pragma: no cover - cq-editor
    show_object(build())  # noqa: F821
