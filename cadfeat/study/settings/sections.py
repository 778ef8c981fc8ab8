"""The simple sections of a study file, each declared once as a ``Settings`` model that IS the configuration
the run uses: ``[constraints]``, ``[shop]``, ``[robustness]``, ``[tracking]``.

Units are in the key names (mm, percent, deg, s, px², grey levels on the 0..255 scale).
"""

from __future__ import annotations

from typing import ClassVar, Literal

from pydantic import field_validator, model_validator

from cadfeat.cell import PER_AXIS, per_axis
from cadfeat.design.shop import HOLE_SIZE_TABLES, hole_sizes
from cadfeat.study.settings._base import (
    Settings,
    Tuple,
    boolean,
    choice,
    integer,
    number,
    reject,
)
from cadfeat.vision.config import CHECK_MODES, TRACKING_ESTIMATORS, TrackingConfig

__all__ = ["CHECK_MODES", "ROBUST_STATISTICS", "SYMMETRIES", "TRACKING_ESTIMATORS", "ConstraintSettings",
           "RobustnessSettings", "ShopSettings", "TrackingSettings"]

SYMMETRIES = ("none", "x", "y", "xy")


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


ROBUST_STATISTICS = ("percentile", "mean", "chance")


class RobustnessSettings(Settings):
    """``[robustness]``: the uncertainty of the cell that will be built and how the design answers to it
    (``cadfeat.design.uncertainty``, ``cadfeat.design.robust``, ``cadfeat.design.robustness``) — one table for
    the tolerances, the robust objective and the analysis.

    Tolerances (each ±t; ``distribution`` uniform in [−t, t] or a normal of σ = t/2 truncated at ±t): the camera mount,
    the part's placement and the sensor noise's spread are the cell's (``[cell]``, ``cadfeat.cell.Cell``: declared
    once, read by the robust draws, g_POSE and the closed loop alike); here the path offset ``path_offset_mm`` (per
    task axis), speed ``time_scale_percent``, the shop's hole position ``position_tol_mm`` (across the axis) and
    diameter ``diameter_tol_mm``; ``size_steps``: the analysis also tries a drill ±that many sizes off the table.
    Robust objective (``robust = true``, the default): maximise the ``percentile`` (default 10th) of the combined
    objective over ``draws`` fixed draws (``sampling``: Sobol or Latin hypercube, seeded by the study), or its
    ``mean``, or (``chance``) the nominal value subject to ``chance_measure`` ≥ ``chance_min`` (raw units; g_POSE
    is minus the error in mm) in ``chance_probability`` of the cells. ``robust = false``: the nominal optimum.
    Analysis: ``samples`` draws per source (0: off), and as many on a held-out seed (out of sample)."""

    robust: bool = boolean(True, description="optimise a statistic over the draws (false: the nominal optimum)")
    statistic: Literal["percentile", "mean", "chance"] = choice("percentile", ROBUST_STATISTICS)
    percentile: float = number(10.0, 0.0, 50.0, lo_open=True, description="the percentile maximised")
    chance_measure: str | None = choice(None, "a measure of objective.measures (with statistic = \"chance\")")
    chance_min: float | None = number(None, description="the chance constraint's bound (raw units)")
    chance_probability: float = number(0.95, 0.5, 1.0, lo_open=True)
    draws: int = integer(64, 2, 4096, description="draws the robust objective is evaluated on")
    sampling: Literal["sobol", "lhs"] = choice("sobol", ("sobol", "lhs"))
    distribution: Literal["uniform", "normal"] = choice("uniform", ("uniform", "normal"))
    path_offset_mm: float | Tuple[float] = choice(0.5, PER_AXIS)
    time_scale_percent: float = number(10.0, 0.0, 90.0)

    section: ClassVar[str] = "robustness"
    moved: ClassVar[dict[str, str]] = {
        "camera_position_mm": "[cell] camera_position_mm (the camera's mount tolerance ±t, mm)",
        "camera_angle_deg": "[cell] camera_angle_deg (the camera's mount tolerance ±t, deg)",
        "placement_position_mm": "[cell] placement_position_mm (the part's placement tolerance ±t, mm)",
        "placement_angle_deg": "[cell] placement_angle_deg (the part's placement tolerance ±t, deg)",
        "pixel_noise_grey": "[cell] noise_spread_grey (± spread of the sensor noise σ from cell to cell)",
    }
    position_tol_mm: float = number(0.1, 0.0, 10.0)
    diameter_tol_mm: float = number(0.1, 0.0, 10.0)
    size_steps: int = integer(1, 0, 5)
    samples: int = integer(200, 0, 10000)

    @field_validator("path_offset_mm")
    @classmethod
    def _mm(cls, value: object) -> float | tuple[float, ...]:
        return per_axis(value, 100.0)

    @model_validator(mode="after")
    def _chance(self) -> RobustnessSettings:
        if self.statistic == "chance" and (self.chance_measure is None or self.chance_min is None):
            raise reject("chance_measure", "statistic = \"chance\" needs chance_measure and chance_min",
                         "a measure of objective.measures and its bound chance_min (raw units)")
        return self


TrackingSettings = TrackingConfig
"""``[tracking]``: ``cadfeat.vision.config.TrackingConfig`` (the closed loop's configuration; one declaration)."""
