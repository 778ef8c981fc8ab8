"""Fault injection (issue 16): the study plate (tests/data/study_plate.py) whose ``build`` raises for a first hole
at -16 < x0 < -13 mm — a "kernel failure in this region", which contains the study's optimum (x0 ≈ -14.65 mm
for tests/study/test_build_failures.py's study). Everywhere else it is the study plate.
"""

FAIL_X0_MM = (-16.0, -13.0)
PARAMETERS = {
    "x0": {"default": -10.0, "bounds": (-20.0, 0.0), "unit": "mm", "description": "x of the first hole"},
    "y0": {"default": 5.0, "bounds": (-10.0, 12.0), "unit": "mm", "description": "y of the hole row"},
    "pitch": {"default": 10.0, "bounds": (6.0, 14.0), "unit": "mm", "description": "hole spacing"},
    "diameter": {"default": 4.0, "bounds": (2.0, 6.0), "unit": "mm", "description": "hole diameter"},
    "count": {"default": 3, "bounds": (2, 4), "unit": "", "description": "number of holes in the row"},
}
FIXED_HOLES = "the 4 mm hole at (-22, -12) is a dowel hole and may not move"
VIEW_DIRECTION = (0.0, 0.0, 1.0)
DESCRIPTION = "Plate with a row of holes whose build fails in a region of x0 (fault injection)."


def build(x0=-10.0, y0=5.0, pitch=10.0, diameter=4.0, count=3):
    import cadquery as cq

    if FAIL_X0_MM[0] < x0 < FAIL_X0_MM[1]:
        raise RuntimeError("kernel failure in this region")
    plate = cq.Workplane("XY").box(60.0, 40.0, 6.0, centered=(True, True, False))
    pts = [(x0 + i * pitch, y0) for i in range(int(count))]
    plate = plate.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0)).pushPoints(pts).hole(diameter)
    plate = plate.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0)) \
        .pushPoints([(-22.0, -12.0)]).hole(4.0)
    return plate
