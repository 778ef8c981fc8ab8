"""The recommended added-hole design as the study's answer (``[add_targets]``, issue 31).

When the added-target phase (``study.added_targets``) recommends k ≥ 1 new holes, the design cadfeat delivers is
the move-only optimum — or its rebuild at the jointly refined design — with those holes drilled. It is a
first-class output, as a move-only optimum is without ``[add_targets]``:

- ``optimised.step`` / ``optimised.stl`` hold it (verified as every delivered design is: a valid solid, the
  re-imported STEP's holes equal to the design's within 1e-6 mm, and here also every added hole found where it
  was put and every old hole unchanged — ``cad.drill_targets.verify_drilled`` — and every kept requirement on the
  re-imported solid); ``move_only.step`` holds the move-only optimum beside it, verified the same way;
- results.json's sections of the design "after" describe it: ``holes.after`` (the part's holes in their order,
  then the added ones with ``"added": true``), ``measures.after``, ``objectives.after`` / ``combined_after`` (the
  aggregated objectives of its measures, as ``cadfeat evaluate`` scores a design: ``deliver``), ``constraints``
  (every kept requirement on its B-rep, then on the re-imported ``optimised.step``), ``pose_accuracy.after``,
  the variables' ``after`` (the refined values when the refinement moved them) and ``patterns``; the move-only
  optimum's are kept in ``added_targets.move_only``;
- ``holes.csv`` and the report's hole table list every hole of it, the added ones "added";
- the closed-loop check tracks the original, the move-only optimum and this design in the same paired runs
  (``closed_loop_check.ADDED_PAIRS``): its verdicts — this design against the original — are the verdict's
  decisive tracking rule, and ``added_targets.tracking`` sums up the three comparisons;
- the verdict (``report.verdict``) judges it.

With k = 0 the move-only optimum is delivered and nothing here applies. Units: mm.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.cad.features.identity import hole_names
from cadfeat.study.added_targets import as_added, brep_checks
from cadfeat.study.delivery import AddedDesign, Delivery, MoveOnly
from cadfeat.study.outputs import hole_dict, measures_summary, normalise_step_header

if TYPE_CHECKING:  # pragma: no cover
    import trimesh
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.measures.evaluate import Measures
    from cadfeat.results import HoleData, JsonDict, RequirementData, ResultsData
    from cadfeat.study.schema import StudyConfig
    from cadfeat.study.setup import StudySetup

__all__ = ["MOVE_ONLY_STEP", "delivered", "deliver", "export_move_only", "step_checks", "tracking_summary"]

MOVE_ONLY_STEP = "move_only.step"
"""The move-only optimum's STEP file in the output folder when the delivered design has added holes."""


def delivered(delivery: Delivery) -> bool:
    """True when the delivered design (``delivery.shape1``) is the move-only optimum with added holes."""
    return delivery.move_only is not None


def _hole_records(setup: StudySetup, holes: Sequence[Hole], n_old: int) -> list[HoleData]:
    """results.json ``holes.after`` of the delivered design: the part's holes as the set-up marks them, then the
    added ones (neither fixed nor movable: new, ``"added": true``)."""
    out: list[HoleData] = []
    for i, h in enumerate(holes):
        if i < n_old:
            out.append(hole_dict(h, i, bool(setup.fixed_mask[i]), bool(setup.movable_mask[i])))
        else:
            out.append({**hole_dict(h, i, False, False), "added": True})
    return out


def _objectives(config: StudyConfig, setup: StudySetup, holes: Sequence[Hole], measured: Measures,
                mesh: trimesh.Trimesh) -> tuple[dict[str, float], float | None]:
    """The study's aggregated objectives of a design with any number of holes and their combined value: its
    measures ``measured`` (with its pose information for g_POSE, rims tested against its own ``mesh``), every
    hole scored (the added ones too), normalised as the optimiser normalises (``Problem.combined_from``)."""
    from cadfeat.design.objectives import objective_values
    from cadfeat.study.pose_accuracy import with_pose

    problem = setup.problem
    if "pose" in config.objective.measures:
        measured = with_pose(setup, holes, setup.trajectory, measured, mesh)
    mask = np.asarray(getattr(problem, "feature_mask", None) if getattr(problem, "feature_mask", None) is not None
                      else np.ones(len(setup.holes0), bool), bool)
    mask = np.concatenate([mask, np.ones(len(holes) - len(mask), bool)])
    values = objective_values(measured, config.objective, problem.units, mask)
    values = {n: float(values[n]) for n in problem.names}
    if config.objective.combine == "pareto":
        return values, None
    return values, float(problem.combined_from(np.array([values[n] for n in problem.names], float)))


def deliver(config: StudyConfig, setup: StudySetup, base: StudySetup, results: ResultsData, delivery: Delivery,
            added: AddedDesign, measure: Callable[[Sequence[Hole], Shape], Measures],
            patterns: Callable[[Sequence[Hole]], list[JsonDict]]) -> Delivery:
    """Make the added design (``added``: ``added_targets.run_phase``'s) the delivered one: ``results``'
    after-sections describe it (module docstring; the move-only optimum's go to ``added_targets.move_only``);
    returns ``delivery`` with it as ``shape1``/``holes1``, the move-only optimum as ``move_only`` and the number
    of the part's holes ``n_old``. ``measure(holes, shape)``: the study's measures of a design's holes
    along its trajectory, occlusion by that design's solid (``pipeline.measure_holes``); ``patterns``: the
    original's patterns checked on the part's holes."""
    from cadfeat.study.pose_accuracy import part_mesh, pose_accuracy
    from cadfeat.study.trust import objective_changes

    shape2, holes2, n_old = added.shape, list(added.holes), int(added.n_old)
    block, variables = results.get("added_targets"), results.get("variables")
    constraints, holes_after = results.get("constraints"), results["holes"].get("after")
    assert block is not None and variables is not None and constraints is not None and holes_after is not None, \
        "a run's results (pipeline.compute) with the added-target phase's block"
    obj = results["objectives"]
    block["move_only"] = {
        "file": MOVE_ONLY_STEP, "holes": holes_after,
        "objectives": obj.get("after"), "combined": obj.get("combined_after"),
        "variables": {v["name"]: v["after"] for v in variables},
        "constraints": list(constraints),
        "predicted_error_mm": block["predicted"]["move_only"]["error_mm"]}
    mesh2 = part_mesh(config, shape2)
    m2 = measure(holes2, shape2)
    after, combined = _objectives(config, setup, holes2, m2, mesh2)
    changes = objective_changes(setup.problem, obj["before"], after)
    obj["after"], obj["combined_after"] = after, combined
    obj["limiting"], obj["changes"] = changes["limiting"], changes["changes"]
    obj["score"] += f"; after: the added target holes ({', '.join(hole_names(holes2[n_old:]))}) too"
    results["holes"]["after"] = _hole_records(setup, holes2, n_old)
    results["measures"]["after"] = measures_summary(m2, hole_names(holes2), setup.trajectory.times_s,
                                                    config.objective.min_axis_px,
                                                    0.5 * min(setup.camera.width, setup.camera.height))
    results["constraints"] = [c for c in block["constraints"] if c.get("checked_on") == "brep"]
    results["pose_accuracy"] = pose_accuracy(config, base, base.holes0,
                                             part_mesh(config, base.shape0, base.problem.occlusion_mesh), setup,
                                             holes2, mesh2)
    refinement = block.get("refinement")
    moved = (None if refinement is None else refinement.get("variables")) or {}
    for v in variables:
        if v["name"] in moved:
            v["move_only"], v["after"] = v["after"], float(moved[v["name"]])
    results["patterns"] = patterns(holes2[:n_old])
    block["delivered"] = {"design": "added", "files": ["optimised.step", "optimised.stl"],
                          "move_only_file": MOVE_ONLY_STEP}
    return dataclasses.replace(delivery, shape1=shape2, holes1=holes2,
                               move_only=MoveOnly(delivery.shape1, delivery.holes1), n_old=n_old)


def step_checks(config: StudyConfig, delivery: Delivery, label: str) -> Callable[[Shape], list[RequirementData]]:
    """What ``verify.export_and_verify`` measures on the re-imported ``optimised.step`` of the delivered added
    design: every hole found where it was put — the part's holes unchanged, each added hole at its centre, axis,
    rim radius and depth (``verify_drilled``: ``CadfeatError`` naming a missing one) — and every kept requirement
    on the re-imported solid (``added_targets.brep_checks``)."""
    from cadfeat.cad.drill_targets import verify_drilled

    setup, holes = delivery.setup, list(delivery.holes1)
    n_old = len(holes) if delivery.n_old is None else delivery.n_old

    def checks(reimported: Shape) -> list[RequirementData]:
        found = verify_drilled(reimported, holes[:n_old], [as_added(h) for h in holes[n_old:]], label=label,
                               prefer_direction=setup.view_direction)
        return brep_checks(config, setup, reimported, found, n_old, "step")
    return checks


def export_move_only(config: StudyConfig, stage: Path, results: ResultsData, delivery: Delivery) -> None:
    """Write ``move_only.step`` (the move-only optimum) and verify it as ``optimised.step`` is verified without
    added holes: the re-imported STEP's holes equal to the design's within 1e-6 mm (and its volume), every kept
    requirement on the re-imported solid (``CadfeatError`` naming a violated one). Then
    ``added_targets.constraints``/``requirements_hold``/``step`` describe the delivered design's checks (B-rep and
    re-imported ``optimised.step``) and ``added_targets.move_only`` gains its STEP checks."""
    from cadfeat.cad.export import expected_step_volume, export_step, import_step, verify_step_roundtrip
    from cadfeat.study.verify import ROUNDTRIP_TOL_MM, extract_viewed, fail_on, order_like, requirement_checks

    block = results.get("added_targets")
    move_only = delivery.move_only
    if block is None or move_only is None:
        return
    setup, shape, holes = delivery.setup, move_only.shape, move_only.holes
    path = stage / MOVE_ONLY_STEP
    export_step(shape, path)
    normalise_step_header(path, f"{config.study.name} move_only")
    view = setup.view_direction
    volume, uncertainty = expected_step_volume(shape, delivery.shape0, stage / "original.step")
    trip = verify_step_roundtrip(path, extract_viewed(shape, view), tol_mm=ROUNDTRIP_TOL_MM,
                                 expected_volume_mm3=volume, volume_rtol=1e-7, prefer_direction=view,
                                 volume_uncertainty_mm3=uncertainty)
    reimported = import_step(path)
    step_holes = order_like(holes, setup.rebuild_holes(reimported), 1e-3, f"re-imported {MOVE_ONLY_STEP}")
    checks = requirement_checks(setup, reimported, step_holes, "step")
    fail_on(checks, f"{config.label}: {MOVE_ONLY_STEP}")
    move = block.get("move_only")
    if move is None:
        return
    move["constraints"] = list(move["constraints"]) + checks
    move["step"] = {"file": MOVE_ONLY_STEP, "max_error_mm": max(trip.max_centre_error_mm, trip.max_radius_error_mm,
                                                                trip.max_depth_error_mm), "holes": trip.n_holes}
    block["constraints"] = list(results.get("constraints", []))
    block["requirements_hold"] = all(bool(c["ok"]) for c in block["constraints"])
    ver = results.get("verification")
    block["step"] = {"file": "optimised.step",
                     "max_error_mm": None if ver is None else ver.get("step_roundtrip_max_error_mm"),
                     "holes": len(delivery.holes1), "added_found": len(delivery.holes1) - int(delivery.n_old or 0)}


def tracking_summary(results: ResultsData) -> None:
    """``added_targets.tracking`` from the closed-loop check's section (``tracking``): the mode, per comparison
    and estimator the paired verdict — the delivered design against the original (the check's verdicts), the
    move-only optimum against the original and the delivered design against the move-only optimum — and per
    design the Monte-Carlo mean RMS errors. Nothing when the check did not run; why, when it was skipped."""
    block = results.get("added_targets")
    if block is None or "delivered" not in block:
        return
    section = results.get("tracking")
    if section is None:
        skipped = [w for w in results.get("warnings", []) if "closed-loop check skipped" in str(w)]
        block["tracking"] = {"skipped": skipped[0]} if skipped else None
        return
    verdicts = {"added_vs_original": {m: v.get("verdict") for m, v in section["verdicts"].items()}}
    for label, c in section.get("comparisons", {}).items():
        verdicts[label] = {m: v.get("verdict") for m, v in c["verdicts"].items()}
    names = {"before": "original", "move_only": "move_only", "after": "added"}
    check = section.get("check")
    block["tracking"] = {
        "mode": None if check is None else check["mode"], "runs": section["settings"]["runs"],
        "verdicts": verdicts,
        "designs": {names[d]: {m: {"trans_mm_rms": e.get("trans_mm_rms"), "rot_deg_rms": e.get("rot_deg_rms")}
                               for m, e in v["estimators"].items()}
                    for d, v in section["designs"].items() if d in names}}

