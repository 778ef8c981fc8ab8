"""A VESA-style monitor mount plate: four bolt holes on a square pattern and a cable pass-through.

Written for cadfeat's tests in the style of cq-editor / cq-warehouse scripts (top-level constants,
describe_parameter, show_object); it carries its bounds in cadfeat's comment convention
``# [lower, upper] unit`` and runs unchanged in cq-editor and cq-cli.
"""

import cadquery as cq

plate_size = 120.0      # [100, 160] mm  side of the square plate
plate_thickness = 6.0   # mm  (no bounds comment: a study gives bounds if it varies it)
pattern = 100.0         # [60, 110] mm  VESA hole pattern (square side)
bolt_diameter = 4.5     # [3.4, 6.6] mm
cable_x = 0.0           # [-30, 30] mm  cable hole position
cable_diameter = 20.0   # [10, 30] mm
hole_count = 4          # not a design variable here: an integer constant

describe_parameter(bolt_diameter, "clearance hole for the M4 mounting screws")

plate = cq.Workplane("XY").box(plate_size, plate_size, plate_thickness).edges("|Z").fillet(4.0)
result = (
    plate.faces(">Z").workplane()
    .rect(pattern, pattern, forConstruction=True).vertices().hole(bolt_diameter)
    .faces(">Z").workplane().center(cable_x, 0).hole(cable_diameter)
)

show_object(result, name="vesa_plate")
