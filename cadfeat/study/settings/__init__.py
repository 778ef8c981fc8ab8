"""Study-file sections declared once, as pydantic v2 models (strict, unknown keys refused, frozen).

The ``Settings`` base, field helpers and ``validate_section`` (a ``ValidationError`` → one ``StudyError`` line:
file, dotted key, what is allowed) are ``cadfeat.settings`` (``_base`` re-exports them); ``scene``: ``[study]``,
``[part_pose]``; ``design``: ``[design]``; ``sections``: ``[constraints]``, ``[shop]``, ``[robustness]``,
``[tracking]``; ``solve``: ``[objective]``, ``[optimizer]``, which ARE the design layer's ``ObjectiveConfig`` and
``OptimizerConfig``. The section models are the configurations the run uses.
"""

from __future__ import annotations

from cadfeat.study.settings._base import Settings, StudyError, range_text, validate_section
from cadfeat.study.settings.sections import (
    SYMMETRIES,
    TRACKING_ESTIMATORS,
    ConstraintSettings,
    RobustnessSettings,
    ShopSettings,
    TrackingSettings,
)
from cadfeat.study.settings.solve import FOV_MEASURES, LIMITS, SCORES, ObjectiveSettings, OptimizerSettings

__all__ = ["FOV_MEASURES", "LIMITS", "SCORES", "SYMMETRIES", "TRACKING_ESTIMATORS", "ConstraintSettings",
           "ObjectiveSettings", "OptimizerSettings", "RobustnessSettings", "Settings", "ShopSettings", "StudyError",
           "TrackingSettings", "range_text", "validate_section"]
