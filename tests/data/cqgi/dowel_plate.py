"""A 6 mm plate with two functional dowel through holes and one blind target hole free to move: a user's
cq-editor script (cadfeat's tests: a through hole keeps its identity and its entrance on the camera's side).

The top edges are broken (a 0.5 mm chamfer), so the top face is smaller than the bottom face: extraction's own
rule without a view (the larger host face) would call the bottom the dowel holes' entrance; the camera is above."""

import cadquery as cq

length = 80.0
width = 50.0
thickness = 6.0
dowel_dia = 5.5           # the two dowel holes: functional, not design variables
target_x = 10.0           # [0, 25] mm  x of the blind target hole
target_y = 0.0            # [-12, 12] mm  y of the blind target hole
target_dia = 8.0          # [5, 12] mm
target_depth = 3.0

edge_break = 0.5
plate = cq.Workplane("XY").box(length, width, thickness).edges(">Z").chamfer(edge_break)
result = (
    plate.faces(">Z").workplane().pushPoints([(-30.0, 15.0), (-30.0, -15.0)]).hole(dowel_dia)
    .faces(">Z").workplane().center(target_x, target_y).hole(target_dia, target_depth)
)
show_object(result)
