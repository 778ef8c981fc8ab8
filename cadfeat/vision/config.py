"""``TrackingConfig``: the closed loop's configuration, which IS the study file's ``[tracking]`` section.

One declaration per setting (``cadfeat.settings``: type, default, bounds, the "allowed" text of its error), as
``cadfeat.design.objectives.ObjectiveConfig`` is ``[objective]``: ``cadfeat.study.settings.TrackingSettings`` is
this class, so a key added here is a study key and there is no spec → config copy. The closed loop runs in a cell
(``cell``, the study's ``[cell]``: ``in_cell``), which gives each run's placement σ, the sensor noise, the light's
gain σ, the detector and its gate, and the physically based renderer's light, material and hole ends.

The estimators' and the images' parameter records (``estimate.FilterTuning``, ``images.SensorModel``) are views
of it (``tuning``, ``sensor``): each of their fields is the config's field of the same name (the solver tuning a
study file does not set is declared ``internal``), P₀'s pose σ is the initial error unless given
(``TUNING_DERIVED``) and the noise is the cell's (``SENSOR_DERIVED``); tests/vision/test_vision_config.py checks
that every field arrives.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar, Literal, TypeVar

import numpy as np
from pydantic import Field, ValidationInfo, field_validator, model_validator
from pydantic.json_schema import SkipJsonSchema

from cadfeat.cell import defaults as D
from cadfeat.cell.light import Light
from cadfeat.cell.material import Material
from cadfeat.cell.model import Cell, PerAxis
from cadfeat.settings import Settings, Tuple, boolean, choice, integer, number, seed_from_context
from cadfeat.vision.estimate import FilterTuning
from cadfeat.vision.images import RenderOptions, SensorModel

__all__ = ["CHECK_MODES", "SENSOR_DERIVED", "TRACKING_ESTIMATORS", "TUNING_DERIVED", "RenderOptions",
           "TrackingConfig"]

TRACKING_ESTIMATORS = ("ekf", "iekf", "pnp")
CHECK_MODES = ("fast", "full", "off", "pbr")
"""``[tracking] check``: the closed loop inside ``cadfeat run`` (``cadfeat.study.closed_loop_check``)."""

_FT, _SM = FilterTuning(), SensorModel()  # the estimators' and the images' own defaults are the section's


class TrackingConfig(Settings):
    """``[tracking]``: the closed-loop check of ``cadfeat track`` and the closed loop's configuration
    (``cadfeat.vision.config``; its cell: ``in_cell``).

    Estimators, Monte-Carlo runs and seed (default: the study's); sensor: grey-level noise σ (0..255 scale),
    thin-lens defocus on/off, exposure (s, 0 = no motion blur); initial pose error (mm, deg); filter tuning
    (thesis §6.3.3): R = r I (px²), Q = diag(0, q, …) on the linear (mm²/s²) and angular (rad²/s²) rates, IEKF
    iterations n and threshold τ; every ``frame_step``-th trajectory sample; statistics after ``settle_frames``;
    convergence bounds; association gate (px); rim ellipse-centre model; significance ``alpha`` of the paired
    test, and the smallest change of the median RMS error (percent of the error before) that a verdict counts.
    ``check``: the closed loop inside ``cadfeat run`` — "fast" (PnP and IEKF, few runs and frames), "full" (these
    settings) or "off"; unset: full when the study has a ``[tracking]`` table, else fast
    (``cadfeat.study.closed_loop_check``).
    ``renderer``: "raster" (VTK: holes painted dark, a headlight) or "pbr" (Mitsuba 3: the ``[cell]``'s light,
    material and hole ends; ``spp`` samples per pixel).
    The cell it runs in is the study's ``[cell]`` (``cadfeat.cell.Cell``): each run's part placement (σ = 0.4 t of the
    placement tolerance), the sensor noise σ, the light's gain σ, the detector and its gate; the initial error's
    direction is drawn per run too. Keys that moved to ``[cell]`` are refused with where to (``moved``).
    """

    section: ClassVar[str] = "tracking"
    moved: ClassVar[dict[str, str]] = {
        "placement_mm": "[cell] placement_position_mm = t, the part's placement tolerance ±t per axis (mm); "
                        "the closed loop draws σ = 0.4 t (t = 0.5 gives the former default 0.2)",
        "placement_deg": "[cell] placement_angle_deg = t, the part's placement tolerance ±t per axis (deg); "
                         "the closed loop draws σ = 0.4 t (t = 0.5 gives the former default 0.2)",
        "noise_grey": "[cell] noise_sigma_grey (σ of the sensor's grey-level noise)",
        "gate_px": "[cell] gate_px (the association gate, px)",
        "gain_sigma": "[cell] gain_sigma (relative σ of the light's gain from run to run)",
    }

    estimators: Tuple[Literal["ekf", "iekf", "pnp"]] = choice(
        ("ekf", "iekf", "pnp"), f"a non-empty list of distinct names from {', '.join(TRACKING_ESTIMATORS)}")
    runs: int = integer(20, 1, 10_000)
    seed: int = integer(0, 0, 2**32 - 1)
    defocus: bool = boolean(_SM.defocus)
    exposure_s: float = number(_SM.exposure_s, 0.0, 1.0)
    initial_error_mm: float = number(10.0, 0.0, 10_000.0)
    initial_error_deg: float = number(2.0, 0.0, 180.0)
    r_px2: float = number(_FT.r_px2, 0.0, lo_open=True)
    q_rate_mm2_s2: float = number(_FT.q_rate_mm2_s2, 0.0)
    q_omega_rad2_s2: float = number(_FT.q_omega_rad2_s2, 0.0)
    iterations: int = integer(_FT.iterations, 1, 1000)
    tau: float = number(_FT.tau, 0.0)
    frame_step: int = integer(1, 1)
    settle_frames: int = integer(5, 0)
    converged_mm: float = number(2.0, 0.0, lo_open=True)
    converged_deg: float = number(1.0, 0.0, lo_open=True)
    rim_model: bool = boolean(True)
    alpha: float = number(0.05, 0.0, 0.5, lo_open=True)
    min_change_percent: float = number(5.0, 0.0, 100.0)
    renderer: Literal["raster", "pbr"] = choice("raster", D.RENDERERS, description="raster: VTK, holes painted "
                                                "dark; pbr: Mitsuba 3 path tracer with the [cell] light and material")
    spp: int = integer(16, 1, 4096, description="pbr: samples per pixel")
    check: Literal["fast", "full", "off", "pbr"] | None = choice(
        None, f"one of {', '.join(CHECK_MODES)}", description="the closed loop inside cadfeat run (unset: full "
        "with a [tracking] table, else fast)")
    # the filters' and the images' tuning a study file does not set (``FilterTuning``, ``SensorModel``)
    q_pose_mm2: float = number(_FT.q_pose_mm2, 0.0, internal=True)
    q_pose_rad2: float = number(_FT.q_pose_rad2, 0.0, internal=True)
    sigma0_mm: float | None = number(None, 0.0, lo_open=True, internal=True,
                                     description="P₀'s position σ (unset: the initial error, at least 1 mm)")
    sigma0_rad: float | None = number(None, 0.0, lo_open=True, internal=True,
                                      description="P₀'s rotation σ (unset: the initial error, at least 0.01 rad)")
    sigma0_rate_mm_s: float = number(_FT.sigma0_rate_mm_s, 0.0, lo_open=True, internal=True)
    sigma0_omega_rad_s: float = number(_FT.sigma0_omega_rad_s, 0.0, lo_open=True, internal=True)
    blur_scale: float = number(_SM.blur_scale, 0.0, internal=True)
    cell: SkipJsonSchema[Cell] = Field(default_factory=Cell, json_schema_extra={"x-internal": True})
    """The cell the closed loop runs in (the study's ``[cell]``; ``in_cell``): not a key of ``[tracking]``."""

    @model_validator(mode="before")
    @classmethod
    def _study_seed(cls, data: object, info: ValidationInfo) -> object:
        return seed_from_context(data, info)

    @field_validator("estimators")
    @classmethod
    def _distinct(cls, value: tuple[str, ...]) -> tuple[str, ...]:
        if not value or len(set(value)) != len(value):
            raise ValueError("not a non-empty list of distinct names")
        return value

    def in_cell(self, cell: Cell) -> TrackingConfig:
        """These settings run in ``cell`` (the study's ``[cell]``)."""
        return self.model_copy(update={"cell": cell})

    # the cell's numbers as the closed loop uses them
    @property
    def placement_mm(self) -> PerAxis:
        """σ (mm, one or per axis) of each run's placement error (0: every run at the nominal placement)."""
        return self.cell.placement_sigma()[0]

    @property
    def placement_deg(self) -> PerAxis:
        """σ (deg, one or per axis) of each run's placement rotation."""
        return self.cell.placement_sigma()[1]

    @property
    def noise_grey(self) -> float:
        return self.cell.noise_sigma_grey

    @property
    def gain_sigma(self) -> float:
        return self.cell.gain_sigma

    @property
    def gate_px(self) -> float:
        return self.cell.gate_px

    @property
    def detector(self) -> str:
        return self.cell.detector

    @property
    def light(self) -> Light:
        return self.cell.light

    @property
    def material(self) -> Material:
        return self.cell.material

    @property
    def hole_ends(self) -> str:
        return self.cell.hole_ends

    @property
    def min_change(self) -> float:
        """The smallest relative change of the median RMS error a verdict counts (``metrics.paired_verdict``)."""
        return self.min_change_percent / 100.0

    @property
    def tuning(self) -> FilterTuning:
        """The filters' R, Q, P₀, n, τ: P₀'s pose σ is the initial error (at least 1 mm, 0.01 rad) unless given."""
        return _record(FilterTuning, self,
                       sigma0_mm=max(self.initial_error_mm, 1.0) if self.sigma0_mm is None else self.sigma0_mm,
                       sigma0_rad=max(np.radians(self.initial_error_deg), 0.01) if self.sigma0_rad is None
                       else self.sigma0_rad)

    @property
    def sensor(self) -> SensorModel:
        """The images' sensor: the cell's noise σ, this section's defocus and exposure."""
        return _record(SensorModel, self, noise_grey=self.cell.noise_sigma_grey)

    def render_options(self) -> RenderOptions:
        """The keyword arguments of ``render.camera_renderer`` for this config's renderer: none for the raster
        one; the cell's light, material and hole ends, the samples per pixel and a metered exposure for the
        physically based one (``render.sensor``: the part's median at a fixed fraction of full scale)."""
        if self.renderer != "pbr":
            return {}
        from cadfeat.render.sensor import Sensor  # lazy: pydantic

        return {"light": self.light, "material": self.material, "spp": self.spp, "hole_ends": self.hole_ends,
                "sensor": Sensor(exposure="meter")}


#: The fields of ``FilterTuning`` / ``SensorModel`` a ``TrackingConfig`` derives: P₀'s pose σ (from the initial error
#: when unset), the noise (the cell's); every other field is the config's field of the same name.
TUNING_DERIVED = ("sigma0_mm", "sigma0_rad")
SENSOR_DERIVED = ("noise_grey",)


R = TypeVar("R", FilterTuning, SensorModel)


def _record(kind: type[R], config: TrackingConfig, **derived: float) -> R:
    """A parameter record ``kind`` of ``config``: every field the config has by name, then ``derived``."""
    own = {f.name: getattr(config, f.name) for f in dataclasses.fields(kind)
           if f.name in TrackingConfig.model_fields and f.name not in derived}
    return kind(**own, **derived)
