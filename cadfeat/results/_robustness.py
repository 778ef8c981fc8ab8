"""results.json ``robustness``: the tolerance study and the robust redesign's designs side by side (issue 18)."""

from __future__ import annotations

from cadfeat.results._record import Json, Number, Record

__all__ = ["DesignDraws", "OutOfSample", "RobustObjective", "Robustness", "SampleShift", "Sensitivity", "Spread"]


class Spread(Record):
    """One value's nominal and its spread over random draws (``robustness``): mean, 5th/10th percentile, minimum."""

    nominal: Number | None = None
    mean: Number | None = None
    p05: Number | None = None
    p10: Number | None = None
    min: Number | None = None


class RobustObjective(Record):
    """``robustness.objective``: the robust statistic the optimiser maximised and its draws (issue 18)."""

    robust: bool | None = None
    statistic: str | None = None
    label: str | None = None
    draws: int | None = None
    sampling: str | None = None
    seed: int | None = None


class DesignDraws(Record):
    """``robustness.distributions.<design>``: the held-out draws of the combined value per source of uncertainty,
    and of each objective under the whole cell."""

    combined: dict[str, list[Number | None]] = {}
    objectives_cell: dict[str, list[Number | None]] = {}


class SampleShift(Record):
    """One design's robust statistic in sample (the optimiser's draws) and out of sample (fresh draws)."""

    in_sample: Number | None = None
    out_of_sample: Number | None = None


class OutOfSample(Record):
    """``robustness.out_of_sample``: the robust statistic of each design on the optimiser's and on fresh draws."""

    statistic: str | None = None
    draws_in_sample: int | None = None
    seed_in_sample: int | None = None
    draws_out_of_sample: int | None = None
    seed_out_of_sample: int | None = None
    designs: dict[str, SampleShift] = {}


class Sensitivity(Record):
    """``robustness.sensitivity``: where the robustness comes from, in words."""

    words: str | None = None


class Robustness(Record):
    """``robustness``: the tolerance study (``design.robustness``: per objective its spread under the shop
    tolerance and the camera mount) and, for a robust redesign (issue 18), the designs side by side: per design
    (original, recommended, nominal, robust) and source of uncertainty, per objective and "combined", a
    ``Spread``."""

    names: list[str] = []
    samples: int = 0
    position_tol_mm: Number | None = None
    size_steps: int | None = None
    camera_position_mm: Number | None = None
    camera_angle_deg: Number | None = None
    razor_edge: list[str] = []
    manufacturing: dict[str, Spread] | None = None
    camera: dict[str, Spread] | None = None
    objective: RobustObjective | None = None
    uncertainty: dict[str, Json] | None = None
    designs: dict[str, dict[str, dict[str, Spread]]] | None = None
    recommended: str | None = None
    delivered: str | None = None
    reason: str = ""
    flagged: list[str] = []
    out_of_sample: OutOfSample | None = None
    sensitivity: Sensitivity | None = None
    distributions: dict[str, DesignDraws] | None = None
