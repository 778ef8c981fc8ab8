"""results.json ``pose_accuracy`` (the predicted pose error, issue 17) and ``tracking`` (the closed-loop
simulation, ``cadfeat.vision``)."""

from __future__ import annotations

from cadfeat.results._record import Json, Number, Record

__all__ = ["EstimatorErrors", "HelpMost", "HelpMostBest", "Interval", "PairedTest", "PoseAccuracy", "PoseDesign",
           "PoseErrors", "Tracking", "TrackingCheck", "TrackingComparison", "TrackingDesign", "TrackingFrame",
           "TrackingSettings", "TrackingVerdict", "WeakestPhase"]


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


class TrackingComparison(Record):
    """``tracking.comparisons.<label>``: one more paired comparison of two tracked designs of the same runs
    (``before`` and ``after`` name designs of ``tracking.designs``), per estimator as ``tracking.verdicts``. A
    study with added target holes compares the move-only optimum with the original and the delivered design with
    the move-only optimum (``study.closed_loop_check``)."""

    before: str
    after: str
    verdicts: dict[str, TrackingVerdict] = {}


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


class PhysicalFrame(Record):
    """A physically rendered camera frame of one design (``study.physical_views``): the holes the closed loop
    expects there, those the cell's detector found and those it missed (by name); the PNG's path relative to the
    output folder (absent when no frame was written)."""

    design: str
    frame: int
    time_s: Number
    expected: list[str] = []
    detected: list[str] = []
    missed: list[str] = []
    path: str | None = None


class PhysicalViews(Record):
    """``physical_views``: what the robot's camera will see — both designs rendered physically (Mitsuba 3) in the
    study's cell at three poses, with the cell's detector's detections and misses."""

    light: str | None = None
    material: str | None = None
    hole_ends: str | None = None
    detector: str | None = None
    spp: int | None = None
    noise_grey: Number | None = None
    frames: list[PhysicalFrame] = []
    seconds: Number | None = None


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
    placement_mm: Number | list[Number] = 0.0
    placement_deg: Number | list[Number] = 0.0
    gain_sigma: Number = 0.0
    settle_frames: int | None = None
    detector: str = "cadfeat"
    renderer: str = "raster"


class Tracking(Record):
    """``tracking``: the closed-loop tracking simulation before and after (``cadfeat.vision``, ``cadfeat track``
    or ``cadfeat run``'s check)."""

    settings: TrackingSettings | None = None
    designs: dict[str, TrackingDesign] = {}
    verdicts: dict[str, TrackingVerdict] = {}
    comparisons: dict[str, TrackingComparison] = {}
    curves: dict[str, Json] = {}
    frames: list[TrackingFrame] = []
    warnings: list[str] = []
    check: TrackingCheck | None = None
