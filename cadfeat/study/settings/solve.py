"""``[objective]`` and ``[optimizer]`` of a study file, declared once as ``Settings`` models.

The enumerations are the design layer's own (``cadfeat.design.objectives``, ``cadfeat.design.optimize``): a
measure, aggregate or method added there is accepted here. ``ObjectiveSettings.config()`` /
``OptimizerSettings.config()`` give the solver's configuration objects.
"""

from __future__ import annotations

import math
from typing import cast

from pydantic import Field, ValidationInfo, field_validator, model_validator

from cadfeat.design.objectives import (
    AGGREGATES,
    COMBINES,
    MEASURES,
    NORMALISATIONS,
    POSE_AGGREGATES,
    ObjectiveConfig,
)
from cadfeat.design.optimize import LOCAL_SOLVERS, METHODS, OptimizerConfig
from cadfeat.study.settings._base import Settings, Tuple, boolean, choice, integer, number, reject, seed_from_context

__all__ = ["FOV_MEASURES", "LIMITS", "SCORES", "STUDY_MEASURES", "ObjectiveSettings", "OptimizerSettings"]

STUDY_MEASURES = ("pose",)
"""``[objective] measures`` of a study that lists none (issue 17): g_POSE, the predicted pose error. The design
layer's ``ObjectiveConfig.measures`` keeps the four thesis measures; the thesis studies list theirs."""

FOV_MEASURES = ("cone", "image")
SCORES = ("movable", "all")
LIMITS = {
    "trajectory_samples": 100_000,   # [trajectory] n (and the rows of a trajectory CSV)
    "trajectory_lines": 10_000,      # [trajectory] lines (raster_scan)
    "trajectory_csv_bytes": 64 * 2**20,
    "design_variables": 64,          # [design] parameters / movable holes
    "optimizer_starts": 10_000,      # [optimizer] starts
    "optimizer_maxiter": 1_000_000,  # [optimizer] maxiter
    "image_pixels": 50_000_000,      # [camera] width * height
    "image_side_px": 20_000,         # [camera] width, height
}
"""Size limits checked when a study is validated, before anything is allocated (each error names its limit).
They bound memory and time on an ordinary machine; for a bigger study, raise them here
(``cadfeat.study.schema.LIMITS[key] = value`` before ``load_study``)."""


def _one_of(value: str, names: tuple[str, ...] | list[str]) -> str:
    if value not in names:
        raise ValueError("not one of the names")
    return value


_OC, _OPT = ObjectiveConfig, OptimizerConfig  # their defaults are the sections' defaults (one declaration)


class ObjectiveSettings(Settings):
    """``[objective]``: how the measures become objectives (``cadfeat.design.objectives.ObjectiveConfig``)."""

    measures: Tuple[str] = choice(STUDY_MEASURES, f"a non-empty list of distinct names from {', '.join(MEASURES)}",
                                  description='default ["pose"] (g_POSE); the thesis studies list the thesis measures')
    aggregate: str = choice(_OC.aggregate, AGGREGATES)
    combine: str = choice(_OC.combine, COMBINES)
    weights: dict[str, float] = choice({}, "a table measure = number ≥ 0, measures from objective.measures")
    thresholds: dict[str, float] = choice({}, "a table measure = minimum value, measures from objective.measures")
    min_axis_px: float = number(_OC.min_axis_px, 0.0, lo_open=True)
    rotation_length_mm: float = number(_OC.rotation_length_mm, 0.0, lo_open=True)
    smoothmin_beta: float = number(_OC.smoothmin_beta, 0.0, lo_open=True)
    normalisation: str = choice(_OC.normalisation, NORMALISATIONS)
    fov_measure: str = choice(_OC.fov_measure, FOV_MEASURES)
    occlusion: bool = boolean(_OC.occlusion)
    score: str | Tuple[str] = choice(
        _OC.score, '"movable", "all" or a non-empty list of distinct hole names (e.g. ["H1", "H3"])')
    pose_aggregate: str = choice(_OC.pose_aggregate, POSE_AGGREGATES,
                                 description='g_POSE over the trajectory ("pose" in measures): rms, worst or logdet')
    pose_rotation_length_mm: float = number(_OC.pose_rotation_length_mm, 0.0, lo_open=True)

    @field_validator("measures")
    @classmethod
    def _measures(cls, value: tuple[str, ...]) -> tuple[str, ...]:
        if not value or len(set(value)) != len(value):
            raise ValueError("not a non-empty list of distinct names")
        return tuple(_one_of(v, list(MEASURES)) for v in value)

    @field_validator("weights", "thresholds")
    @classmethod
    def _finite(cls, value: dict[str, float]) -> dict[str, float]:
        if not all(math.isfinite(v) for v in value.values()):
            raise ValueError("not finite")
        return dict(sorted(value.items()))

    @field_validator("score")
    @classmethod
    def _score(cls, value: str | tuple[str, ...]) -> str | tuple[str, ...]:
        if isinstance(value, str):
            return _one_of(value, SCORES)
        if not value or not all(value) or len(set(value)) != len(value):
            raise ValueError("not a non-empty list of distinct names")
        return value

    @model_validator(mode="after")
    def _rules(self) -> ObjectiveSettings:
        """Weights and thresholds name chosen measures; thresholds exactly with combine = "constraint"."""
        allowed = ", ".join(self.measures)
        for name in ("weights", "thresholds"):
            table = cast("dict[str, float]", getattr(self, name))
            for m, v in table.items():
                if m not in self.measures:
                    raise reject(f"{name}.{m}", "not one of objective.measures", allowed)
                if name == "weights" and v < 0:
                    raise reject(f"weights.{m}", f"{v} is not allowed", "a number ≥ 0")
        if self.combine == "weighted" and self.weights and not any(w > 0 for w in self.weights.values()):
            raise reject("weights", "all weights are zero", "non-negative weights, at least one positive")
        if self.combine == "constraint":
            if not self.thresholds:
                raise reject("thresholds", "missing (combine = \"constraint\" makes these measures hard constraints)",
                             f"a table measure = minimum value, measures from {allowed}")
            if set(self.thresholds) == set(self.measures):
                raise reject("thresholds", "every measure is a constraint, none is left to optimise",
                             "thresholds for some of the measures, not all")
        elif self.thresholds:
            raise reject("thresholds", f"only used with combine = \"constraint\" (combine is {self.combine!r})",
                         "remove it, or combine = \"constraint\"")
        return self

    def config(self) -> ObjectiveConfig:
        """The design layer's objective configuration of these settings."""
        return ObjectiveConfig(**self.model_dump())


class OptimizerSettings(Settings):
    """``[optimizer]``: the solver (``cadfeat.design.optimize.OptimizerConfig``); ``seed`` defaults to the
    study's (validation context ``seed``); ``starts``/``maxiter`` are bounded by ``LIMITS``."""

    method: str = choice(_OPT.method, METHODS)
    starts: int = Field(_OPT.starts, description="multistart: number of local starts", json_schema_extra={
        "minimum": 1, "x-allowed": "an integer in [1, LIMITS['optimizer_starts']]"})
    maxiter: int = Field(_OPT.maxiter, description="iterations of each local solve", json_schema_extra={
        "minimum": 1, "x-allowed": "an integer in [1, LIMITS['optimizer_maxiter']]"})
    seed: int = integer(_OPT.seed, 0, 2**32 - 1)
    local_solver: str = choice(_OPT.local_solver, LOCAL_SOLVERS)
    snap_standard_sizes: bool = boolean(_OPT.snap_standard_sizes)

    @model_validator(mode="before")
    @classmethod
    def _study_seed(cls, data: object, info: ValidationInfo) -> object:
        return seed_from_context(data, info)

    @model_validator(mode="after")
    def _limits(self) -> OptimizerSettings:
        for key, limit in (("starts", "optimizer_starts"), ("maxiter", "optimizer_maxiter")):
            value = cast(int, getattr(self, key))
            if not 1 <= value <= LIMITS[limit]:
                raise reject(key, f"{value} is not allowed", f"an integer in [1, {LIMITS[limit]}]")
        return self

    def config(self) -> OptimizerConfig:
        """The solver configuration of these settings."""
        return OptimizerConfig(**self.model_dump())
