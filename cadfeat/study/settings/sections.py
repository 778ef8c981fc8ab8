"""The simple sections of a study file, each declared once as a ``Settings`` model that IS the configuration
the run uses: ``[constraints]``, ``[shop]``, ``[robustness]``, ``[tracking]``.

Units are in the key names (mm, percent, deg, s, px², grey levels on the 0..255 scale).
"""

from __future__ import annotations

from typing import ClassVar, Literal

from pydantic import ValidationInfo, field_validator, model_validator

from cadfeat.design.shop import HOLE_SIZE_TABLES, hole_sizes
from cadfeat.study.settings._base import Settings, Tuple, boolean, choice, integer, number, seed_from_context
from cadfeat.vision.closed_loop import TrackingConfig
from cadfeat.vision.estimate import FilterTuning
from cadfeat.vision.images import SensorModel

__all__ = ["SYMMETRIES", "TRACKING_ESTIMATORS", "ConstraintSettings", "RobustnessSettings", "ShopSettings",
           "TrackingSettings"]

SYMMETRIES = ("none", "x", "y", "xy")
TRACKING_ESTIMATORS = ("ekf", "iekf", "pnp")


class ConstraintSettings(Settings):
    """``[constraints]``: the kept mechanical requirements (mm; percent of the original volume)."""

    section: ClassVar[str] = "constraints"

    edge_distance_mm: float = number(1.0, 0.0, description="smallest distance of a hole's rim to its face's edge")
    ligament_mm: float = number(1.0, 0.0, description="smallest wall between two holes")
    volume_change_max_percent: float | None = number(None, 0.0, 100.0, lo_open=True,
                                                     description="largest change of the part's volume")
    symmetry: Literal["none", "x", "y", "xy"] = choice("none", SYMMETRIES, description="mirror symmetry kept")


class ShopSettings(Settings):
    """``[shop]``: shop-ready output (``cadfeat.design.shop``). ``hole_sizes``: a table name of
    ``shop.HOLE_SIZE_TABLES`` or diameters (mm); ``grid_mm``: drawing grid of moved hole positions (0: off);
    ``keep_patterns``: holes forming a pattern in the original move as a pattern (false lets them break)."""

    section: ClassVar[str] = "shop"

    hole_sizes: str | Tuple[float] = choice(
        "iso273-medium", f"one of {', '.join(HOLE_SIZE_TABLES)} or a list of diameters > 0 (mm)")
    grid_mm: float = number(0.1, 0.0, 10.0)
    keep_patterns: bool = boolean(True)

    @field_validator("hole_sizes")
    @classmethod
    def _sizes(cls, value: str | tuple[float, ...]) -> str | tuple[float, ...]:
        if isinstance(value, str):
            if value not in HOLE_SIZE_TABLES:
                raise ValueError("not a table")
            return value
        if not value or not all(v > 0 for v in value):
            raise ValueError("not a list of positive diameters")
        return hole_sizes(value)


class RobustnessSettings(Settings):
    """``[robustness]``: tolerances of the robustness study (``cadfeat.design.robustness``): hole positions
    ±``position_tol_mm``, diameters ±``size_steps`` table steps, camera mount ±``camera_position_mm`` and
    ±``camera_angle_deg``; ``samples`` random draws each (0: off)."""

    section: ClassVar[str] = "robustness"

    position_tol_mm: float = number(0.1, 0.0, 10.0)
    size_steps: int = integer(1, 0, 5)
    camera_position_mm: float = number(2.0, 0.0, 100.0)
    camera_angle_deg: float = number(1.0, 0.0, 30.0)
    samples: int = integer(200, 0, 10000)


_CL, _FT, _SM = TrackingConfig, FilterTuning, SensorModel  # the vision defaults are the section's defaults


class TrackingSettings(Settings):
    """``[tracking]``: the closed-loop check of ``cadfeat track`` (``cadfeat.vision.closed_loop.TrackingConfig``,
    built by ``cadfeat.study.tracking.tracking_config``; the defaults are vision's own).

    Estimators, Monte-Carlo runs and seed (default: the study's); sensor: grey-level noise σ (0..255 scale),
    thin-lens defocus on/off, exposure (s, 0 = no motion blur); initial pose error (mm, deg); filter tuning
    (thesis §6.3.3): R = r I (px²), Q = diag(0, q, …) on the linear (mm²/s²) and angular (rad²/s²) rates, IEKF
    iterations n and threshold τ; every ``frame_step``-th trajectory sample; statistics after ``settle_frames``;
    convergence bounds; association gate (px); rim ellipse-centre model; significance ``alpha`` of the paired
    test, and the smallest change of the median RMS error (percent of the error before) that a verdict counts.
    """

    section: ClassVar[str] = "tracking"

    estimators: Tuple[Literal["ekf", "iekf", "pnp"]] = choice(
        _CL.estimators, f"a non-empty list of distinct names from {', '.join(TRACKING_ESTIMATORS)}")
    runs: int = integer(_CL.runs, 1, 10_000)
    seed: int = integer(_CL.seed, 0, 2**32 - 1)
    noise_grey: float = number(_SM.noise_grey, 0.0, 100.0)
    defocus: bool = boolean(_SM.defocus)
    exposure_s: float = number(_SM.exposure_s, 0.0, 1.0)
    initial_error_mm: float = number(_CL.initial_error_mm, 0.0, 10_000.0)
    initial_error_deg: float = number(_CL.initial_error_deg, 0.0, 180.0)
    r_px2: float = number(_FT.r_px2, 0.0, lo_open=True)
    q_rate_mm2_s2: float = number(_FT.q_rate_mm2_s2, 0.0)
    q_omega_rad2_s2: float = number(_FT.q_omega_rad2_s2, 0.0)
    iterations: int = integer(_FT.iterations, 1, 1000)
    tau: float = number(_FT.tau, 0.0)
    frame_step: int = integer(_CL.frame_step, 1)
    settle_frames: int = integer(_CL.settle_frames, 0)
    converged_mm: float = number(_CL.converged_mm, 0.0, lo_open=True)
    converged_deg: float = number(_CL.converged_deg, 0.0, lo_open=True)
    gate_px: float = number(_CL.gate_px, 0.0, lo_open=True)
    rim_model: bool = boolean(_CL.rim_model)
    alpha: float = number(_CL.alpha, 0.0, 0.5, lo_open=True)
    min_change_percent: float = number(100.0 * _CL.min_change, 0.0, 100.0)

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
