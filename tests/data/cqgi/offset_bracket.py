"""An offset bracket, written as a user writes a cq-editor script: negative constants, annotated constants, a
constant at zero, a boolean and a string (cadfeat's tests: every top-level constant is a parameter)."""

import cadquery as cq

length = 120.0              # [100, 140] mm  plate length
width = 90.0
thickness = 6.0
offset_y = -12.0            # [-12, 0] mm  y of the bolt circle's centre
bolt_circle: float = 50.0   # [40, 56] mm  bolt circle diameter
phase_deg = -15.0           # [-45, 45] deg  angle of the first bolt hole
shift_x = 0.0               # [-10, 10] mm  x of the bolt circle's centre
bolt_count: int = 3
bolt_dia = 5.5
chamfered = False
label = "bracket"

describe_parameter(offset_y, "centre of the bolt circle below the plate's middle")

plate = cq.Workplane("XY").box(length, width, thickness)
if chamfered:
    plate = plate.edges("|Z").chamfer(2.0)
result = (
    plate.faces(">Z").workplane(centerOption="CenterOfBoundBox").center(shift_x, offset_y)
    .polarArray(bolt_circle / 2, phase_deg, 360, bolt_count).hole(bolt_dia)
)
show_object(result, name=label)
