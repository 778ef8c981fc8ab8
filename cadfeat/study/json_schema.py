"""The JSON Schema of a study file (``cadfeat schema``), for completion and checking in an editor.

The sections declared as pydantic models (``cadfeat.study.settings``) give their own schema (types, bounds,
enumerations, defaults, descriptions); the others (``[study]``, ``[camera]``, ``[part_pose]``,
``[trajectory]``, ``[design]``) are listed with their keys (the key tuples ``load_study`` checks), and
``load_study`` remains the full check (files, part parameters and their bounds). Use it with taplo / Even
Better TOML by a first line ``#:schema ./study.schema.json`` in the study file (README, "Study files").
"""

from __future__ import annotations

from typing import Any

from cadfeat.study import schema as study_schema
from cadfeat.study.settings import (
    ConstraintSettings,
    ObjectiveSettings,
    OptimizerSettings,
    RobustnessSettings,
    Settings,
    ShopSettings,
    TrackingSettings,
)

__all__ = ["SCHEMA_ID", "study_json_schema"]

SCHEMA_ID = "https://cadfeat.invalid/schema/study.json"
"""The schema's ``$id`` (a name, not a place to fetch it from)."""

_MODELS: dict[str, type[Settings]] = {
    "constraints": ConstraintSettings, "objective": ObjectiveSettings, "optimizer": OptimizerSettings,
    "shop": ShopSettings, "robustness": RobustnessSettings, "tracking": TrackingSettings,
}
_OPEN = {
    "study": ("which part is redesigned", study_schema.STUDY_KEYS),
    "part_pose": ("the part frame in the task frame (mm, deg)", study_schema.PART_POSE_KEYS),
    "design": ("what may change: parameters (script parts) or holes (STEP parts)", study_schema.DESIGN_KEYS),
}
_DESCRIPTION = {
    "camera": "preset = name (cadfeat cameras), explicit fx fy cx cy width height dist + optics, or "
              "calibration = OpenCV file",
    "trajectory": "kind = library kind + its arguments (cadfeat trajectories), or csv = file of poses",
}


def _model_schema(model: type[Settings]) -> dict[str, Any]:
    out = model.model_json_schema()
    keys = set(model.study_keys())
    out["properties"] = {k: v for k, v in out.get("properties", {}).items() if k in keys}
    for prop in out["properties"].values():
        prop.pop("x-allowed", None)
    return out


def study_json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a study file's tables."""
    props: dict[str, Any] = {}
    defs: dict[str, Any] = {}
    for name in study_schema.SECTIONS:
        if name in _MODELS:
            sub = _model_schema(_MODELS[name])
            defs.update(sub.pop("$defs", {}))
            props[name] = sub
        elif name in _OPEN:
            text, keys = _OPEN[name]
            props[name] = {"type": "object", "description": text, "additionalProperties": False,
                           "properties": {k: {} for k in keys}}
        else:
            props[name] = {"type": "object", "description": _DESCRIPTION[name]}
    out: dict[str, Any] = {
        "$schema": "https://json-schema.org/draft/2020-12/schema", "$id": SCHEMA_ID, "title": "cadfeat study file",
        "type": "object", "additionalProperties": False, "required": list(study_schema.REQUIRED_SECTIONS),
        "properties": props,
    }
    if defs:
        out["$defs"] = defs
    return out
