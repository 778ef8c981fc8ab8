"""What an engineer needs to trust a study's answer, gathered for results.json, the summary and the report.

- ``objective_changes``: each objective before → after in its own units, the limiting objective (the one
  whose normalised value sets the max-min), and the objectives that do not depend on the design;
(The per-hole hidden fractions are in ``outputs.measures_summary``.)
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.design.objectives import ObjectiveConfig
    from cadfeat.design.problem import Problem
    from cadfeat.results import ObjectiveChangeData, ObjectiveChangesData

__all__ = ["OBJECTIVE_UNITS", "objective_changes", "objective_unit"]

#: Unit of each measure per pose (the aggregate over the trajectory adds "summed over L poses" for "sum").
OBJECTIVE_UNITS = {"g_FOV": "cone margin 1 − cos (dimensionless)", "g_FOC": "focus margin (½ depth of field)",
                   "g_RES": "px", "g_DIR": "px/mm"}


def objective_unit(name: str, objective_config: ObjectiveConfig) -> str:
    """The unit of an aggregated objective, e.g. "px, summed over the poses"."""
    if name == "g_POSE":  # minus the predicted pose error, by pose_aggregate (not by aggregate)
        how = getattr(objective_config, "pose_aggregate", "rms")
        return {"rms": "mm (minus the predicted pose error), rms over the poses",
                "worst": "mm (minus the predicted pose error), worst pose"}.get(how, "log det of the pose information")
    unit = OBJECTIVE_UNITS.get(name, "")
    if name == "g_FOV" and getattr(objective_config, "fov_measure", "cone") == "image":
        unit = "px"
    how = getattr(objective_config, "aggregate", "sum")
    return unit + {"sum": ", summed over the poses", "mean": ", mean over the poses", "min": ", worst pose",
                   "smoothmin": ", smooth minimum over the poses"}.get(how, "")


def objective_changes(problem: Problem, before: Mapping[str, float], after: Mapping[str, float] | None
                      ) -> ObjectiveChangesData:
    """{"limiting", "limiting_before", "constant", "changes": [{name, before, after, change, unit,
    normalised_before, normalised_after, in_combination}]}: the limiting objective is the smallest normalised
    one among those combined (max-min); ``constant``: objectives that do not depend on the design variables
    on this trajectory (left out of the combination, with a warning)."""
    names = list(problem.names)
    cfg = problem.objective_config
    used = {names[int(i)] for i in problem.combined_idx}
    g0 = np.array([before[n] for n in names], float)
    g1 = None if after is None else np.array([after[n] for n in names], float)
    n0 = problem.normalised(g0)
    n1 = None if g1 is None else problem.normalised(g1)
    rows: list[ObjectiveChangeData] = []
    for i, name in enumerate(names):
        rows.append({"name": name, "unit": objective_unit(name, cfg), "before": float(g0[i]),
                     "after": None if g1 is None else float(g1[i]),
                     "change": None if g1 is None else float(g1[i] - g0[i]),
                     "normalised_before": float(n0[i]), "normalised_after": None if n1 is None else float(n1[i]),
                     "in_combination": name in used})
    constant: list[str] = list(getattr(problem.normaliser, "constant", ()))
    warnings = [f"{n} does not depend on the design variables on this trajectory (the same value at every "
                "design that meets the kept requirements): it is left out of the combination" for n in constant]
    out: ObjectiveChangesData = {
        "limiting_before": problem.limiting(g0) if cfg.combine in ("maxmin", "pareto") else None,
        "limiting": None, "constant": constant, "changes": rows, "warnings": warnings}
    if g1 is not None and cfg.combine in ("maxmin", "pareto"):
        out["limiting"] = problem.limiting(g1)
    return out
