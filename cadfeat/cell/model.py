"""``Cell``: the robot cell that will be built, declared once (the study's ``[cell]`` table).

Every physical number of the cell lives here, and says what it is:

- a **± bound** (a tolerance t: the error lies in [−t, t]): the camera's mount ``camera_position_mm`` /
  ``camera_angle_deg`` (camera frame, the same at every pose) and the part's placement ``placement_position_mm`` /
  ``placement_angle_deg`` (part frame), one number for every axis or three (x, y, z); the spread of the sensor's
  noise from cell to cell ``noise_spread_grey``;
- a **standard deviation** σ: the sensor's grey-level noise ``noise_sigma_grey`` (0..255 scale, per pixel and
  frame) and the light's gain from run to run ``gain_sigma`` (relative);
- a **setting**: the detector (``detector``) and its association gate ``gate_px``, how the holes are made
  (``hole_ends``), the light (``[cell.light]``, ``cell.light.Light``: ring, coaxial, dome or spot) and the part's
  material and finish (``[cell.material]``, ``cell.material.Material``) — what the physically based closed loop
  renders (``[tracking] renderer = "pbr"``).

``BOUND_KEYS`` and ``SIGMA_KEYS`` list which is which (the JSON Schema carries it too: ``x-statistic``).

Where each reaches (the same object, so a prediction and the check that confirms it assume one cell):

- g_POSE's models (``measures.pose_models.PoseModels.for_cell``): the gate and the placement error of the
  association term, the noise of the centre's σ model;
- the robust draws (``design.uncertainty.Uncertainty.from_cell``): the mount and placement tolerances ±t, the
  noise σ ± its spread;
- the closed loop (``vision.config.TrackingConfig.in_cell``, the study's ``[tracking]`` in its cell): each run's
  placement drawn from a normal of σ = ``PLACEMENT_SIGMA_PER_TOLERANCE`` · t per axis (``placement_sigma``), the
  noise σ, the gain σ, the gate and the detector.

Units are in the names: mm, degrees, grey levels, px.
"""

from __future__ import annotations

from typing import ClassVar, Literal, TypeVar, cast

from pydantic import JsonValue, ValidationInfo, field_validator
from pydantic.fields import FieldInfo

from cadfeat.cell import defaults as D
from cadfeat.cell.light import Light
from cadfeat.cell.material import Material
from cadfeat.settings import Settings, Tuple, boolean, choice, context_of, number, validate_nested

__all__ = ["BOUND_KEYS", "DETECTORS", "HOLE_ENDS", "PER_AXIS", "PLACEMENT_SIGMA_PER_TOLERANCE", "SIGMA_KEYS", "Cell",
           "per_axis", "triple"]

PER_AXIS = "a number ≥ 0 or a list of three numbers ≥ 0 (per axis x, y, z)"
DETECTORS = D.DETECTORS
HOLE_ENDS = D.HOLE_ENDS

PLACEMENT_SIGMA_PER_TOLERANCE = D.PLACEMENT_SIGMA_PER_TOLERANCE
"""The closed loop draws the part's placement per run from a normal of σ = 0.4 t per axis (t the placement
tolerance), so ±t is 2.5 σ (98.8 % of the runs inside it); g_POSE's association term assumes the same σ. The
robust draws use ±t itself (``[robustness] distribution``)."""

PerAxis = float | tuple[float, ...]


def per_axis(value: object, hi: float) -> PerAxis:
    """A tolerance per axis: one number in [0, hi] for every axis, or three (x, y, z)."""
    items: tuple[object, ...] = cast("tuple[object, ...]", value) if isinstance(value, tuple) else (value,)
    nums = [float(v) for v in items if isinstance(v, int | float) and not isinstance(v, bool)]
    if len(items) not in (1, 3) or len(nums) != len(items) or not all(0.0 <= v <= hi for v in nums):
        raise ValueError("not a tolerance per axis")
    return nums[0] if not isinstance(value, tuple) else tuple(nums)


def triple(value: PerAxis) -> tuple[float, float, float]:
    """A per-axis value as (x, y, z)."""
    t = tuple(float(x) for x in (value if isinstance(value, tuple) else (value, value, value)))
    return (t[0], t[1], t[2])


F = TypeVar("F")


def _stat(field: F, statistic: Literal["bound", "sigma"]) -> F:
    """A field whose JSON Schema says whether its number is a ± bound or a standard deviation: ``field`` with
    its constraints (``number``'s range and finiteness) and ``x-statistic`` added to its JSON Schema extra."""
    info = cast(FieldInfo, field)  # (a settings helper's field definition, typed as its value: settings.F)
    extra = dict(cast("dict[str, JsonValue]", info.json_schema_extra))
    extra["x-statistic"] = statistic
    return cast(F, FieldInfo.merge_field_infos(info, json_schema_extra=extra))


def _bound(default: PerAxis, what: str) -> PerAxis:
    return _stat(choice(default, PER_AXIS, description=f"± tolerance of the {what}, per axis"), "bound")


_NOISE = "σ of the sensor's grey-level noise (0..255 scale, per pixel and frame)"
_SPREAD = "± spread of that σ from cell to cell (the robust draws)"
_GAIN = "relative σ of the light's gain from run to run"
_GATE = "association gate of a detection to its hole (px)"


class Cell(Settings):
    """``[cell]``: the robot cell (module docstring). Defaults: a camera mounted to ±2 mm / ±1°, the part placed to
    ±0.5 mm / ±0.5°, 2 grey levels of sensor noise (±1 from cell to cell), a 5 % light gain spread, cadfeat's
    detector with a 10 px gate, holes as modelled."""

    section: ClassVar[str] = "cell"

    camera_position_mm: float | Tuple[float] = _bound(D.CAMERA_POSITION_MM, "camera's mount (mm, camera frame)")
    camera_angle_deg: float | Tuple[float] = _bound(D.CAMERA_ANGLE_DEG, "camera's mount (deg, camera frame)")
    placement_position_mm: float | Tuple[float] = _bound(D.PLACEMENT_POSITION_MM, "part's placement (mm, part frame)")
    placement_angle_deg: float | Tuple[float] = _bound(D.PLACEMENT_ANGLE_DEG, "part's placement (deg, part frame)")
    noise_sigma_grey: float = _stat(number(D.NOISE_SIGMA_GREY, 0.0, 100.0, description=_NOISE), "sigma")
    noise_spread_grey: float = _stat(number(D.NOISE_SPREAD_GREY, 0.0, 100.0, description=_SPREAD), "bound")
    gain_sigma: float = _stat(number(D.GAIN_SIGMA, 0.0, 1.0, description=_GAIN), "sigma")
    gate_px: float = number(D.GATE_PX, 0.0, lo_open=True, description=_GATE)
    detector: Literal["cadfeat", "edcircles", "blob"] = choice("cadfeat", DETECTORS,
                                                                description="the closed loop's hole detector")
    hole_ends: Literal["as_modelled", "drilled", "milled"] = choice(
        "as_modelled", HOLE_ENDS, description="how a blind hole ends as the shop makes it")
    glare: bool = boolean(True, description="g_POSE reads where the part's own light leaves a blind rim in a metal "
                                            "part little contrast, from physically based renders of the part at "
                                            "the study's poses made at set-up (cadfeat.measures.glare); false: the "
                                            "detection model alone")
    light: Light = choice(Light, "a table [cell.light] (kind = ring | coaxial | dome | spot, …)", factory=True,
                          description="the cell's light (cadfeat.cell.light)")
    material: Material = choice(Material, "a table [cell.material] (name, roughness)", factory=True,
                                description="the part's material and finish (cadfeat.cell.material)")

    @field_validator("light", "material", mode="before")
    @classmethod
    def _table(cls, value: object, info: ValidationInfo) -> object:
        """A sub-table validated as its model, its errors keyed ``cell.light.kind``."""
        model = Light if info.field_name == "light" else Material
        if isinstance(value, model):
            return value
        return validate_nested(model, value, str(info.field_name), "cell", context_of(info))

    @field_validator("camera_position_mm", "placement_position_mm")
    @classmethod
    def _mm(cls, value: object) -> PerAxis:
        return per_axis(value, 100.0)

    @field_validator("camera_angle_deg", "placement_angle_deg")
    @classmethod
    def _deg(cls, value: object) -> PerAxis:
        return per_axis(value, 30.0)

    def placement_sigma(self) -> tuple[PerAxis, PerAxis]:
        """(mm, deg) σ per axis of the part's placement error as the closed loop draws it and g_POSE's association
        term assumes it: ``PLACEMENT_SIGMA_PER_TOLERANCE`` · t (one number, or three)."""
        def sigma(t: PerAxis) -> PerAxis:
            k = PLACEMENT_SIGMA_PER_TOLERANCE
            return tuple(k * v for v in t) if isinstance(t, tuple) else k * t
        return sigma(self.placement_position_mm), sigma(self.placement_angle_deg)


def _keys(statistic: str) -> tuple[str, ...]:
    return tuple(n for n, f in Cell.model_fields.items()
                 if dict(cast("dict[str, JsonValue]", f.json_schema_extra or {})).get("x-statistic") == statistic)


BOUND_KEYS = _keys("bound")
"""The ``[cell]`` keys that are ± bounds."""
SIGMA_KEYS = _keys("sigma")
"""The ``[cell]`` keys that are standard deviations."""
