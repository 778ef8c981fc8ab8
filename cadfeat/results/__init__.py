"""results.json as a typed model: ``StudyResults`` (pydantic v2), written by ``cadfeat run`` / ``evaluate`` /
``track`` and read by ``cadfeat.report``; its JSON Schema (``cadfeat schema --results``) carries the version.

Each top-level section is one field. A section cadfeat types is a ``Record`` sub-model (``Objectives``,
``Verdict``, ``HoleRecord`` …); a section another part of the program owns and has not typed yet is plain JSON
(``Json``). **To add a section**: one optional field, ``my_section: MySection | None = None`` with ``class
MySection(Record)`` (or ``Json``), and bump ``SCHEMA_VERSION`` when an existing key changes meaning.
Every ``Record`` keeps keys it does not declare (``extra="allow"``): a key a newer writer adds inside a section
passes through unchanged and is written back, so the model never drops data.

A sub-package: the base ``Record`` in ``_record``, the robustness section in ``_robustness``, the pose-accuracy
and tracking sections in ``_closed_loop``, all re-exported here; the report reads every section through
``section(results, "x", Model)``. ``_data``: the ``TypedDict``s of the dicts a run builds and reads back before
the file is written (``ResultsData``).

Writing is the identity on the data: ``StudyResults.from_data(d).to_data() == d`` for every results.json
cadfeat writes (keys never given stay absent: ``exclude_unset``; strict types: an integer stays an integer).
Values are rounded and made JSON-ready by ``cadfeat.study.outputs.plain`` before the model sees them.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar, Optional, TypeAlias, TypeVar

from pydantic import create_model

from cadfeat.results._added_targets import AddedTargetCurve, AddedTargetHole, AddedTargets
from cadfeat.results._closed_loop import (
    EstimatorErrors,
    HelpMost,
    HelpMostBest,
    Interval,
    PairedTest,
    PhysicalFrame,
    PhysicalViews,
    PoseAccuracy,
    PoseDesign,
    PoseErrors,
    Tracking,
    TrackingCheck,
    TrackingComparison,
    TrackingDesign,
    TrackingFrame,
    TrackingSettings,
    TrackingVerdict,
    WeakestPhase,
)
from cadfeat.results._data import (
    AddedTargetsData,
    CheckData,
    ComparisonData,
    DesignTrackingData,
    EstimatorVerdictData,
    FeatureData,
    FindingData,
    GlareCaveatData,
    HistoryPointData,
    HoleData,
    HolesData,
    IntervalData,
    LoopSettingsData,
    MeasuresData,
    MeasureSummaryData,
    MoveOnlyData,
    ObjectiveChangeData,
    ObjectiveChangesData,
    ObjectivesData,
    PairedTestData,
    PerPoseData,
    RefinementData,
    RequirementData,
    ResultsData,
    ShopData,
    StudyData,
    SweepData,
    TrackingData,
    VariableData,
    VerdictData,
    VerificationData,
)
from cadfeat.results._record import Json, JsonDict, Number, Record
from cadfeat.results._robustness import (
    DesignDraws,
    OutOfSample,
    Robustness,
    RobustObjective,
    SampleShift,
    Sensitivity,
    Spread,
)

__all__ = ["SCHEMA_ID", "SCHEMA_VERSION", "AddedTargetCurve", "AddedTargetHole", "AddedTargets", "AddedTargetsData",
           "CheckData", "ComparisonData", "DesignDraws", "DesignMatrix", "DesignTrackingData", "EstimatorErrors",
           "GlareCaveatData",
           "EstimatorVerdictData", "FeatureData", "FeatureSummary", "FileEntry", "Finding", "FindingData", "HelpMost",
           "HelpMostBest", "HistoryPoint", "HistoryPointData", "HoleData", "HoleRecord", "Holes", "HolesData",
           "Interval", "IntervalData", "Json", "JsonDict", "LoopSettingsData", "MeasureSummary", "MeasureSummaryData",
           "Measures", "MeasuresData", "MoveOnlyData", "Normalisation", "ObjectiveChange", "ObjectiveChangeData",
           "ObjectiveChangesData", "Objectives", "ObjectivesData", "OptimizerRecord", "OutOfSample", "PairedTest",
           "PairedTestData", "Pareto", "Pattern", "PerPoseData", "PhysicalFrame", "PhysicalViews", "PoseAccuracy",
           "PoseDesign", "PoseErrors", "Record", "RefinementData", "RequirementCheck", "RequirementData",
           "RequirementUsed", "Results", "ResultsData", "RobustObjective", "Robustness", "SampleShift", "Sensitivity",
           "Shop", "ShopData", "Spread", "StudyData", "StudyRecord", "StudyResults", "Sweep", "SweepData", "Tracking",
           "TrackingCheck", "TrackingComparison", "TrackingData", "TrackingDesign", "TrackingFrame", "TrackingSettings",
           "TrackingVerdict", "TrajectoryRecord", "Variable", "VariableData", "Verdict", "VerdictData", "Verification",
           "VerificationData", "WeakestPhase", "partial_model", "present", "results_json_schema", "section", "value"]

SCHEMA_VERSION = 4
"""results.json layout version (``schema_version``): 1 first layout; 2 ``shop``, ``patterns`` and
``robustness`` added by issue 13; 3: ``verdict``, tracking holes named H1…; 4: ``pose_accuracy``, ``tracking`` and
``robustness``'s robust-redesign keys (designs, out_of_sample …) typed in the schema, the layout unchanged (a
version-3 file reads the same); readers compare it before relying on a key."""
SCHEMA_ID = f"https://cadfeat.invalid/schema/results-v{SCHEMA_VERSION}.json"
"""The results schema's ``$id`` (a name, not a place to fetch it from), versioned."""

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
    added: bool | None = None
    """True for a target hole cadfeat added (``[add_targets]``, after the part's holes in ``holes.after``)."""


class Holes(Record):
    """``holes``: before and (a run) after, index-aligned: the same physical hole at the same index; with added
    target holes (``[add_targets]``) ``after`` — the delivered design — lists them after the part's holes."""

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
    holes: list[str | int] = []
    """Hole names (older layouts: hole indices)."""
    value: Number | None = None
    required: Number | None = None
    margin: Number | None = None
    unit: str = ""
    ok: bool | None = None
    checked_on: str | None = None


class RequirementUsed(Record):
    """A requirement of the optimisation (``requirements_used``): its 2-D margin at the optimum (the unit mm
    unless given)."""

    name: str
    holes: list[str] = []
    margin: Number | None = None
    required: Number | None = None
    unit: str = "mm"


class ObjectiveChange(Record):
    """One objective before → after in its own unit (``objectives.changes``, ``cadfeat.study.trust``), its
    normalised values and whether it enters the combination."""

    name: str
    unit: str = ""
    before: Number | None = None
    after: Number | None = None
    change: Number | None = None
    normalised_before: Number | None = None
    normalised_after: Number | None = None
    in_combination: bool | None = None


class Normalisation(Record):
    """``objectives.normalisation``: how the objectives were made comparable (method, reference value per
    objective, where each came from, a note)."""

    method: str | None = None
    reference: dict[str, Number | None] | None = None
    sources: dict[str, Json] | None = None
    note: str | None = None


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
    normalisation: Normalisation | None = None
    changes: list[ObjectiveChange] = []
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


class HistoryPoint(Record):
    """One evaluation of the optimiser (``history``): the minimised f, the combined objective (larger is better),
    feasibility, the phase."""

    iteration: int | None = None
    f: Number | None = None
    combined: Number | None = None
    feasible: bool = True
    phase: str | None = None
    time_s: Number | None = None


class Sweep(Record):
    """``sweep``: each objective over the range of the one design variable of a one-variable study."""

    variable: str = "parameter"
    unit: str | None = None
    values: list[Number | None] = []
    objectives: dict[str, list[Number | None]] = {}
    combined: list[Number | None] | None = None


class Pareto(Record):
    """``pareto``: the non-dominated designs (objective values per point), the chosen one and why."""

    names: list[str] = []
    points: list[list[Number | None]] = []
    chosen: int | None = None
    chosen_by: str | None = None
    feasible: list[bool] | None = None
    normalised: list[list[Number | None]] | None = None
    x: Json = None


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


class Pattern(Record):
    """A hole pattern of the original (``patterns``, ``cadfeat.design.patterns``) and whether the design keeps it:
    a bolt circle (centre, radius mm, count), a grid (shape, pitch mm), an opposite or a mirror pair (normal)."""

    kind: str
    holes: list[str] = []
    indices: list[int] = []
    broken: bool = False
    why: str = ""
    centre: list[Number] | None = None
    radius_mm: Number | None = None
    count: int | None = None
    shape: list[int] | None = None
    pitch_mm: list[Number] | None = None
    normal: list[Number] | None = None
    point: list[Number] | None = None


class Shop(Record):
    """``shop``: the shop-ready rounding (``cadfeat.design.shop``): moved holes on a grid (mm), resized holes on
    the hole table, the model's combined objective at the optimum and rounded, notes."""

    applied: bool | None = None
    grid_mm: Number | None = None
    hole_sizes: Json = None
    moved: list[str] = []
    resized: list[str] = []
    notes: list[str] = []
    combined_optimum: Number | None = None
    combined_shop: Number | None = None
    residual_mm: Number | None = None
    rebuilt_off_target_mm: Number | None = None
    x_optimum: dict[str, Number] | None = None
    x_shop: dict[str, Number] | None = None


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
    shop: Shop | None = None
    patterns: list[Pattern] | None = None
    robustness: Robustness | None = None
    design_matrix: DesignMatrix | None = None
    history: list[HistoryPoint] | None = None
    sweep: Sweep | None = None
    pareto: Pareto | None = None
    optimizer: OptimizerRecord | None = None
    interrupted: bool | None = None
    preflight: dict[str, Json] | None = None
    warnings: list[str] = []
    pose_accuracy: PoseAccuracy | None = None
    verification: Verification | None = None
    files: list[FileEntry] | None = None
    timings_s: dict[str, Number] | None = None
    versions: dict[str, str] | None = None
    tracking: Tracking | None = None
    physical_views: PhysicalViews | None = None
    added_targets: AddedTargets | None = None
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

Results: TypeAlias = StudyResults | Mapping[str, object]
"""What ``cadfeat.report`` reads: the typed results, or plain data (as read from results.json, or partial data
built by hand)."""


def value(results: Results, name: str) -> Any:
    """A top-level value of ``results`` that is not a typed section (a flag such as ``interrupted``, or a section
    still ``Json``), or None when absent."""
    return getattr(results, name, None) if isinstance(results, StudyResults) else results.get(name)


def present(record: Record | None) -> bool:
    """True for a section (or sub-record) that holds something: given and not ``{}`` (as ``bool`` of the dict)."""
    return record is not None and bool(record.to_data())


def section(results: Results, name: str, model: type[R], *, partial: bool = False) -> R | None:
    """The typed section ``name`` of ``results`` (a ``StudyResults``, or plain data as read from results.json or
    built by hand, possibly partial), or None when it is absent. How ``cadfeat.report`` reads a section.

    ``partial``: the section may lack keys the model requires (``cadfeat track`` writes ``study`` with its name
    only into a results.json it starts); those read as None, every key given is still checked."""
    data = getattr(results, name, None) if isinstance(results, StudyResults) else results.get(name)
    if data is None or isinstance(data, model):
        return data
    return (partial_model(model) if partial else model).model_validate(
        data.to_data() if isinstance(data, Record) else data)


@functools.cache
def partial_model(model: type[R]) -> type[R]:
    """``model`` with its required keys optional (None when absent): a subclass, so it is still a ``model``."""
    loose: dict[str, Any] = {n: (Optional[f.annotation], None)  # noqa: UP045 (a runtime type, not an annotation)
                             for n, f in model.model_fields.items() if f.is_required()}
    if not loose:
        return model
    return create_model(f"Partial{model.__name__}", __base__=model, __doc__=model.__doc__, **loose)


def results_json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of results.json, versioned by ``$id`` and ``schema_version``."""
    out = StudyResults.model_json_schema(mode="serialization")
    out.update({"$schema": "https://json-schema.org/draft/2020-12/schema", "$id": SCHEMA_ID,
                "title": f"cadfeat results.json, schema_version {SCHEMA_VERSION}"})
    out["properties"]["schema_version"]["const"] = SCHEMA_VERSION
    return out
