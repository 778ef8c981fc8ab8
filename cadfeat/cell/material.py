"""The part's material and finish, by name, as Mitsuba 3 BSDFs (docs/design.md "The cell is one model").

``Material(name="machined_aluminium", roughness=None)`` is the user-facing setting (``roughness`` None: the
named finish's default GGX α); ``bsdf_dict(material)`` is its Mitsuba 3 BSDF as a ``mi.load_dict`` table.

Where the numbers come from (engineering estimates, not measurements of a given part):

- Metals are ``roughconductor`` with the GGX microfacet distribution. Aluminium uses Mitsuba's tabulated
  complex index ``"Al"`` (Rakić 1995, shipped with Mitsuba); Mitsuba ships no iron table, so steel is given as
  iron's complex index at ≈ 650 / 550 / 450 nm (Johnson & Christy 1974, rounded: n ≈ 2.9, k ≈ 3.0, i.e. a
  normal-incidence reflectance of ≈ 0.52–0.56, the usual figure for polished steel).
- GGX α is roughly the RMS slope of the microfacets. Machined (turned / face-milled, Ra ≈ 0.4–1.6 µm) faces
  show a sharp but not mirror highlight: α ≈ 0.05–0.15, default 0.10. Bead- or sand-blasted (Ra ≈ 2–6 µm)
  faces look matt-metallic: α ≈ 0.3–0.5, default 0.40. These are the ranges used in measured-BRDF fits of
  metals (e.g. the MERL aluminium / steel samples fit with α between ≈ 0.05 and ≈ 0.5).
- Black anodised aluminium: a dark dye under a clear oxide layer (n ≈ 1.6): ``roughplastic`` with diffuse
  reflectance 0.03 and α 0.25 (a soft sheen). Grey plastic (polypropylene / ABS): ``roughplastic`` with
  diffuse reflectance 0.45 (a mid grey) and α 0.15, interior index of polypropylene (1.49).
- ``white_reference``: a Lambertian white of reflectance 0.99 (a Spectralon target), to check a light's strength
  (``cell.light``: it reads 0.99 × intensity where the light's irradiance is its intensity); no roughness.
"""

from __future__ import annotations

from dataclasses import dataclass

from pydantic import JsonValue

from cadfeat.settings import Settings, choice, number

__all__ = ["MATERIALS", "Material", "MaterialSpec", "bores_return_light", "bsdf_dict", "material_spec"]

#: Iron's complex index of refraction (n, k) at ≈ 650 / 550 / 450 nm (Johnson & Christy 1974, rounded).
IRON_ETA_RGB = (2.87, 2.91, 2.58)
IRON_K_RGB = (3.09, 2.93, 2.71)


@dataclass(frozen=True)
class MaterialSpec:
    """A named finish: ``kind`` is the Mitsuba BSDF plugin, ``alpha`` its default GGX roughness (unitless, ≈ RMS
    microfacet slope) and ``params`` the plugin's other parameters (index of refraction, diffuse reflectance)."""

    name: str
    kind: str
    alpha: float
    params: tuple[tuple[str, JsonValue], ...]
    description: str


def _metal(name: str, alpha: float, description: str, **index: JsonValue) -> MaterialSpec:
    return MaterialSpec(name, "roughconductor", alpha, tuple(index.items()), description)


def _plastic(name: str, alpha: float, diffuse: float, ior: float | str, description: str) -> MaterialSpec:
    return MaterialSpec(name, "roughplastic", alpha,
                        (("diffuse_reflectance", {"type": "rgb", "value": [diffuse] * 3}), ("int_ior", ior)),
                        description)


_STEEL = {"eta": {"type": "rgb", "value": list(IRON_ETA_RGB)}, "k": {"type": "rgb", "value": list(IRON_K_RGB)}}

MATERIALS: dict[str, MaterialSpec] = {spec.name: spec for spec in (
    _metal("machined_aluminium", 0.10, "turned or face-milled aluminium: sharp highlight", material="Al"),
    _metal("blasted_aluminium", 0.40, "bead-blasted aluminium: matt metallic", material="Al"),
    _metal("machined_steel", 0.10, "turned or ground steel: sharp highlight", **_STEEL),
    _metal("blasted_steel", 0.40, "sand-blasted steel: matt metallic", **_STEEL),
    _plastic("black_anodised", 0.25, 0.03, 1.6, "black anodised aluminium: dark with a soft sheen"),
    _plastic("grey_plastic", 0.15, 0.45, "polypropylene", "mid-grey moulded or machined plastic"),
    MaterialSpec("white_reference", "diffuse", 0.0, (("reflectance", {"type": "rgb", "value": [0.99] * 3}),),
                 "a Lambertian white reference target (Spectralon-like, reflectance 0.99): for calibration"),
)}


class Material(Settings):
    """The part's material and finish: one of ``MATERIALS`` by name; ``roughness`` overrides its GGX α (None:
    the finish's default, see the module docstring)."""

    section = "material"

    name: str = choice("machined_aluminium", tuple(MATERIALS), description="named material and finish")
    roughness: float | None = number(None, 0.001, 1.0, description="GGX α (≈ RMS microfacet slope); None: the "
                                                                      "named finish's default")


def material_spec(material: Material) -> MaterialSpec:
    """The named finish of ``material``."""
    return MATERIALS[material.name]


def bores_return_light(material: Material) -> bool:
    """Whether a bore in this material clips the sensor under a light at the lens: a conductor's bore walls and
    floor mirror the light back (the flagship's targets under the ring light, docs/results.md "Under physical
    light"); a plastic's or a diffuse finish's bore is darker than its face. g_POSE counts a rim's clipped
    surround as hidden only where the bore clips too (``measures.glare``)."""
    return material_spec(material).kind == "roughconductor"


def bsdf_dict(material: Material) -> dict[str, JsonValue]:
    """The Mitsuba 3 BSDF of ``material`` as a ``mi.load_dict`` table (GGX, α from ``roughness`` or the name)."""
    spec = material_spec(material)
    if spec.kind == "diffuse":
        return {"type": spec.kind, **dict(spec.params)}
    alpha = spec.alpha if material.roughness is None else material.roughness
    return {"type": spec.kind, "distribution": "ggx", "alpha": float(alpha), **dict(spec.params)}
