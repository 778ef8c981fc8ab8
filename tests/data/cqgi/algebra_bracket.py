"""
An angle bracket written here for cadfeat's corpus in build123d's algebra style (``part = Box(...)``,
``part -= Pos(x, y, z) * Hole(...)``, ``Rot(X=90) * ...``), with plain cadquery underneath: the few build123d
names used are defined below on ``cadquery.func`` shapes, and the result is shown as build123d shows a ``Part``,
an object whose ``.wrapped`` is the OCP shape.

Base plate in XY with two counterbored holes from the top; an upright plate along the back edge with three
plain through holes in its face (axis along y).
"""
import cadquery as cq
from cadquery.func import box, cylinder

length, width, thickness = 80.0, 50.0, 8.0
upright_height: float = 60.0
base_hole_x = 25.0           # [15, 32] mm  the base holes at x = ±base_hole_x
base_hole_y = 5.0            # [-5, 12] mm
cbore_hole_radius = 2.75
cbore_radius = 5.0
cbore_depth = 4.0
face_hole_z = 38.0           # [25, 55] mm  height of the upright's holes
face_hole_pitch = 24.0       # [16, 30] mm
face_hole_radius = 3.0       # [2, 4] mm


class Pos(cq.Location):
    """build123d's Pos: ``Pos(x, y, z) * shape`` is the shape moved by (x, y, z)."""

    def __init__(self, x: float = 0.0, y: float = 0.0, z: float = 0.0):
        super().__init__(cq.Vector(x, y, z))

    def __mul__(self, other):
        return other.moved(self) if isinstance(other, cq.Shape) else super().__mul__(other)


class Rot(cq.Location):
    """build123d's Rot about one axis: ``Rot(X=90) * shape``."""

    def __init__(self, X: float = 0.0, Y: float = 0.0, Z: float = 0.0):
        axis = (1, 0, 0) if X else (0, 1, 0) if Y else (0, 0, 1)
        super().__init__(cq.Vector(0, 0, 0), cq.Vector(*axis), X or Y or Z)

    def __mul__(self, other):
        return other.moved(self) if isinstance(other, cq.Shape) else super().__mul__(other)


class Part:
    """The shown object, as build123d's Part: the OCP shape is ``.wrapped``."""

    def __init__(self, shape: cq.Shape):
        self.wrapped = shape.wrapped


def Box(x: float, y: float, z: float) -> cq.Shape:
    """A box centred on the origin (build123d's default alignment)."""
    return Pos(0, 0, -z / 2) * box(x, y, z)


def Hole(radius: float, depth: float) -> cq.Shape:
    """A drill going down from z = 0."""
    return Pos(0, 0, -depth) * cylinder(2 * radius, depth)


def CounterBoreHole(radius: float, counter_bore_radius: float, counter_bore_depth: float, depth: float) -> cq.Shape:
    """A counterbored drill going down from z = 0."""
    return Hole(radius, depth) + Hole(counter_bore_radius, counter_bore_depth)


base = Pos(0, 0, thickness / 2) * Box(length, width, thickness)
upright = Pos(0, -width / 2 + thickness / 2, upright_height / 2) * Box(length, thickness, upright_height)
part = base + upright

for x in (-base_hole_x, base_hole_x):
    part -= Pos(x, base_hole_y, thickness) * CounterBoreHole(cbore_hole_radius, cbore_radius, cbore_depth,
                                                              thickness)
for k in (-1, 0, 1):
    part -= Pos(k * face_hole_pitch, -width / 2 + thickness, face_hole_z) * (Rot(X=-90) * Hole(face_hole_radius,
                                                                                            thickness))

bracket = Part(part.clean())
show_object(bracket)
