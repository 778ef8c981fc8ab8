"""Studies: the TOML study file, its set-up, the run and its outputs.

- ``schema``: ``load_study`` validates a study before any work (``StudyConfig``);
- ``setup``: part, camera, trajectory, design space and feature model of a validated study (``StudySetup``);
- ``run``: ``run_study`` (optimise, rebuild, verify, export, report) and ``evaluate_study``;
- ``outputs``: results.json pieces; ``progress``: the progress display.

``run_study``, ``evaluate_study`` and ``StudyResult`` are importable from here, and ``score_design`` /
``track_design`` (``designs``: any design of a study, a parameter dict, scored and tracked) — lazily: the run
imports numpy-heavy modules only when used.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover (the names ``__getattr__`` gives, for the type checker)
    from cadfeat.study.designs import score_design, track_design
    from cadfeat.study.run import StudyResult, evaluate_study, run_study

__all__ = ["StudyResult", "evaluate_study", "run_study", "score_design", "track_design"]
_HOMES = {"score_design": "cadfeat.study.designs", "track_design": "cadfeat.study.designs"}


def __getattr__(name: str) -> object:
    if name in __all__:
        return getattr(importlib.import_module(_HOMES.get(name, "cadfeat.study.run")), name)
    raise AttributeError(f"module 'cadfeat.study' has no attribute {name!r}")
