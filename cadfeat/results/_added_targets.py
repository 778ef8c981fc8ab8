"""results.json ``added_targets``: the new target holes cadfeat proposes (``cadfeat.study.added_targets``, issue 31)."""

from __future__ import annotations

from cadfeat.results._record import Json, Number, Record

__all__ = ["AddedTargetCurve", "AddedTargetHole", "AddedTargets"]


class AddedTargetCurve(Record):
    """The greedy curve: minus g_POSE (mm: the predicted pose error aggregated over the path as the study's
    ``pose_aggregate`` says, rms by default) with 0, 1, … added holes, and each step's site (mm)."""

    added: list[int] = []
    error_mm: list[Number] = []
    aggregate: str = "rms"
    sites: list[list[Number]] = []


class AddedTargetHole(Record):
    """One added hole (mm): rim centre, axis, drill, depth, chamfer, its face and status "added"."""

    name: str
    centre: list[Number]
    axis: list[Number]
    diameter_mm: Number
    depth_mm: Number
    chamfer_mm: Number
    rim_radius_mm: Number
    face: str = ""
    status: str = "added"


class AddedTargets(Record):
    """``added_targets``: the allowed faces and candidate sites, the curve, the recommended number and why, the
    added holes, the predicted error of the original, the move-only optimum and the added design, every kept
    requirement measured on the B-rep and the re-imported STEP, and the closed loop of the three designs. With
    k ≥ 1 the added design is the delivered one (``delivered``; ``study.added_design``) and the move-only
    optimum's numbers are in ``move_only``."""

    settings: dict[str, Json] = {}
    faces: list[str] = []
    candidate_sites: int = 0
    curve: AddedTargetCurve | None = None
    recommended: int = 0
    reason: str = ""
    refinement: dict[str, Json] | None = None
    holes: list[AddedTargetHole] = []
    predicted: dict[str, dict[str, Number]] = {}
    drop_vs_move_only: Number | None = None
    constraints: list[dict[str, Json]] = []
    requirements_hold: bool | None = None
    evaluations: int | None = None
    seconds: Number | None = None
    step: dict[str, Json] | None = None
    """The delivered design's STEP file re-imported: its file, the largest hole error (mm), its holes."""
    tracking: dict[str, Json] | None = None
    """The closed loop of the original, the move-only optimum and the delivered design in the same paired runs
    (``study.added_design.tracking_summary``): the mode, ``verdicts`` per comparison ("added_vs_original",
    "move_only_vs_original", "added_vs_move_only") and estimator, per design the mean RMS errors."""
    delivered: dict[str, Json] | None = None
    """Present when the added design is the delivered one (k ≥ 1): its files and the move-only optimum's."""
    move_only: dict[str, Json] | None = None
    """The move-only optimum when the added design is delivered: its holes, objectives, combined value,
    variables, requirement checks (B-rep and ``move_only.step``) and predicted error."""
