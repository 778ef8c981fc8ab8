"""The cell's material and light settings (``cell.material``, ``cell.light``) and the light's strength law.

Reference for the strength: the on-axis irradiance of a Lambertian disc, E = π L a² / (a² + D²), checked here by
integrating L cos θ cos θ' / d² over the annulus numerically (independent of the closed form).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cadfeat.cell.light import Light, annulus_irradiance, emitter_strength
from cadfeat.cell.material import MATERIALS, Material, bsdf_dict
from cadfeat.errors import CadfeatError


def test_named_materials_and_roughness_override():
    assert {"machined_aluminium", "blasted_aluminium", "machined_steel", "blasted_steel", "black_anodised",
            "grey_plastic", "white_reference"} <= set(MATERIALS)
    al = bsdf_dict(Material(name="machined_aluminium"))
    assert al["type"] == "roughconductor" and al["material"] == "Al" and 0.05 <= al["alpha"] <= 0.15
    assert 0.3 <= bsdf_dict(Material(name="blasted_steel"))["alpha"] <= 0.5
    assert bsdf_dict(Material(name="grey_plastic", roughness=0.3))["alpha"] == 0.3
    with pytest.raises(CadfeatError, match="material.name"):
        Material(name="gold")


def test_annulus_irradiance_by_quadrature():
    inner, outer, D, L = 20.0, 40.0, 150.0, 2.0
    r = np.linspace(inner, outer, 4001)
    integrand = L * D ** 2 / (r ** 2 + D ** 2) ** 2 * 2 * np.pi * r          # cos θ cos θ' / d² over rings
    assert annulus_irradiance(L, inner, outer, D) == pytest.approx(np.trapezoid(integrand, r), rel=1e-6)


def test_emitter_strength_gives_the_intensity():
    ring = Light(kind="ring", intensity=2.0, reference_mm=250.0)
    assert annulus_irradiance(emitter_strength(ring), 20.0, 40.0, 250.0) == pytest.approx(2.0)
    spot = Light(kind="spot", intensity=1.5, position_mm=(0.0, 0.0, 300.0), target_mm=(0.0, 0.0, 0.0))
    assert emitter_strength(spot) / 300.0 ** 2 == pytest.approx(1.5)
    assert math.pi * emitter_strength(Light(kind="dome", intensity=0.7)) == pytest.approx(0.7)
    with pytest.raises(CadfeatError, match="outer_radius_mm"):
        Light(inner_radius_mm=50.0)
