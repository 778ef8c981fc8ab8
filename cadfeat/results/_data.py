"""results.json as the program builds it: ``TypedDict``s of the sections whose keys are read back before the file
is written (``ResultsData`` and its parts).

The ``Record`` models of this package type the file as it is read (``StudyResults``: validated, strict); these
type the dicts the run assembles, reads and amends on the way there (``cadfeat.study.pipeline``, ``run``,
``added_design``, ``closed_loop_check``; the closed loop's section, ``vision.closed_loop``). Numbers may still be
numpy scalars (``np.float64`` is a ``float``) until ``study.outputs.plain``; a section nobody reads back stays a
``JsonDict`` (values opaque).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, NotRequired, TypedDict

from cadfeat.results._record import JsonDict

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.camera import CameraFields

__all__ = ["AddedTargetsData", "CheckData", "ComparisonData", "DesignTrackingData", "EstimatorVerdictData",
           "FeatureData", "FindingData", "HistoryPointData", "HoleData", "HolesData", "IntervalData",
           "LoopSettingsData", "MeasureSummaryData", "MeasuresData", "MoveOnlyData", "ObjectiveChangeData",
           "ObjectiveChangesData", "ObjectivesData", "PairedTestData", "PerPoseData", "RefinementData",
           "RequirementData", "ResultsData", "ShopData", "StudyData", "SweepData", "TrackingData", "VariableData",
           "VerdictData", "VerificationData"]


class StudyData(TypedDict):
    """``study``: which study ran."""

    name: str
    file: str | None
    part: str
    part_kind: str
    seed: int
    description: str


class VariableData(TypedDict):
    """One design variable (``variables``); ``move_only``: its value at the move-only optimum when the delivered
    design is the refined added-target design."""

    name: str
    unit: str
    kind: str
    lower: float
    upper: float
    before: float
    after: float
    standard_sizes: list[float] | None
    move_only: NotRequired[float]


class HoleData(TypedDict):
    """One hole (``holes.before`` / ``holes.after``: ``study.outputs.hole_dict``), part frame, mm."""

    index: int
    name: str
    centre_mm: list[float]
    axis: list[float]
    radius_mm: float
    depth_mm: float
    through: bool
    kind: str
    fixed: bool
    movable: bool
    added: NotRequired[bool]


class HolesData(TypedDict):
    """``holes``: before and (a run) after."""

    before: list[HoleData]
    after: NotRequired[list[HoleData]]


class ObjectiveChangeData(TypedDict):
    """One objective before → after (``objectives.changes``, ``study.trust.objective_changes``)."""

    name: str
    unit: str
    before: float
    after: float | None
    change: float | None
    normalised_before: float
    normalised_after: float | None
    in_combination: bool


class ObjectiveChangesData(TypedDict):
    """The trust analysis of the objectives (``study.trust.objective_changes``): merged into ``objectives``."""

    limiting_before: str | None
    limiting: str | None
    constant: list[str]
    changes: list[ObjectiveChangeData]
    warnings: list[str]


class ObjectivesData(TypedDict):
    """``objectives``: raw objective values before/after, the combined objective, the trust analysis."""

    names: list[str]
    combine: str
    aggregate: str
    before: dict[str, float]
    after: NotRequired[dict[str, float] | None]
    combined_before: float | None
    combined_after: NotRequired[float | None]
    larger_is_better: NotRequired[bool]
    normalisation: NotRequired[JsonDict]
    limiting_before: NotRequired[str | None]
    limiting: NotRequired[str | None]
    constant: NotRequired[list[str]]
    changes: NotRequired[list[ObjectiveChangeData]]
    warnings: NotRequired[list[str]]
    score: str
    occlusion: bool


class FeatureData(TypedDict):
    """One hole's worst values over the trajectory (``measures.<design>.per_feature``; None: not finite)."""

    index: int
    name: str
    fov_min: float | None
    fov_px_min: float | None
    focus_min: float | None
    resolution_px_min: float | None
    visible_frac: float | None
    worst_pose: int
    hidden_frac: float | None
    hidden_worst_pose: int | None
    folded_frac: float | None


class PerPoseData(TypedDict):
    """One design's measures per pose (``measures.<design>.per_pose``; None: not finite)."""

    time_s: list[float | None]
    resolvability: list[float | None]
    sigma_min: list[float | None]
    condition: list[float | None]
    fov_min: list[float | None]
    focus_min: list[float | None]
    resolution_px_min: list[float | None]
    visible: list[int]
    centre_px: object
    """(L, N, 2) px, as nested lists."""


class MeasureSummaryData(TypedDict):
    """One design's measures (``study.outputs.measures_summary``): per hole, and per pose."""

    per_feature: list[FeatureData]
    per_pose: PerPoseData


class MeasuresData(TypedDict):
    """``measures``: each design's summary (``study.outputs.measures_summary``)."""

    before: MeasureSummaryData
    after: NotRequired[MeasureSummaryData]


class RequirementData(TypedDict):
    """One kept requirement checked (``constraints``; ``design.constraints.RequirementCheck.to_dict``), and where
    (``brep``, ``step``)."""

    name: str
    holes: list[str]
    required: float
    value: float
    margin: float
    unit: str
    ok: bool
    checked_on: NotRequired[str]


class FindingData(TypedDict):
    """One verdict rule's outcome (``report.verdict``)."""

    rule: str
    outcome: str
    detail: str


class VerdictData(TypedDict):
    """``verdict``: the decision, the limiting objective, one finding per rule (``report.verdict.verdict_json``)."""

    decision: str
    limiting: str | None
    findings: list[FindingData]


class VerificationData(TypedDict):
    """``verification``: the delivered files checked (``study.verify.export_and_verify``)."""

    step_roundtrip_max_error_mm: float
    step_roundtrip_max_axis_error_rad: float
    brep_valid: bool
    stl_watertight: bool
    tolerance_mm: float


class HistoryPointData(TypedDict):
    """One evaluation of the optimiser as results.json ``history`` lists it (``study.pipeline._history``)."""

    iteration: int
    f: float
    combined: float
    feasible: bool
    phase: str


class ShopData(TypedDict):
    """``shop``: the shop-ready rounding of the optimum (``study.pipeline._shop``)."""

    grid_mm: float
    hole_sizes: str | list[float]
    applied: bool
    notes: list[str]
    x_optimum: NotRequired[dict[str, float]]
    x_shop: NotRequired[dict[str, float]]
    residual_mm: NotRequired[float]
    moved: NotRequired[list[str]]
    resized: NotRequired[list[str]]
    combined_optimum: NotRequired[float]
    combined_shop: NotRequired[float]
    rebuilt_off_target_mm: NotRequired[float]


# -------------------------------------------------------------------------------------------- the closed loop
class IntervalData(TypedDict):
    """A statistic over the Monte-Carlo runs (``vision.metrics.aggregate_runs``; None: not finite)."""

    mean: float | None
    ci_low: float | None
    ci_high: float | None
    median: float | None
    runs_not_finite: int


class PairedTestData(TypedDict):
    """The paired test of one error before vs after (``vision.metrics.paired_verdict``)."""

    test: str
    runs: int
    alpha: float
    verdict: str
    p_value: float | None
    median_change: float | None
    min_change: NotRequired[float]


class EstimatorVerdictData(TypedDict):
    """One estimator's verdict (``tracking.verdicts.<m>``) and its two tests."""

    verdict: str
    translation: PairedTestData
    rotation: PairedTestData


class ComparisonData(TypedDict):
    """One more paired comparison of two tracked designs (``tracking.comparisons.<label>``)."""

    before: str
    after: str
    verdicts: dict[str, EstimatorVerdictData]
    verdicts_not_used: NotRequired[dict[str, EstimatorVerdictData]]


class DesignTrackingData(TypedDict):
    """One design's tracking (``tracking.designs.<name>``: ``vision.closed_loop.design_json``)."""

    estimators: dict[str, dict[str, IntervalData]]
    detection_rate: dict[str, float | None]
    frames_under_3_holes: float | None
    frames: int
    runs: int


class LoopSettingsData(TypedDict):
    """``tracking.settings``: the closed loop's configuration as it ran (``BeforeAfter.to_json``)."""

    estimators: list[str]
    runs: int
    noise_grey: float
    defocus: bool
    exposure_s: float
    initial_error_mm: float
    initial_error_deg: float
    r_px2: float
    q_rate_mm2_s2: float
    q_omega_rad2_s2: float
    iterations: int
    tau: float
    settle_frames: int
    frames: int
    frame_step: int
    rim_model: bool
    seed: int
    alpha: float
    min_change: float
    placement_mm: float | Sequence[float]
    placement_deg: float | Sequence[float]
    gain_sigma: float
    gate_px: float
    detector: str
    renderer: str
    spp: NotRequired[int]
    light: NotRequired[str | None]
    material: NotRequired[str | None]
    hole_ends: NotRequired[str]


class GlareCaveatData(TypedDict):
    """``tracking.check.glare``: the blind rims a raster check in a metal cell cannot see lose their contrast
    (``study.closed_loop_check.glare_caveat``): per design, hole → share of its facing poses; the warning line."""

    holes: dict[str, dict[str, float]]
    warning: str


class CheckData(TypedDict):
    """``tracking.check``: the closed-loop check of ``cadfeat run`` that made the section
    (``study.closed_loop_check``)."""

    mode: str
    runs: int
    frames: int
    estimators: list[str]
    seconds: float
    cpu_seconds: float
    in_worker: list[str]
    verdicts_not_used: NotRequired[dict[str, EstimatorVerdictData]]
    glare: NotRequired[GlareCaveatData]


class TrackingData(TypedDict):
    """The results.json ``tracking`` section: the closed loop's own (``vision.closed_loop.BeforeAfter.to_json``),
    then what ``study.tracking.run_tracking`` adds (warnings, error curves, drawn frames) and the check's block."""

    settings: LoopSettingsData
    designs: dict[str, DesignTrackingData]
    verdicts: dict[str, EstimatorVerdictData]
    comparisons: NotRequired[dict[str, ComparisonData]]
    timings_s: dict[str, float]
    warnings: NotRequired[list[str]]
    curves: NotRequired[JsonDict]
    frames: NotRequired[list[JsonDict]]
    check: NotRequired[CheckData]


class SweepData(TypedDict):
    """A ``cadfeat track --sweep`` (``study.tracking.sweep``, thesis §6.3.3): the setting varied, its values, and per
    value a row: the value, per design and estimator the Monte-Carlo mean RMS errors and convergence time, the
    verdicts per estimator."""

    kind: str
    values: list[float]
    rows: list[JsonDict]


# ------------------------------------------------------------------------------------------ added targets
class MoveOnlyData(TypedDict):
    """``added_targets.move_only``: the move-only optimum when the added design is delivered."""

    file: str
    holes: list[HoleData]
    objectives: dict[str, float] | None
    combined: float | None
    variables: dict[str, float]
    constraints: list[RequirementData]
    predicted_error_mm: float
    step: NotRequired[JsonDict]


class RefinementData(TypedDict):
    """``added_targets.refinement``: the joint refinement of the added holes (and the study's variables)."""

    error_before_mm: float
    error_mm: float
    moves: int
    evaluations: int
    variables: NotRequired[dict[str, float]]
    moved_holes: NotRequired[list[JsonDict]]


class AddedTargetsData(TypedDict):
    """``added_targets`` (``study.added_targets.run_phase``; amended by ``study.added_design``)."""

    settings: JsonDict
    faces: list[str]
    candidate_sites: int
    curve: JsonDict
    recommended: int
    reason: str
    refinement: RefinementData | None
    holes: list[JsonDict]
    predicted: dict[str, dict[str, float]]
    drop_vs_move_only: float
    constraints: list[RequirementData]
    requirements_hold: bool
    evaluations: int
    seconds: float
    move_only: NotRequired[MoveOnlyData]
    delivered: NotRequired[JsonDict]
    step: NotRequired[JsonDict]
    tracking: NotRequired[JsonDict | None]


# ----------------------------------------------------------------------------------------------- the whole
class ResultsData(TypedDict):
    """The results.json a run (``study.pipeline.compute`` and ``run``) or an evaluation builds; the sections
    nobody reads back before the file is written are ``JsonDict``s."""

    schema_version: int
    cadfeat_version: str
    created: str
    evaluation_only: NotRequired[bool]
    study: StudyData
    inputs: JsonDict
    camera: CameraFields
    trajectory: JsonDict
    part_pose: NotRequired[JsonDict]
    variables: NotRequired[list[VariableData]]
    holes: HolesData
    objectives: ObjectivesData
    measures: MeasuresData
    constraints: NotRequired[list[RequirementData]]
    requirements_used: NotRequired[list[JsonDict]]
    shop: NotRequired[ShopData]
    patterns: NotRequired[list[JsonDict]]
    robustness: NotRequired[JsonDict | None]
    design_matrix: NotRequired[JsonDict | None]
    history: NotRequired[list[HistoryPointData]]
    sweep: NotRequired[JsonDict | None]
    pareto: NotRequired[object]
    optimizer: NotRequired[JsonDict]
    interrupted: NotRequired[bool]
    preflight: NotRequired[JsonDict]
    warnings: list[str]
    pose_accuracy: NotRequired[JsonDict | None]
    verification: NotRequired[VerificationData]
    files: NotRequired[list[JsonDict]]
    timings_s: NotRequired[dict[str, float]]
    versions: NotRequired[dict[str, str]]
    tracking: NotRequired[TrackingData]
    physical_views: NotRequired[JsonDict]
    added_targets: NotRequired[AddedTargetsData]
    verdict: NotRequired[VerdictData]
