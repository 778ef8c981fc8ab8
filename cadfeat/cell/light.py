"""The cell's light (docs/design.md "The cell is one model"): its kind, placement and strength.

``Light(kind=...)``:

- ``"ring"``: an annulus of diffuse emitters around the lens, ``inner_radius_mm`` … ``outer_radius_mm`` in the
  camera's z = 0 plane, emitting forward (+z); it moves with the camera.
- ``"coaxial"``: light from the camera's centre along the optical axis (a beam-splitter illuminator): a
  diffuse disc of ``radius_mm`` at the camera centre, in its z = 0 plane, emitting forward.
- ``"dome"``: uniform radiance from every direction (a large diffuse dome / cloudy-day light).
- ``"spot"``: a spot light at ``position_mm`` aimed at ``target_mm`` (part frame, fixed in the cell), full
  strength within ``beam_deg`` of its axis, falling to 0 at ``cutoff_deg``.

Strength. ``intensity`` is the irradiance on a surface facing the light on its axis at ``reference_mm`` (ring,
coaxial; the spot: at its target; the dome: anywhere), in units where a white Lambertian face so lit has the
radiance 1/π — the renderer multiplies radiance by π, so that face reads 1.0 and a mid-grey face ≈ 0.5.
``ambient`` adds a uniform (dome-like) irradiance in the same units. The emitters' own radiance / radiant
intensity follow from the on-axis irradiance of a Lambertian disc of radius a and radiance L at distance D,
E = π L a² / (a² + D²) (an annulus: the difference of two discs), and of a point of intensity I, E = I / D².
"""

from __future__ import annotations

import math
from typing import Self

from pydantic import model_validator

from cadfeat.settings import Finite, Settings, Tuple, choice, number, reject

__all__ = ["LIGHT_KINDS", "Light", "annulus_irradiance", "emitter_strength"]

LIGHT_KINDS = ("ring", "coaxial", "dome", "spot")


class Light(Settings):
    """The cell's light (module docstring): kind, geometry (mm, degrees) and strength (relative irradiance)."""

    section = "light"

    kind: str = choice("ring", LIGHT_KINDS, description="ring, coaxial, dome or spot")
    intensity: float = number(1.0, 0.0, description="on-axis irradiance at reference_mm (1: a white face reads 1)")
    ambient: float = number(0.0, 0.0, description="uniform extra irradiance, same units as intensity")
    reference_mm: float = number(300.0, 0.0, lo_open=True, description="distance at which intensity is the "
                                                                        "irradiance (ring, coaxial), mm")
    inner_radius_mm: float = number(20.0, 0.0, description="ring: inner radius, mm")
    outer_radius_mm: float = number(40.0, 0.0, lo_open=True, description="ring: outer radius, mm")
    radius_mm: float = number(5.0, 0.0, lo_open=True, description="coaxial: radius of the emitting disc, mm")
    position_mm: Tuple[Finite] = choice((0.0, -300.0, 300.0), "three numbers (x, y, z), mm",
                                        description="spot: position in the part frame, mm")
    target_mm: Tuple[Finite] = choice((0.0, 0.0, 0.0), "three numbers (x, y, z), mm",
                                      description="spot: the point it aims at, part frame, mm")
    cutoff_deg: float = number(30.0, 0.0, 90.0, lo_open=True, description="spot: half-angle of the cone, deg")
    beam_deg: float = number(20.0, 0.0, 90.0, lo_open=True, description="spot: half-angle of full strength, deg")

    @model_validator(mode="after")
    def _geometry(self) -> Self:
        """The ring's outer radius past its inner one; the spot's three-number points apart."""
        if self.outer_radius_mm <= self.inner_radius_mm:
            raise reject("outer_radius_mm", f"{self.outer_radius_mm:g} is not allowed",
                         f"a number > inner_radius_mm ({self.inner_radius_mm:g})")
        for key in ("position_mm", "target_mm"):
            if len(getattr(self, key)) != 3:
                raise reject(key, f"{list(getattr(self, key))} is not allowed", "three numbers (x, y, z), mm")
        if math.dist(self.position_mm, self.target_mm) == 0.0:
            raise reject("target_mm", "equal to position_mm", "a point apart from the spot's position")
        return self

def annulus_irradiance(radiance: float, inner_mm: float, outer_mm: float, distance_mm: float) -> float:
    """On-axis irradiance at ``distance_mm`` of a Lambertian annulus of ``radiance`` between the radii (mm):
    π L (b²/(b² + D²) − a²/(a² + D²)); a = 0 is a disc."""
    d2 = distance_mm ** 2
    return math.pi * radiance * (outer_mm ** 2 / (outer_mm ** 2 + d2) - inner_mm ** 2 / (inner_mm ** 2 + d2))


def emitter_strength(light: Light) -> float:
    """The emitter's own strength that gives ``light.intensity`` (module docstring): the radiance of the ring's
    annulus, the coaxial disc or the dome, or the spot's radiant intensity (per steradian, mm² units)."""
    e = light.intensity
    if light.kind == "ring":
        return e / annulus_irradiance(1.0, light.inner_radius_mm, light.outer_radius_mm, light.reference_mm)
    if light.kind == "coaxial":
        return e / annulus_irradiance(1.0, 0.0, light.radius_mm, light.reference_mm)
    if light.kind == "spot":
        return e * math.dist(light.position_mm, light.target_mm) ** 2
    return e / math.pi  # dome: E = π L over the hemisphere
