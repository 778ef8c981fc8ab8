"""results.json as a typed model: ``StudyResults`` (pydantic v2), written by ``cadfeat run`` / ``evaluate`` /
``track`` and read by ``cadfeat.report``; its JSON Schema (``cadfeat schema --results``) carries the version.

Each top-level section is one field. A section cadfeat types is a ``Record`` sub-model (``Objectives``,
``Verdict``, ``HoleRecord`` …); a section another part of the program owns and has not typed yet is plain JSON
(``Json``). **To add a section**: one optional field, ``my_section: MySection | None = None`` with ``class
MySection(Record)`` (or ``Json``), and bump ``SCHEMA_VERSION`` when an existing key changes meaning.
Every ``Record`` keeps keys it does not declare (``extra="allow"``): a key a newer writer adds inside a section
passes through unchanged and is written back, so the model never drops data.

Writing is the identity on the data: ``StudyResults.from_data(d).to_data() == d`` for every results.json
cadfeat writes (keys never given stay absent: ``exclude_unset``; strict types: an integer stays an integer).
Values are rounded and made JSON-ready by ``cadfeat.study.outputs.plain`` before the model sees them.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar, TypeAlias, TypeVar

from pydantic import BaseModel, ConfigDict, JsonValue

__all__ = ["SCHEMA_ID", "SCHEMA_VERSION", "DesignMatrix", "FeatureSummary", "FileEntry", "Finding", "HoleRecord",
           "Holes", "Json", "MeasureSummary", "Measures", "Objectives", "OptimizerRecord", "Record", "RequirementCheck",
           "RequirementUsed", "Robustness", "StudyRecord", "StudyResults", "TrajectoryRecord", "Variable", "Verdict",
           "Verification", "results_json_schema", "section"]

SCHEMA_VERSION = 3
"""results.json layout version (``schema_version``): 1 first layout; 2 ``shop``, ``patterns`` and
``robustness`` added by issue 13; 3: ``verdict``, tracking holes named H1…); readers compare it before relying
on a key."""
SCHEMA_ID = f"https://cadfeat.invalid/schema/results-v{SCHEMA_VERSION}.json"
"""The results schema's ``$id`` (a name, not a place to fetch it from), versioned."""

Json: TypeAlias = JsonValue
"""A section (or value) kept as plain JSON: not typed here yet."""
Number: TypeAlias = int | float
"""A JSON number as written (an integer stays an integer, a float a float: strict, no coercion)."""


class Record(BaseModel):
    """A results.json object: strict (no coercion, so the data round-trips), keys not declared are kept."""

    model_config = ConfigDict(strict=True, extra="allow", frozen=False, ser_json_inf_nan="null")

    def to_data(self) -> dict[str, Any]:
        """The object as plain JSON data: the keys that were given (or set), nothing added."""
        return self.model_dump(exclude_unset=True)


class StudyRecord(Record):
    """``study``: which study ran (``file`` None for a study given as a dict)."""

    name: str
    file: str | None = None
    part: str
    part_kind: str
    seed: int
    description: str = ""


class TrajectoryRecord(Record):
    """``trajectory``: the poses that were scored (T_task_cam, 4x4 each, mm) and their times (s)."""

    T_task_cam: list[list[list[Number]]]
    time_s: list[Number]
    duration_s: Number
    n_samples: int
    kind: str
    pose: int | None = None
    """``cadfeat evaluate --pose k``: the one sample scored."""


class HoleRecord(Record):
    """One hole (part frame, mm): ``outputs.hole_dict``."""

    index: int
    name: str
    centre_mm: list[Number]
    axis: list[Number]
    radius_mm: Number
    depth_mm: Number
    through: bool
    kind: str
    fixed: bool
    movable: bool


class Holes(Record):
    """``holes``: before and (a run) after, index-aligned: the same physical hole at the same index."""

    before: list[HoleRecord]
    after: list[HoleRecord] | None = None


class Variable(Record):
    """One design variable (``variables``): its bounds, value before and after, unit and kind."""

    name: str
    unit: str = ""
    kind: str = ""
    lower: Number | None = None
    upper: Number | None = None
    before: Number | None = None
    after: Number | None = None
    standard_sizes: list[Number] | None = None


class FeatureSummary(Record):
    """One hole's worst values over the trajectory (``measures.<design>.per_feature``): margins (FOV cone, FOV
    image px, focus × half depth of field, resolution px), visible/hidden/folded fractions, the worst pose."""

    index: int
    name: str
    fov_min: Number | None = None
    fov_px_min: Number | None = None
    focus_min: Number | None = None
    resolution_px_min: Number | None = None
    visible_frac: Number | None = None
    hidden_frac: Number | None = None
    hidden_worst_pose: int | None = None
    folded_frac: Number | None = None
    worst_pose: int | None = None


class MeasureSummary(Record):
    """The measures of one design (``measures.before`` / ``measures.after``): per hole, and per pose (plain)."""

    per_feature: list[FeatureSummary] = []
    per_pose: Json = None


class Measures(Record):
    """``measures``: the design before and (a run) after."""

    before: MeasureSummary
    after: MeasureSummary | None = None


class RequirementCheck(Record):
    """One kept requirement checked on the delivered design (``constraints``): value, required, margin (≥ 0:
    holds), unit, the holes, where it was checked (``brep``, ``step``)."""

    name: str
    holes: list[str] = []
    value: Number | None = None
    required: Number | None = None
    margin: Number | None = None
    unit: str = ""
    ok: bool | None = None
    checked_on: str | None = None


class RequirementUsed(Record):
    """A requirement of the optimisation (``requirements_used``): its 2-D margin at the optimum."""

    name: str
    holes: list[str] = []
    margin: Number | None = None


class Objectives(Record):
    """``objectives``: raw objective values by name (g_FOV …, larger is better) before/after, the combined
    objective, and the trust analysis (``changes``, ``limiting``; ``study.trust``)."""

    names: list[str]
    combine: str
    aggregate: str
    before: dict[str, Number | None]
    after: dict[str, Number | None] | None = None
    combined_before: Number | None = None
    combined_after: Number | None = None
    larger_is_better: bool = True
    normalisation: Json = None
    changes: list[Json] = []
    constant: list[str] = []
    limiting: str | None = None
    limiting_before: str | None = None
    warnings: list[str] = []
    score: Json = None
    occlusion: bool = True


class OptimizerRecord(Record):
    """``optimizer``: what the solver did."""

    method: str
    n_evals: int
    linear_feature_map: bool
    prediction_error_mm: Number | None = None
    integer_combinations: int = 1
    rebuild_failed_at_model_optimum: str | None = None


class DesignMatrix(Record):
    """``design_matrix``: ∂(requirements)/∂(parameters) at the optimum and its axiomatic verdict (eq. 2.2)."""

    rows: list[str]
    cols: list[str]
    matrix: list[list[Number | None]]
    verdict: str
    note: str = ""


class Verification(Record):
    """``verification``: the delivered files checked (B-rep valid, STEP round trip, STL watertight)."""

    brep_valid: bool | None = None
    step_roundtrip_max_error_mm: Number | None = None
    step_roundtrip_max_axis_error_rad: Number | None = None
    stl_watertight: bool | None = None
    tolerance_mm: Number | None = None


class FileEntry(Record):
    """One written file: name relative to the output folder, size, SHA-256."""

    name: str
    bytes: int
    sha256: str


class Finding(Record):
    """One verdict rule's outcome (``cadfeat.report.verdict.RULES``)."""

    rule: str
    outcome: str
    detail: str


class Verdict(Record):
    """``verdict``: adopt / adopt with care / do not adopt, the limiting objective, one finding per rule."""

    decision: str
    limiting: str | None = None
    findings: list[Finding] = []


class Robustness(Record):
    """``robustness``: the tolerance study (``design.robustness``); further keys (designs, out of sample) pass
    through until typed here."""

    names: list[str] = []
    samples: int = 0
    position_tol_mm: Number | None = None
    size_steps: int | None = None
    camera_position_mm: Number | None = None
    camera_angle_deg: Number | None = None
    razor_edge: list[str] = []
    manufacturing: Json = None
    camera: Json = None


class StudyResults(Record):
    """The whole of results.json. Sections a run writes and ``evaluate`` does not are optional."""

    schema_version: int
    cadfeat_version: str
    created: str
    evaluation_only: bool | None = None
    study: StudyRecord
    inputs: dict[str, Json]
    camera: dict[str, Json]
    trajectory: TrajectoryRecord
    part_pose: dict[str, Json] | None = None
    variables: list[Variable] | None = None
    holes: Holes
    objectives: Objectives
    measures: Measures
    constraints: list[RequirementCheck] | None = None
    requirements_used: list[RequirementUsed] | None = None
    shop: dict[str, Json] | None = None
    patterns: list[Json] | None = None
    robustness: Robustness | None = None
    design_matrix: DesignMatrix | None = None
    history: list[dict[str, Json]] | None = None
    sweep: Json = None
    pareto: Json = None
    optimizer: OptimizerRecord | None = None
    interrupted: bool | None = None
    preflight: dict[str, Json] | None = None
    warnings: list[str] = []
    pose_accuracy: dict[str, Json] | None = None
    verification: Verification | None = None
    files: list[FileEntry] | None = None
    timings_s: dict[str, Number] | None = None
    versions: dict[str, str] | None = None
    tracking: dict[str, Json] | None = None
    verdict: Verdict | None = None

    file_name: ClassVar[str] = "results.json"

    @classmethod
    def from_data(cls, data: Mapping[str, Any]) -> StudyResults:
        """The typed results of plain JSON data (as ``plain`` gives it, or as read from results.json)."""
        return cls.model_validate(dict(data))

    @classmethod
    def read(cls, path: str | Path) -> StudyResults:
        """A results.json file (or the results.json in a folder)."""
        p = Path(path)
        p = p / cls.file_name if p.is_dir() else p
        return cls.from_data(json.loads(p.read_text(encoding="utf-8")))

    @property
    def is_run(self) -> bool:
        """A ``cadfeat run`` (an after design exists), not an ``evaluate``."""
        return self.holes.after is not None


R = TypeVar("R", bound=Record)


def section(results: StudyResults | Mapping[str, Any], name: str, model: type[R]) -> R | None:
    """The typed section ``name`` of ``results`` (a ``StudyResults``, or plain data as read from results.json or
    built by hand, possibly partial), or None when it is absent. How ``cadfeat.report`` reads a section."""
    value = getattr(results, name, None) if isinstance(results, StudyResults) else results.get(name)
    if value is None or isinstance(value, model):
        return value
    return model.model_validate(value.to_data() if isinstance(value, Record) else value)


def results_json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of results.json, versioned by ``$id`` and ``schema_version``."""
    out = StudyResults.model_json_schema(mode="serialization")
    out.update({"$schema": "https://json-schema.org/draft/2020-12/schema", "$id": SCHEMA_ID,
                "title": f"cadfeat results.json, schema_version {SCHEMA_VERSION}"})
    out["properties"]["schema_version"]["const"] = SCHEMA_VERSION
    return out
