"""The JSON Schema of a study file (``cadfeat schema``), for completion and checking in an editor.

Every section comes from its one declaration: the ``Settings`` models (``cadfeat.study.settings``: ``[study]``,
``[part_pose]``, ``[design]``, ``[constraints]``, ``[objective]``, ``[optimizer]``, ``[shop]``,
``[robustness]``, ``[tracking]``) give their own schema (types, bounds, enumerations, defaults, descriptions);
``[camera]`` (``CameraSettings``) is the ``Camera`` dataclass's fields (all optional, over a ``preset`` or a
``calibration`` file) and ``[trajectory]`` one form per library kind (its arguments, ``kind_arguments``) or a
``csv`` file. ``load_study``
remains the full check (files, the part's parameters and their bounds, what depends on the part's kind). Use it
with taplo / Even Better TOML by a first line ``#:schema ./study.schema.json`` in the study file
(docs/guide/study-files.md).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, cast

from cadfeat.cell import Cell
from cadfeat.settings import Settings
from cadfeat.study import schema as study_schema
from cadfeat.study.settings import (
    ConstraintSettings,
    ObjectiveSettings,
    OptimizerSettings,
    RobustnessSettings,
    ShopSettings,
    TrackingSettings,
)
from cadfeat.study.settings.add_targets import AddTargetsSettings
from cadfeat.study.settings.camera import CameraSettings
from cadfeat.study.settings.design import DesignSpec
from cadfeat.study.settings.scene import PartPose, StudyInfo
from cadfeat.trajectory import TRAJECTORY_KINDS, trajectory_model

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import JsonDict

__all__ = ["SCHEMA_ID", "study_json_schema"]

SCHEMA_ID = "https://cadfeat.invalid/schema/study.json"
"""The schema's ``$id`` (a name, not a place to fetch it from)."""

_MODELS: dict[str, type[Settings]] = {
    "study": StudyInfo, "camera": CameraSettings, "part_pose": PartPose, "design": DesignSpec,
    "constraints": ConstraintSettings, "objective": ObjectiveSettings, "optimizer": OptimizerSettings,
    "shop": ShopSettings, "robustness": RobustnessSettings, "tracking": TrackingSettings, "cell": Cell,
    "add_targets": AddTargetsSettings,
}


def _model_schema(model: type[Settings]) -> JsonDict:
    out = model.model_json_schema()
    keys = set(model.study_keys())
    out["properties"] = {k: v for k, v in out.get("properties", {}).items() if k in keys}
    out["required"] = [k for k in out.get("required", []) if k in keys]
    if not out["required"]:
        del out["required"]
    for prop in out["properties"].values():
        prop.pop("x-allowed", None)
    return out


def _trajectory_schema() -> JsonDict:
    """``[trajectory]``: one form per library kind (its generated model) or a CSV file (``CsvTrajectory``)."""
    forms = [_model_schema(trajectory_model(kind)) for kind in (None, *TRAJECTORY_KINDS)]
    return {"description": "kind = library kind + its arguments (cadfeat trajectories), or csv = file of poses",
            "oneOf": forms}


def study_json_schema() -> JsonDict:
    """The JSON Schema (draft 2020-12) of a study file's tables."""
    props: JsonDict = {}
    defs: JsonDict = {}
    for name in study_schema.SECTIONS:
        if name in _MODELS:
            sub = _model_schema(_MODELS[name])
            defs.update(cast("JsonDict", sub.pop("$defs", {})))  # (pydantic's $defs: a JSON object)
            props[name] = sub
        else:
            props[name] = _trajectory_schema()
    out: JsonDict = {
        "$schema": "https://json-schema.org/draft/2020-12/schema", "$id": SCHEMA_ID, "title": "cadfeat study file",
        "type": "object", "additionalProperties": False, "required": list(study_schema.REQUIRED_SECTIONS),
        "properties": props,
    }
    if defs:
        out["$defs"] = defs
    return out
