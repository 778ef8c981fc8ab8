"""Test part of the robust redesign (issue 18): a razor-edge optimum.

A 340 x 60 x 6 mm plate with three fixed 4 mm holes ((0, 0), (−40, ±15)) and a movable 4 mm target hole at
(x, 0) on the top face. A camera straight above the centre approaching the plate resolves the motion best (the
target's image speed, and with it the resolvability Λ, grows with x) when x is as large as the image allows: the
nominal optimum puts the target exactly on the image border at the nearest pose — seen only from the exact camera
pose, through the narrow gap between the image border and the plate's edge. A camera mounting error of a degree
pushes it out of the image in many cells; the robust optimum keeps it a few millimetres inside.
"""

PARAMETERS = {
    "x": {"default": 60.0, "bounds": (20.0, 165.0), "unit": "mm", "description": "x of the target hole"},
}
FIXED_HOLES = "the three 4 mm holes at (0, 0) and (-40, ±15) are dowel holes and may not move"
VIEW_DIRECTION = (0.0, 0.0, 1.0)
DESCRIPTION = "Plate with a target hole whose best place is on the image border (robust redesign tests)."


def build(x=60.0):
    import cadquery as cq

    plate = cq.Workplane("XY").box(340.0, 60.0, 6.0, centered=(True, True, False))
    wp = plate.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0))
    plate = wp.pushPoints([(x, 0.0)]).hole(4.0)
    wp = plate.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0))
    return wp.pushPoints([(0.0, 0.0), (-40.0, -15.0), (-40.0, 15.0)]).hole(4.0)


if "show_object" in globals():  # pragma: no cover - cq-editor
    show_object(build())  # noqa: F821
