"""``[objective]`` and ``[optimizer]`` of a study file: the design layer's own configurations.

``ObjectiveSettings`` IS ``cadfeat.design.objectives.ObjectiveConfig`` and ``OptimizerSettings`` IS
``cadfeat.design.optimize.OptimizerConfig`` (one declaration per setting, no spec → config copy): a measure,
aggregate or method added there is a study key here. ``LIMITS`` are the study's size limits, given to the
models as validation context (``load_study``).
"""

from __future__ import annotations

from cadfeat.design.objectives import FOV_MEASURES, SCORES, STUDY_MEASURES, ObjectiveConfig
from cadfeat.design.optimize import OptimizerConfig

__all__ = ["FOV_MEASURES", "LIMITS", "SCORES", "STUDY_MEASURES", "ObjectiveSettings", "OptimizerSettings"]

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

ObjectiveSettings = ObjectiveConfig
"""``[objective]``: ``cadfeat.design.objectives.ObjectiveConfig``."""
OptimizerSettings = OptimizerConfig
"""``[optimizer]``: ``cadfeat.design.optimize.OptimizerConfig``."""
