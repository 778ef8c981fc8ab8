"""
Parametric hub flange, written here for cadfeat's corpus in the style of cq_warehouse's parametric parts
(a class that holds the part's parameters, derived properties, a private ``_make_...`` method that builds a
``cq_object``, and an extension method bound to ``cq.Workplane``); the script's constants feed the class and the
result goes to ``show_object``.

A round flange plate with a hub: a central bore through plate and hub, a bolt circle of through holes in the
plate (cut through all from circles, as cq_warehouse's Sprocket cuts its mounting holes), and one radial
set-screw hole into the side of the hub.
"""
from dataclasses import dataclass
from math import cos, pi, radians, sin

import cadquery as cq

flange_diameter = 120.0
flange_thickness = 10.0
hub_diameter = 50.0
hub_height = 20.0
bore_diameter = 22.0            # [16, 30] mm
bolt_circle_diameter = 90.0     # [80, 100] mm
num_mount_bolts = 6
mount_bolt_diameter = 9.0       # [6.6, 11] mm
bolt_phase_deg = 0.0            # [0, 30] deg
set_screw_diameter = 5.0


def _bolt_pattern(self, radius: float, count: int, diameter: float, phase_deg: float = 0.0) -> cq.Workplane:
    """cq.Workplane extension: cut ``count`` holes of ``diameter`` on a circle through the whole part."""
    points = [(radius * cos(radians(phase_deg) + 2 * pi * i / count),
               radius * sin(radians(phase_deg) + 2 * pi * i / count)) for i in range(count)]
    return self.pushPoints(points).circle(diameter / 2).cutThruAll()


cq.Workplane.bolt_pattern = _bolt_pattern


@dataclass
class HubFlange:
    """
    A flange plate with a hub.

    Attributes
    ----------
    flange_diameter : float
        outer diameter of the plate
    flange_thickness : float
        thickness of the plate
    hub_diameter, hub_height : float
        the hub on top of the plate
    bore_diameter : float
        the central bore through plate and hub (0: none)
    bolt_circle_diameter, num_mount_bolts, mount_bolt_diameter, bolt_phase_deg
        the bolt circle (no holes if num_mount_bolts is 0)
    set_screw_diameter : float
        radial hole into the hub at half its height (0: none)
    """

    flange_diameter: float
    flange_thickness: float
    hub_diameter: float
    hub_height: float
    bore_diameter: float = 0.0
    bolt_circle_diameter: float = 0.0
    num_mount_bolts: int = 0
    mount_bolt_diameter: float = 0.0
    bolt_phase_deg: float = 0.0
    set_screw_diameter: float = 0.0

    def __post_init__(self):
        if self.bolt_circle_diameter + self.mount_bolt_diameter >= self.flange_diameter:
            raise ValueError("the bolt holes do not fit on the flange")
        self._cq_object = self._make_flange()

    @property
    def overall_height(self) -> float:
        """Plate and hub"""
        return self.flange_thickness + self.hub_height

    @property
    def cq_object(self) -> cq.Workplane:
        """The cadquery flange"""
        return self._cq_object

    def _make_flange(self) -> cq.Workplane:
        flange = (
            cq.Workplane("XY")
            .circle(self.flange_diameter / 2)
            .extrude(self.flange_thickness)
            .faces(">Z")
            .workplane()
            .circle(self.hub_diameter / 2)
            .extrude(self.hub_height)
        )
        if self.num_mount_bolts and self.mount_bolt_diameter:
            flange = (
                flange.faces("<Z")
                .workplane(invert=True)
                .bolt_pattern(self.bolt_circle_diameter / 2, self.num_mount_bolts,
                              self.mount_bolt_diameter, self.bolt_phase_deg)
            )
        if self.bore_diameter:
            flange = flange.faces(">Z").workplane().hole(self.bore_diameter)
        if self.set_screw_diameter:
            screw = (
                cq.Workplane("YZ", origin=(0, 0, self.flange_thickness + self.hub_height / 2))
                .circle(self.set_screw_diameter / 2)
                .extrude(self.hub_diameter)
            )
            flange = flange.cut(screw)
        return flange


flange = HubFlange(
    flange_diameter=flange_diameter,
    flange_thickness=flange_thickness,
    hub_diameter=hub_diameter,
    hub_height=hub_height,
    bore_diameter=bore_diameter,
    bolt_circle_diameter=bolt_circle_diameter,
    num_mount_bolts=num_mount_bolts,
    mount_bolt_diameter=mount_bolt_diameter,
    bolt_phase_deg=bolt_phase_deg,
    set_screw_diameter=set_screw_diameter,
)
show_object(flange.cq_object)
