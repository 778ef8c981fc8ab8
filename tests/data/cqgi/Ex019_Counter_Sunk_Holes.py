import cadquery as cq

# These can be modified rather than hardcoding values for each dimension.
length = 4.0  # Length of the plate
width = 2.0  # Width of the plate
thickness = 0.5  # Thickness of the plate
hole_spacing_x = 3.5  # Spacing of the holes along the length
hole_spacing_y = 1.5  # Spacing of the holes along the width
hole_diameter = 0.125  # Diameter of the through hole
csk_diameter = 0.25  # Diameter of the countersink
csk_angle = 82.0  # Countersink angle (complete angle)

# Create a plate with 4 counter-sunk holes in it.
# 1.  Establishes a workplane using an XY object instead of a named plane.
# 2.  Creates a plain box to base future geometry on with the box() function.
# 3.  Selects the top-most face of the box and established a workplane on that.
# 4.  Draws a for-construction rectangle on the workplane which only exists for
#     placing other geometry.
# 5.  Selects the corner vertices of the rectangle and places a counter-sink
#     hole, using each vertex as the center of a hole using the cskHole()
#     function.
# 5a. When the depth of the counter-sink hole is set to None, the hole will be
#     cut through.
result = (
    cq.Workplane(cq.Plane.XY())
    .box(length, width, thickness)
    .faces(">Z")
    .workplane()
    .rect(hole_spacing_x, hole_spacing_y, forConstruction=True)
    .vertices()
    .cskHole(hole_diameter, csk_diameter, csk_angle, depth=None)
)

# Displays the result of this script
show_object(result)
