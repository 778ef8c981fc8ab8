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

import functools
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar, Optional, TypeAlias, TypeVar

from pydantic import BaseModel, ConfigDict, JsonValue, create_model

__all__ = ["SCHEMA_ID", "SCHEMA_VERSION", "DesignDraws", "DesignMatrix", "EstimatorErrors", "FeatureSummary",
           "FileEntry", "Finding", "HelpMost", "HelpMostBest", "HoleRecord", "Holes", "Interval", "Json",
           "MeasureSummary", "Normalisation", "Measures", "ObjectiveChange", "Objectives", "OptimizerRecord",
           "OutOfSample", "PairedTest", "Pattern", "PoseAccuracy", "PoseDesign", "PoseErrors", "Record",
           "RequirementCheck", "RequirementUsed", "Results", "RobustObjective", "Robustness", "SampleShift",
           "Sensitivity", "Shop", "Spread", "StudyRecord", "StudyResults", "Tracking", "TrackingCheck",
           "TrackingDesign", "TrackingFrame", "TrackingSettings", "TrackingVerdict", "TrajectoryRecord", "Variable",
           "Verdict", "Verification", "WeakestPhase", "partial_model", "present", "results_json_schema", "section",
           "value"]

SCHEMA_VERSION = 4
"""results.json layout version (``schema_version``): 1 first layout; 2 ``shop``, ``patterns`` and
``robustness`` added by issue 13; 3: ``verdict``, tracking holes named H1…; 4: ``pose_accuracy``, ``tracking`` and
``robustness``'s robust-redesign keys (designs, out_of_sample …) typed in the schema, the layout unchanged (a
version-3 file reads the same); readers compare it before relying on a key."""
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


class PoseErrors(Record):
    """Predicted pose errors (RMS or worst over the trajectory; ``pose_accuracy.<design>.rms``/``worst``):
    single frame (error, its bias and noise parts) and the IEKF posterior bound, translation mm, rotation deg."""

    error_translation_mm: Number | None = None
    bias_translation_mm: Number | None = None
    noise_translation_mm: Number | None = None
    iekf_translation_mm: Number | None = None
    error_rotation_deg: Number | None = None
    bias_rotation_deg: Number | None = None
    noise_rotation_deg: Number | None = None
    iekf_rotation_deg: Number | None = None


class WeakestPhase(Record):
    """The weakest direction of the pose estimate in one phase of the path (σ in mm)."""

    phase: str
    weakest: str
    sigma_mm: Number | None = None
    fraction: Number | None = None
    poses: list[int] = []


class HelpMostBest(Record):
    """The one change that would help the pose estimate most, in words."""

    sentence: str
    hole: str | None = None
    change: str | None = None
    d_error_per_mm: Number | None = None


class HelpMost(Record):
    """``pose_accuracy.<design>.help_most``: what would help most (per movable hole, and the best)."""

    best: HelpMostBest | None = None
    holes: Json = None
    rms_translation_mm: Number | None = None
    step_mm: Number | None = None


class PoseDesign(Record):
    """``pose_accuracy.before`` / ``after``: one design's predicted pose error (issue 17)."""

    rms: PoseErrors | None = None
    worst: PoseErrors | None = None
    per_pose: dict[str, list[Number | None]] = {}
    """Per trajectory sample, the ``PoseErrors`` keys."""
    share: dict[str, Number | None] = {}
    """Each hole's share of the pose information (fraction, mean over the trajectory)."""
    weakest: list[WeakestPhase] = []
    help_most: HelpMost | None = None
    holes_detected_mean: Number | None = None


class PoseAccuracy(Record):
    """``pose_accuracy``: the predicted pose error along the trajectory, before and after
    (``cadfeat.study.pose_accuracy``)."""

    times_s: list[Number] = []
    phases: list[str] = []
    before: PoseDesign | None = None
    after: PoseDesign | None = None
    model: str | None = None
    movable: list[str] = []
    rotation_length_mm: Number | None = None
    tuning: dict[str, Number] | None = None


class Interval(Record):
    """A statistic over the Monte-Carlo runs: mean and median with its 95 % bootstrap interval."""

    mean: Number | None = None
    median: Number | None = None
    ci_low: Number | None = None
    ci_high: Number | None = None
    runs_not_finite: int | None = None


class EstimatorErrors(Record):
    """One estimator's tracking errors over the runs (``tracking.designs.<design>.estimators.<m>``): RMS, p95
    and max translation (mm) and rotation (deg), frames lost (and their fraction), convergence time (s)."""

    trans_mm_rms: Interval | None = None
    trans_mm_p95: Interval | None = None
    trans_mm_max: Interval | None = None
    rot_deg_rms: Interval | None = None
    rot_deg_p95: Interval | None = None
    rot_deg_max: Interval | None = None
    frames_lost: Interval | None = None
    lost_frac: Interval | None = None
    convergence_s: Interval | None = None


class TrackingDesign(Record):
    """``tracking.designs.<design>``: per estimator the errors, per hole the detection rate (None: never in view)."""

    estimators: dict[str, EstimatorErrors] = {}
    detection_rate: dict[str, Number | None] = {}
    frames: int | None = None
    runs: int | None = None
    frames_under_3_holes: Number | None = None


class PairedTest(Record):
    """The paired test of one error (translation or rotation) before against after."""

    test: str = ""
    p_value: Number | None = None
    median_change: Number | None = None
    alpha: Number | None = None
    min_change: Number = 0.0
    runs: int | None = None
    verdict: str | None = None


class TrackingVerdict(Record):
    """``tracking.verdicts.<estimator>``: better / worse / no significant difference / mixed, and its tests."""

    verdict: str
    translation: PairedTest | None = None
    rotation: PairedTest | None = None


class TrackingCheck(Record):
    """``tracking.check``: which closed-loop check of ``cadfeat run`` produced the section (fast or full)."""

    mode: str | None = None
    estimators: list[str] = []
    runs: int | None = None
    frames: int | None = None
    seconds: Number | None = None


class TrackingFrame(Record):
    """A camera frame written beside the results (path relative to the output folder)."""

    path: str
    design: str
    frame: int
    time_s: Number
    detected: int
    holes: int


class TrackingSettings(Record):
    """``tracking.settings``: the simulation's settings (``[tracking]``; noise in grey levels, times in s)."""

    estimators: list[str] = []
    frames: int | None = None
    runs: int | None = None
    noise_grey: Number | None = None
    defocus: bool | None = None
    exposure_s: Number | None = None
    initial_error_mm: Number | None = None
    initial_error_deg: Number | None = None
    placement_mm: Number = 0.0
    placement_deg: Number = 0.0
    gain_sigma: Number = 0.0
    settle_frames: int | None = None


class Tracking(Record):
    """``tracking``: the closed-loop tracking simulation before and after (``cadfeat.vision``, ``cadfeat track``
    or ``cadfeat run``'s check)."""

    settings: TrackingSettings | None = None
    designs: dict[str, TrackingDesign] = {}
    verdicts: dict[str, TrackingVerdict] = {}
    curves: dict[str, Json] = {}
    frames: list[TrackingFrame] = []
    warnings: list[str] = []
    check: TrackingCheck | None = None


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
    history: list[dict[str, Json]] | None = None
    sweep: Json = None
    pareto: Json = None
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

Results: TypeAlias = StudyResults | Mapping[str, Any]
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
