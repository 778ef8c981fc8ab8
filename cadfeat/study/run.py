"""Run a redesign study end to end (docs/design.md "Data flow") and score designs without optimising.

``run_study(study)``:

1. ``load_study`` — validate everything before any work (``StudyError``);
2. set up: part (script or STEP), camera, trajectory, part pose, design space, feature model
   (``cadfeat.study.setup``); integer parameters are enumerated, one continuous optimisation per combination;
3. optimise on features (``optimize.optimise``; with the CAD trust-region loop ``solve_with_cad`` when the
   design map is not linear); Ctrl-C keeps the best design so far (``interrupted: true``);
4. rebuild the optimum in CAD, re-extract its holes (the answer is the real CAD model, never the surrogate),
   score it, check every kept requirement on the B-rep (``verify_on_brep``);
5. in a staged folder (``export.staged_output``): ``original.step``, ``optimised.step``, ``optimised.stl``;
   re-import ``optimised.step``, match its holes to the design to 1e-6 mm (``verify_step_roundtrip``) and
   check every kept requirement again on the re-imported solid; the report's renders while the closed-loop
   check's workers track both designs (``study.closed_loop_check``); ``results.json``; the report
   (``cadfeat.report.build_report``); then publish the folder.

Nothing is written if validation, the CAD rebuild or a verification fails, or if the run is interrupted
before the optimiser found a design; the input part file is only read.
"""

from __future__ import annotations

import contextlib
import io
import shutil
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np

from cadfeat import measures, report
from cadfeat._version import __version__
from cadfeat.cad.features import holes_to_arrays
from cadfeat.cad.features.identity import hole_names
from cadfeat.cad.parts import load_part
from cadfeat.cad.sandbox import start_workers
from cadfeat.cad.step_parts import load_step
from cadfeat.design.objectives import objective_values
from cadfeat.design.unseen import scored_measures
from cadfeat.errors import CadfeatError
from cadfeat.output_folder import staged_output
from cadfeat.poses import cam_from_part
from cadfeat.report.holes import write_holes_csv
from cadfeat.report.verdict import verdict_json
from cadfeat.results import JsonDict, ObjectivesData, ResultsData, StudyResults
from cadfeat.study import added_design, added_targets, closed_loop_check
from cadfeat.study.interrupts import RunInterrupts
from cadfeat.study.outputs import (
    SCHEMA_VERSION,
    file_entry,
    hole_dict,
    measures_summary,
    now_iso,
    plain,
    versions,
    write_results,
)
from cadfeat.study.pipeline import (
    compute,
    half_image,
    measure_holes,
    part_points,
    preflight_setup,
    scored_mask,
    trajectory_info,
)
from cadfeat.study.pose_accuracy import part_mesh, pose_accuracy, with_pose
from cadfeat.study.preflight import preflight
from cadfeat.study.progress import StudyProgress
from cadfeat.study.schema import StudyConfig, StudyError, StudySource, load_study
from cadfeat.study.setup import load_scene, occlusion_mesh, score_rule
from cadfeat.study.setup_cache import SetupCache, cached_setup, open_cache, save
from cadfeat.study.trust import objective_changes
from cadfeat.study.verify import (
    export_and_verify,
)

if TYPE_CHECKING:  # pragma: no cover
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.design.problem import Problem
    from cadfeat.measures.evaluate import Measures
    from cadfeat.study.delivery import Delivery
    from cadfeat.study.preflight import Preflight
    from cadfeat.trajectory import Trajectory

__all__ = ["EXPORTS_DIR", "StudyResult", "evaluate_study", "run_study"]

EXPORTS_DIR = Path("exports")
"""Default parent of a study's output folder: ``exports/<study name>/`` (relative to the current folder)."""
OUTPUT_FILES = ("original.step", "optimised.step", "optimised.stl", "holes.csv", "results.json", "move_only.step")


@dataclass(frozen=True)
class StudyResult:
    """Where a study wrote its outputs and the results (the content of results.json)."""

    out_dir: Path | None
    results: ResultsData

    @property
    def typed(self) -> StudyResults:
        """The results as the typed model (``cadfeat.results.StudyResults``), as results.json holds them."""
        return StudyResults.from_data(plain(self.results))

    def summary(self) -> str:
        """A short human-readable before/after summary."""
        return summarise(self.results, self.out_dir)


def _table(value: object) -> Mapping[str, object]:
    """``value`` as a JSON object (an empty one when it is none)."""
    return cast("Mapping[str, object]", value) if isinstance(value, Mapping) else {}


def summarise(results: ResultsData, out_dir: Path | None) -> str:
    obj = results["objectives"]
    lines = [f"study {results['study']['name']}" + (" (INTERRUPTED: best design so far)"
                                                     if results.get("interrupted") else "")]
    for v in results.get("variables", []):
        lines.append(f"  {v['name']:<16} {_num(v['before']):>10} -> {_num(v['after']):>10} {v['unit']}")
    units = {c["name"]: c.get("unit", "") for c in obj.get("changes", [])}
    after = obj.get("after") or {}
    for name in obj["names"]:
        lines.append(f"  {name:<16} {_num(obj['before'].get(name)):>10} -> {_num(after.get(name)):>10}"
                     f"  {units.get(name, '')}")
    lines.append(f"  {'combined':<16} {_num(obj.get('combined_before')):>10} -> "
                 f"{_num(obj.get('combined_after')):>10}  ({obj['combine']}, larger is better)")
    if limiting := obj.get("limiting"):
        lines.append(f"  limiting objective: {limiting} (before: {obj.get('limiting_before')})")
    if obj.get("score"):
        lines.append(f"  scored holes: {obj['score']}")
    for w in obj.get("warnings", []) + list(results.get("warnings", [])):
        lines.append(f"  WARNING: {w}")
    assumptions = _table(results.get("preflight")).get("assumptions", [])
    for a in cast("list[object]", assumptions) if isinstance(assumptions, list) else []:
        lines.append(f"  ASSUMED: {a}")
    lines += closed_loop_check.summary_lines(results)
    constraints = results.get("constraints", [])
    failed = [c for c in constraints if not c["ok"]]
    verdict = results.get("verdict")
    lines.append(f"  kept requirements: {len(constraints) - len(failed)} of {len(constraints)} "
                 "hold (B-rep and re-imported STEP)")
    if verdict:
        lines.append(f"  verdict: {verdict['decision']}" + "".join(
            f"\n    {f['rule']}: {f['outcome']} ({f['detail']})" for f in verdict["findings"]
            if f["outcome"] != "adopt"))
    added = results.get("added_targets")
    if added is not None and added.get("delivered"):
        names = ", ".join(str(h["name"]) for h in added["holes"])
        p = added["predicted"]
        lines.append(f"  delivered: the move-only optimum with {added['recommended']} added target hole(s) ({names}); "
                     "predicted RMS pose error (mm) original {0} -> move-only {1} -> delivered {2}".format(
                         *(_num((p.get(k) or {}).get("error_mm")) for k in ("original", "move_only", "added"))))
    if out_dir is not None:
        lines.append(f"  outputs: {out_dir}")
        for name in ("optimised.step", "optimised.stl", "move_only.step", "report.html"):
            if (out_dir / name).exists():
                lines.append(f"    {out_dir / name}")
    return "\n".join(lines)


def _num(x: float | None) -> str:
    if x is None:
        return "-"
    if isinstance(x, int):
        return str(x)
    return f"{x:.6g}"


# ------------------------------------------------------------------------------------------ run
def _resolve(path_or_dict: StudySource | StudyConfig, seed: int | None) -> StudyConfig:
    config = path_or_dict if isinstance(path_or_dict, StudyConfig) else load_study(path_or_dict)
    return config.with_seed(seed) if seed is not None else config


def default_out_dir(config: StudyConfig) -> Path:
    return EXPORTS_DIR / config.study.name


def run_study(path_or_dict: StudySource | StudyConfig, out_dir: str | Path | None = None, *, seed: int | None = None,
              quiet: bool = False, progress: bool = True, force: bool = False, track: str | None = None,
              cache: bool | None = None) -> StudyResult:
    """Run a study (a TOML path, a dict or a ``StudyConfig``) and write its outputs to ``out_dir``
    (default ``exports/<study name>/``): original.step, optimised.step, optimised.stl, results.json and the
    report. ``seed`` overrides the study's seeds. Raises ``CadfeatError`` (nothing written) on bad input or a
    failed verification; ``KeyboardInterrupt`` before the optimiser found a design also writes nothing.

    The output folder is checked before any work (``cadfeat.output_folder``): a non-empty folder cadfeat
    did not create is refused unless ``force`` (then cadfeat's files are added, other files untouched).
    ``track``: the closed-loop check's mode, fast | full | off (default: the study's; ``study.closed_loop_check``).
    Every part-script import and CAD build runs in a worker process within ``[study] build_timeout_s``.
    ``cache``: the set-up cache (``study.setup_cache``: the set-up of unchanged inputs is read from it); None: on
    unless ``CADFEAT_CACHE=off``.
    """

    config = closed_loop_check.with_mode(_resolve(path_or_dict, seed), track)
    out = out_dir if out_dir is not None else default_out_dir(config)
    start_workers()  # (CadQuery loads in the worker server meanwhile)
    interrupts = RunInterrupts()  # Ctrl-C keeps the best design so far (study.interrupts)
    with interrupts.installed(), staged_output(out, force) as stage, \
            StudyProgress(config.study.name, enabled=progress and not quiet, interrupts=interrupts) as prog:
        results, delivery = compute(config, prog, config.study.build_timeout_s, open_cache(cache))
        try:
            with prog.phase("export"):
                _write_outputs(config, stage, results, delivery, prog)
        finally:  # the closed loop's workers (``closed_loop_check.start_design``), if not collected
            delivery.workers.cancel()
    return StudyResult(Path(out), results)


def preflight_study(path_or_dict: StudySource | StudyConfig, time_limit_s: float | None = None) -> Preflight:
    """The pre-flight of a study on its part as it is (``cadfeat validate``): every hole counts as scored
    (which holes the design moves needs the design map, which ``run`` builds). ``time_limit_s``: the part's
    import and build in a worker process within it; None: in this process."""
    config = _resolve(path_or_dict, None)
    camera, traj, T_task_part = load_scene(config)
    shape, holes, _, names = _current_design(config, time_limit_s)
    added = None
    if config.add_targets is not None:  # issue 31: faces, keep-in, drill, count, a site, a dry run: before any work
        added = _preflight_added(config, shape, holes, traj, T_task_part, time_limit_s)
    mesh = occlusion_mesh(config, shape)
    o = config.objective
    T_cam_part = cam_from_part(traj.T_task_cam, T_task_part)
    m = measures.evaluate(camera, T_cam_part, traj.velocity_screws(), *holes_to_arrays(list(holes)),
                          min_axis_px=o.min_axis_px, rotation_length_mm=o.rotation_length_mm, occlusion_mesh=mesh)
    m = scored_measures(m, camera, o.min_axis_px)  # as the objectives score them (``design.unseen``)
    pre = preflight(config, camera, traj, T_task_part, part_points(shape, mesh), m, np.ones(len(holes), bool), names)
    if added is not None:
        pre.numbers["add_targets"] = added
    return pre


def _preflight_added(config: StudyConfig, shape: Shape, holes: list[Hole], traj: Trajectory, T_task_part: np.ndarray,
                     time_limit_s: float | None) -> JsonDict:
    """``added_targets.preflight_part`` on the part as it is, its holes extracted with the study's view (the
    through holes' entrance as ``run`` extracts them; names kept): {"faces", "sites", "most_that_fit"}."""
    from cadfeat.study.setup import study_view_direction
    from cadfeat.study.verify import extract_viewed, pair_by_axis

    part = load_part(config.study.part_path, time_limit_s) if config.study.part_kind == "script" else None
    view = study_view_direction(config, shape, traj, T_task_part, part)
    viewed = pair_by_axis(holes, extract_viewed(shape, view), f"{config.label}: the part's holes")
    return added_targets.preflight_part(config, shape, viewed, view)


def _write_outputs(config: StudyConfig, stage: Path, results: ResultsData, delivery: Delivery,
                   prog: StudyProgress) -> None:
    """Write and verify the outputs into the staging folder ``stage`` (published by the caller). The report's
    renders are made before the closed-loop check collects its workers' tracking (they run meanwhile)."""
    t0 = time.perf_counter()
    added = added_design.delivered(delivery)  # issue 31: the delivered design has added target holes
    results["constraints"], results["verification"] = export_and_verify(
        config, stage, delivery, results.get("constraints", []),
        step_checks=added_design.step_checks(config, delivery, f"{config.label}: optimised.step") if added else None)
    added_design.export_move_only(config, stage, results, delivery)  # issue 31: move_only.step beside it, verified
    write_holes_csv(stage / "holes.csv", plain(results))
    results["files"] = [file_entry(stage / n, stage) for n in ("original.step", "optimised.step", "optimised.stl",
                                                                 "holes.csv", added_design.MOVE_ONLY_STEP)
                        if (stage / n).exists()]
    results["timings_s"] = {**prog.timings, "export": time.perf_counter() - t0}
    results["versions"] = versions()
    finish_report = _report(stage, results, _report_context(delivery), prog)
    _closed_loop(config, results, delivery, stage, prog)  # the closed loop confirms (issue 17)
    added_design.tracking_summary(results)  # issue 31: the three designs' closed loop, summed up
    results["interrupted"] = bool(results.get("interrupted") or prog.interrupts.requested)
    results["verdict"] = verdict_json(plain(results))
    write_results(stage / "results.json", results)
    if finish_report is not None:
        finish_report(results)


def _closed_loop(config: StudyConfig, results: ResultsData, delivery: Delivery, stage: Path,
                 prog: StudyProgress) -> None:
    """The closed-loop check (``closed_loop_check.attach``); skipped — its workers stopped, whatever it had written
    into the stage removed, a warning saying so — when the run is interrupted before or during it
    (``study.interrupts``: the run finishes with the design found)."""
    try:
        with prog.interrupts.skippable():
            closed_loop_check.attach(config, results, delivery, stage, prog)
    except KeyboardInterrupt:
        from cadfeat.study.physical_views import FOLDER as VIEWS  # lazy: Mitsuba

        delivery.workers.cancel()
        for key in ("tracking", "physical_views"):
            results.pop(key, None)
        for name in ("tracking", VIEWS):  # (the frames and views drawn so far: no half-written folder)
            if (stage / name).is_dir():
                shutil.rmtree(stage / name)
        results["warnings"].append(
            f"{closed_loop_check.SKIPPED}: the run was interrupted (`cadfeat track` on this study confirms the "
            "design in the closed loop)")


def _report(stage: Path, results: Mapping[str, object], context: report.ReportContext, prog: StudyProgress
            ) -> Callable[[Mapping[str, object]], None]:
    """The report's renders now (they need the designs and their measures, not the closed loop, whose workers
    run meanwhile); returns what writes the report from the final results (``report.build_report``)."""
    with prog.phase("report"):
        renders = report.report_renders(stage, plain(results), context)

    def finish(final: Mapping[str, object]) -> None:
        with prog.phase("report"):
            report.build_report(stage, plain(final), context, renders=renders)
    return finish


def _report_context(delivery: Delivery) -> report.ReportContext:
    """The report's designs, camera and trajectory (camera views at each hole's worst pose, its default)."""
    setup = delivery.setup
    return report.ReportContext(
        shape_before=delivery.shape0, shape_after=delivery.shape1, holes_before=delivery.holes0,
        holes_after=delivery.holes1, fixed_mask=np.asarray(setup.fixed_mask, bool), camera=setup.camera,
        trajectory=setup.trajectory, T_task_part=setup.T_task_part)


# ------------------------------------------------------------------------------------------ evaluate
def evaluate_study(path_or_dict: StudySource | StudyConfig, out_dir: str | Path | None = None, *,
                   pose: int | None = None, quiet: bool = True, echo: bool = False, seed: int | None = None,
                   force: bool = False, cache: bool | None = None) -> JsonDict:
    """Score the study's current design without optimising (the thesis GUI's single-pose mode when ``pose``
    is given: one trajectory sample). Returns the results dict; prints the per-feature table (thesis
    Table 5.1: FOV, focus, resolution margins, visibility, worst pose) and a per-pose summary when ``echo``;
    writes results.json (+ report) into ``out_dir`` if given (checked before any work, as by ``run_study``;
    ``force``: add the files to a folder cadfeat did not create; ``cache``: as ``run_study``'s)."""

    config = _resolve(path_or_dict, seed)
    with contextlib.ExitStack() as stack:
        stage = stack.enter_context(staged_output(out_dir, force)) if out_dir is not None else None
        start_workers()
        results = _evaluate(config, stage, pose, quiet, echo, open_cache(cache))
    return results


def _evaluate(config: StudyConfig, stage: Path | None, pose: int | None, quiet: bool, echo: bool,
              cache: SetupCache | None = None) -> JsonDict:
    with StudyProgress(config.study.name, enabled=not quiet) as prog:
        with prog.phase("setup"):
            camera, traj, T_task_part = load_scene(config)
            if pose is not None and not 0 <= pose < len(traj):
                raise StudyError(f"{config.label}: --pose {pose}: allowed: 0..{len(traj) - 1} "
                                 f"(the trajectory has {len(traj)} samples)")
            # the same holes, names, scored holes and occlusion mesh as ``run``
            setup = cached_setup(config, time_limit_s=config.study.build_timeout_s, cache=cache)
            holes, fixed, names = setup.holes0, setup.fixed_mask, setup.hole_names
        full_traj = traj
        if pose is not None:
            traj = _single_pose(traj, pose)
        with prog.phase("measures"):
            m = measure_holes(setup, holes, traj)
            if "pose" in config.objective.measures:  # g_POSE: the holes' pose information at these poses

                m = with_pose(setup, holes, traj, m)
            values = _plain_objectives(config, m, setup.problem)
            pre = preflight_setup(config, setup, m if pose is None else measure_holes(setup, holes, full_traj))
            trust = objective_changes(setup.problem, values, None) if pose is None else None
            combined = float(setup.problem.combined_from(np.array([values[n] for n in setup.problem.names]))) \
                if pose is None and config.objective.combine != "pareto" else None
            save(setup)  # (its normaliser built above, when the evaluation needs one)
        summary = measures_summary(m, names, traj.times_s, config.objective.min_axis_px, half_image(camera))
        pose_block = None
        if pose is None:  # the predicted pose error of the design as it is (``study.pose_accuracy``)

            mesh = setup.problem.occlusion_mesh  # (a cached set-up's solid is loaded only without one)
            pose_block = pose_accuracy(config, setup, holes, mesh if mesh is not None else part_mesh(config,
                                                                                                    setup.shape0))
        if pose is not None:  # pose indices of the full trajectory
            for f in summary["per_feature"]:
                f["worst_pose"] = pose
        o = config.objective
        score, occlusion = score_rule(config, holes, scored_mask(setup)), bool(o.occlusion)
        objectives: ObjectivesData = {
            "names": list(values), "combine": o.combine, "aggregate": o.aggregate, "before": values,
            "combined_before": combined, "score": score, "occlusion": occlusion} if trust is None else {
            "names": list(values), "combine": o.combine, "aggregate": o.aggregate, "before": values,
            "combined_before": combined, **trust, "score": score, "occlusion": occlusion}
        results: ResultsData = {
            "schema_version": SCHEMA_VERSION, "cadfeat_version": __version__, "created": now_iso(),
            "evaluation_only": True,
            "study": {"name": config.study.name, "file": str(config.file) if config.file else None,
                      "part": config.study.part, "part_kind": config.study.part_kind, "seed": config.study.seed,
                      "description": config.study.description},
            "inputs": config.to_dict(), "camera": camera.to_dict(),
            "trajectory": {**trajectory_info(traj), "kind": config.trajectory.table.get("kind", "csv"),
                           "pose": pose},
            "holes": {"before": [hole_dict(h, i, fixed[i], setup.movable_mask[i]) for i, h in enumerate(holes)]},
            "objectives": objectives,
            "measures": {"before": summary}, "timings_s": dict(prog.timings), "versions": versions(),
            "preflight": pre.to_dict(), "warnings": list(pre.warnings),
        }
        if pose_block is not None:
            results["pose_accuracy"] = pose_block
    if echo:
        print(format_table(results, pose))
    if stage is not None:
        write_results(stage / "results.json", results)
        same: ResultsData = {**results,
                             "holes": {"before": results["holes"]["before"], "after": results["holes"]["before"]},
                             "measures": {"before": summary, "after": summary},
                             "objectives": {**objectives, "after": values}}
        context = report.ReportContext(shape_before=setup.shape0, shape_after=setup.shape0, holes_before=holes,
                                       holes_after=holes, fixed_mask=np.asarray(fixed, bool), camera=camera,
                                       trajectory=full_traj, T_task_part=T_task_part)
        finish_report = _report(stage, same, context, prog)
        if finish_report is not None:
            finish_report(same)
    return plain(results)


def _current_design(config: StudyConfig, time_limit_s: float | None
                    ) -> tuple[Shape, list[Hole], np.ndarray, list[str]]:
    """The part as it is (defaults / the STEP file): solid, holes, fixed mask (STEP: holes not in the design;
    scripts: the holes the script declares functional)."""
    if config.study.part_kind == "step":
        step = load_step(config.study.part_path)
        holes = list(step.holes)
        fixed = np.ones(len(holes), bool)
        for h in config.design.holes:
            with contextlib.suppress(CadfeatError):
                fixed[holes.index(step.select(list(h.select) if isinstance(h.select, tuple) else h.select))] = False
        return step.shape, holes, fixed, [h.name for h in holes]
    part = load_part(config.study.part_path, time_limit_s)
    shape = part.build()
    holes = part.holes()
    fixed = np.asarray(part.fixed_mask(holes), bool)
    return shape, holes, fixed, hole_names(holes)


def _single_pose(traj: Trajectory, k: int) -> _OnePose:
    """A one-sample view of a trajectory at sample ``k`` (with the full trajectory's velocity screw there)."""
    return _OnePose(traj, k)


class _OnePose:
    """A trajectory view with exactly one sample (``len == 1``), for single-pose evaluation."""

    def __init__(self, traj: Trajectory, k: int) -> None:
        self.T_task_cam = np.asarray(traj.T_task_cam)[k:k + 1]
        self.times_s = np.asarray(traj.times_s)[k:k + 1]
        self._screws = np.asarray(traj.velocity_screws())[k:k + 1]
        self.name = getattr(traj, "name", "")
        self.duration_s = 0.0

    def __len__(self) -> int:
        return 1

    def velocity_screws(self) -> np.ndarray:
        return self._screws


def _plain_objectives(config: StudyConfig, m: Measures, problem: Problem) -> dict[str, float]:
    """The aggregated objectives of measures ``m`` exactly as the optimiser scores them (the problem's scored
    holes ``feature_mask`` and natural units for the smooth min)."""
    return objective_values(m, config.objective, problem.units, problem.feature_mask)


def format_table(results: ResultsData, pose: int | None = None) -> str:
    """The per-feature table of thesis Table 5.1 (margins: positive = satisfied) and a per-pose summary."""
    from rich.console import Console
    from rich.table import Table

    m = results["measures"]["before"]
    where = f"pose {pose}" if pose is not None else f"{results['trajectory']['n_samples']} poses (minimum over them)"
    table = Table(title=f"{results['study']['name']}: measures per feature, {where}")
    for col in ("feature", "FOV cone", "FOV px", "focus", "resolution px", "visible", "worst pose"):
        table.add_column(col, justify="right" if col != "feature" else "left")
    for f in m["per_feature"]:
        table.add_row(f["name"], _num(f["fov_min"]), _num(f["fov_px_min"]), _num(f["focus_min"]),
                      _num(f["resolution_px_min"]), f"{100 * (f['visible_frac'] or 0.0):.0f}%", str(f["worst_pose"]))
    pp = m["per_pose"]
    res = np.asarray([np.nan if v is None else v for v in pp["resolvability"]], float)
    cond = np.asarray([np.inf if v is None else v for v in pp["condition"]], float)
    buffer = io.StringIO()
    console = Console(file=buffer, width=110, force_terminal=False, color_system=None)
    console.print(table)
    console.print(f"resolvability Λ (px/mm): min {np.nanmin(res):.6g}, mean {np.nanmean(res):.6g}; "
                  f"Jacobian condition: max {np.max(cond):.6g}; poses with < 3 visible features: "
                  f"{int(np.sum(np.asarray(pp['visible']) < 3))}")
    for name, g in results["objectives"]["before"].items():
        how = (_table(results["inputs"].get("objective")).get("pose_aggregate", "rms") if name == "g_POSE"
               else results["objectives"]["aggregate"])  # g_POSE: pose_aggregate (predicted error, mm)
        console.print(f"{name} = {_num(g)} ({how} over the trajectory)")
    return buffer.getvalue().rstrip()
