"""A small hydraulic manifold block, as people post cq-editor scripts: constants at the top (a string picks the
port size from a table, booleans switch features), a helper function and a loop that drill the ports, blind
ports on three faces, and through mounting holes with counterbores. Written here for cadfeat's corpus.
"""
import cadquery as cq

# block
block_x = 60.0   # [50, 80] mm
block_y = 40.0
block_z = 30.0
port_size = "G1/4"          # thread of the ports: a key of PORT_DRILL
side_ports = True           # drill the two side ports
chamfer_edges = False
# ports
inlet_offset = -12.0        # [-18, 0] mm  x of the inlet port on the top face
outlet_offset = 12.0        # [0, 18] mm  x of the outlet port on the top face
port_depth = 14.0
side_port_z = 2.0           # [-6, 6] mm  height of the side ports above the block's middle
# mounting: two counterbored through holes for M5 cap screws
mount_pitch = 44.0
mount_dia = 5.5
mount_cbore = 9.5
mount_cbore_depth = 5.5

PORT_DRILL = {"G1/8": 8.8, "G1/4": 11.8, "G3/8": 15.25}  # thread minor diameters (mm)


def drill_port(wp, points, diameter, depth):
    """Blind ports at points of the workplane wp."""
    return wp.pushPoints(points).hole(diameter, depth)


body = cq.Workplane("XY").box(block_x, block_y, block_z)
if chamfer_edges:
    body = body.edges().chamfer(1.0)

drill = PORT_DRILL[port_size]
body = drill_port(body.faces(">Z").workplane(centerOption="CenterOfBoundBox"),
                  [(inlet_offset, 0.0), (outlet_offset, 0.0)], drill, port_depth)
if side_ports:
    for face in ("<Y", ">Y"):
        body = drill_port(body.faces(face).workplane(centerOption="CenterOfBoundBox"),
                          [(0.0, side_port_z)], drill * 0.75, port_depth)

result = (
    body.faces("<Z").workplane(centerOption="CenterOfBoundBox")
    .rarray(mount_pitch, 1.0, 2, 1)
    .cboreHole(mount_dia, mount_cbore, mount_cbore_depth)
)
show_object(result, name="manifold")
