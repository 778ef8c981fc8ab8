"""The phases of a study run: set up, optimise, deliver (shop rounding and CAD rebuild), analyse, and the
results they give (``compute``).

``compute(config, progress)`` returns the results.json content (before export) and the designs the export, the
report and the closed-loop check need (``delivery.Delivery``); ``cadfeat.study.run`` stages, exports
(``cadfeat.study.verify``) and publishes. Each phase is a function of its own below, in run order.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, ParamSpec, Protocol, TypeAlias, TypeVar, cast

import numpy as np

from cadfeat import measures
from cadfeat._version import __version__
from cadfeat.cad.export import mesh_from_shape
from cadfeat.cad.features import holes_to_arrays
from cadfeat.cad.features.identity import hole_names
from cadfeat.design import optimize  # (called through the module: tests replace its functions)
from cadfeat.design.memory import check_fits
from cadfeat.design.patterns import check_patterns, find_patterns
from cadfeat.design.robustness import robustness
from cadfeat.design.shop import ShopDesign, hole_sizes, refine_on_rebuild, shop_design
from cadfeat.design.unseen import scored_measures
from cadfeat.errors import CadfeatError
from cadfeat.poses import cam_from_part
from cadfeat.results import (
    AddedTargetsData,
    HistoryPointData,
    HolesData,
    JsonDict,
    RequirementData,
    ResultsData,
    ShopData,
    VariableData,
)
from cadfeat.study import added_design, added_targets, closed_loop_check
from cadfeat.study import setup as study_setup  # (called through the module: tests replace setup_*)
from cadfeat.study.delivery import AddedDesign, Delivery, TrackingWorkers
from cadfeat.study.interrupts import RunInterrupts
from cadfeat.study.outputs import (
    SCHEMA_VERSION,
    hole_dict,
    measures_summary,
    now_iso,
)
from cadfeat.study.pose_accuracy import part_mesh, pose_accuracy
from cadfeat.study.preflight import preflight
from cadfeat.study.progress import StudyProgress
from cadfeat.study.robust_study import attach_robust, check_robust, robust_designs, robust_phase
from cadfeat.study.schema import StudyConfig, StudyError
from cadfeat.study.setup import int_grid, load_scene, occlusion_mesh, score_rule
from cadfeat.study.setup_cache import cached_setup, save
from cadfeat.study.trust import objective_changes
from cadfeat.study.verify import (
    AnchoredModel,
    HoleCountError,
    outlines_differ,
    rebuild,
    requirement_checks,
)

if TYPE_CHECKING:  # pragma: no cover
    import trimesh
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.camera import Camera
    from cadfeat.design.design_space import FeatureModel
    from cadfeat.design.objectives import Normaliser
    from cadfeat.design.optimize import OptimResult
    from cadfeat.design.optimize.evaluator import HistoryEntry, ParetoFront
    from cadfeat.measures.evaluate import Measures
    from cadfeat.study.preflight import Preflight
    from cadfeat.study.setup import Scene, StudySetup
    from cadfeat.study.setup_cache import SetupCache


_P = ParamSpec("_P")
_T = TypeVar("_T")

OUTLINE_ROUNDS = 4


class Samples(Protocol):
    """What the measures and results.json read of a trajectory: a ``Trajectory``, or ``cadfeat evaluate``'s view of
    one of its samples (``run._OnePose``)."""

    @property
    def T_task_cam(self) -> np.ndarray: ...
    @property
    def times_s(self) -> np.ndarray: ...
    @property
    def duration_s(self) -> float: ...

    def __len__(self) -> int: ...

    def velocity_screws(self) -> np.ndarray:
        """(L, 6) the camera's velocity screws (v mm/s, ω rad/s), camera frame."""
        ...


SWEEP_SAMPLES = 41


def measure_holes(setup: StudySetup, holes: Sequence[Hole], trajectory: Samples | None = None, *,
                  mesh: trimesh.Trimesh | None = None) -> Measures:
    """``measures.evaluate`` of real holes (part frame) along the study's trajectory (or ``trajectory``), with
    the occlusion test against ``mesh`` (default: the setup problem's part mesh, None when occlusion is off), as
    the objectives score them (``design.unseen.scored_measures``: results.json's measures, the pre-flight and the
    explorer show the values the objectives aggregate; ``measures.evaluate`` alone gives the thesis's)."""
    traj = trajectory if trajectory is not None else setup.trajectory
    o = setup.config.objective
    if mesh is None:
        mesh = getattr(getattr(setup, "problem", None), "occlusion_mesh", None)
    T_cam_part = cam_from_part(traj.T_task_cam, setup.T_task_part)
    c, a, r = holes_to_arrays(list(holes))
    m = measures.evaluate(setup.camera, T_cam_part, traj.velocity_screws(), c, a, r, min_axis_px=o.min_axis_px,
                          rotation_length_mm=o.rotation_length_mm, occlusion_mesh=mesh)
    return scored_measures(m, setup.camera, o.min_axis_px)


def score(setup: StudySetup, holes: Sequence[Hole]) -> tuple[dict[str, float], float | None]:
    """The aggregated objectives of real holes and their combined value (larger is better), computed exactly
    as the optimiser does (``Problem.features_objectives`` / ``combined_from``: same normalisation), with the
    exact occlusion ray test (the optimiser uses the part's depth maps, ``measures.depth``)."""
    problem = setup.problem
    G = problem.features_objectives(*holes_to_arrays(list(holes)), exact_occlusion=True,
                                    depth_mm=[float(h.depth_mm) for h in holes])
    values = dict(zip(problem.names, map(float, G), strict=True))
    if setup.config.objective.combine == "pareto":
        return values, None
    return values, float(problem.combined_from(G))


def _optimise(setup: StudySetup, progress: StudyProgress, label: str = "") -> tuple[OptimResult, bool]:
    """Optimise one setup; returns (OptimResult-like, interrupted)."""
    oc = setup.config.optimizer
    try:
        with progress.interrupts.keeping():  # Ctrl-C: the optimiser returns its best design so far
            if setup.linear:
                res = optimize.optimise(setup.problem, oc, progress=progress.iteration)
            else:
                res = optimize.solve_with_cad(setup.problem, cad_holes(setup), oc, progress=progress.iteration)
    except KeyboardInterrupt:
        if progress.best_x is None:
            raise
        # a stand-in with the fields the run reads of an optimiser's result
        res = cast("OptimResult", _Interrupted(progress.best_x, progress.best_f))
    if getattr(res, "interrupted", False) and not getattr(res, "history", None) and progress.best_x is None:
        raise KeyboardInterrupt  # stopped before the optimiser evaluated any design: nothing to write
    return res, bool(getattr(res, "interrupted", False))


def _with_cad(setup: StudySetup, progress: StudyProgress) -> OptimResult:
    """``solve_with_cad`` on ``setup`` (a rebuild that raises or times out is an infeasible point)."""
    return optimize.solve_with_cad(setup.problem, cad_holes(setup), setup.config.optimizer,
                                   progress=progress.iteration)


def cad_holes(setup: StudySetup) -> Callable[[np.ndarray], list[Hole]]:
    """``rebuild(x) -> holes`` of the CAD-in-the-loop search: the part rebuilt at design ``x`` and its holes
    extracted (``StudySetup.rebuild_holes``); a design whose holes differ in number from the study's (a moved hole
    broke into an edge or into another hole) raises ``HoleCountError``, an infeasible point for the optimiser."""

    def holes_at(x: np.ndarray) -> list[Hole]:
        holes = setup.rebuild_holes(setup.rebuild_shape(x))
        if len(holes) != len(setup.holes0):
            raise HoleCountError(f"CAD rebuild at {setup.space.as_dict(np.asarray(x, float))}: {len(holes)} holes "
                                 f"found, {len(setup.holes0)} designed", len(holes), len(setup.holes0))
        return holes

    return holes_at


@dataclass
class _Interrupted:
    """Stand-in result when the optimiser itself was stopped by Ctrl-C before returning."""

    x_best: np.ndarray
    f_best: float
    history: list[HistoryEntry] = dataclasses.field(default_factory=list["HistoryEntry"])
    interrupted: bool = True
    pareto: ParetoFront | None = None
    n_evals: int = 0


def _violations(setup: StudySetup, x: np.ndarray, most: int = 5) -> str:
    """The most violated 2-D constraints at ``x``: "kind (holes) by N mm", worst first."""
    C = np.asarray(setup.problem.constraints(x), float)
    labels = setup.problem.constraint_labels()
    order = [int(i) for i in np.argsort(C) if C[i] < 0][:most]
    return "; ".join(f"{labels[i][0]} ({', '.join(labels[i][1]) or '-'}) by {-C[i]:.4g}" for i in order) or \
        "(no 2-D constraint; see the optimiser's message)"


def _refresh_outlines(setup: StudySetup, res: OptimResult, scene: Scene, normaliser: Normaliser,
                      prog: StudyProgress, label: str) -> tuple[StudySetup, OptimResult, list[HistoryPointData], bool]:
    """The optimiser's 2-D constraints use the host-face outlines of the design it was linearised at; when a
    parameter also changes the faces (e.g. a block that grows with the hole spacing), rebuild at the
    optimum, linearise again there (new outlines) and re-optimise from it, until the outlines agree (at
    most ``OUTLINE_ROUNDS`` rounds; a round is kept only if it improves the objective)."""
    history: list[HistoryPointData] = []
    stopped = False
    for k in range(OUTLINE_ROUNDS):
        x = np.asarray(res.x_best, float)
        try:
            with prog.interrupts.keeping():  # Ctrl-C: the previous round's design is kept
                _, holes, _ = rebuild(setup, x)
                holes_at = getattr(setup.model, "holes_at", None)
                if not outlines_differ(holes_at(x) if holes_at is not None else setup.model.holes,
                                       holes):  # the outlines the model predicts at x (they may move with x)
                    break
                names = setup.space.names
                new = study_setup.setup_script(setup.config, setup.int_values, scene, normaliser,
                                               at=dict(zip(names, x, strict=True)), time_limit_s=setup.time_limit_s)
                res2, stopped = _optimise(new, prog, label)
        except CadfeatError:
            break
        except KeyboardInterrupt:  # keep the design of the previous round
            return setup, res, history, True
        history += _history(res2, f"{label} outlines round {k + 1}".strip())
        if float(res2.f_best) < float(res.f_best) - 1e-12:
            setup, res = new, res2
        if stopped:
            break
    return setup, res, history, stopped


def _history(res: OptimResult, label: str) -> list[HistoryPointData]:
    """results.json ``history`` of an optimiser's iterations (``OptimResult.history``), their phase after
    ``label``."""
    return [{"iteration": int(h.get("iteration", i)), "f": h["f"], "combined": h["combined"],
             "feasible": bool(h.get("feasible", True)), "phase": (label + " " if label else "")
             + str(h.get("phase", "")).strip()} for i, h in enumerate(res.history or [])]


def _sweep(setup: StudySetup) -> JsonDict | None:
    """For a one-variable study: the objectives over the variable's range (thesis Figs. 5.10/5.11)."""
    space = setup.space
    if space.size != 1:
        return None
    v = space.variables[0]
    values = np.linspace(v.lower, v.upper, SWEEP_SAMPLES)
    objectives: dict[str, list[float]] = {}
    combined: list[float] = []
    for x in values:
        obj = setup.problem.objectives(np.array([x]))
        for k, g in obj.items():
            objectives.setdefault(k, []).append(float(g))
        combined.append(-float(setup.problem.objective(np.array([x]))))
    return {"variable": v.name, "unit": v.unit, "values": values, "objectives": objectives, "combined": combined}


def _variables(setup: StudySetup, x0: np.ndarray, x1: np.ndarray, ints0: Mapping[str, int],
               ints1: Mapping[str, int]) -> list[VariableData]:
    out: list[VariableData] = []
    for v, a, b in zip(setup.space.variables, x0, x1, strict=True):
        out.append({"name": v.name, "unit": v.unit, "kind": v.kind, "lower": v.lower, "upper": v.upper,
                    "before": float(a), "after": float(b),
                    "standard_sizes": None if v.standard_sizes is None else list(v.standard_sizes)})
    specs = {p.name: p for p in setup.config.design.parameters}
    for name in ints0:
        p = specs[name]
        out.append({"name": name, "unit": p.unit, "kind": "integer", "lower": int(p.lower), "upper": int(p.upper),
                    "before": int(ints0[name]), "after": int(ints1[name]), "standard_sizes": None})
    return out


def _holes_block(setup0: StudySetup, holes0: Sequence[Hole], setup1: StudySetup,
                 holes1: Sequence[Hole]) -> HolesData:
    return {"before": [hole_dict(h, i, setup0.fixed_mask[i], setup0.movable_mask[i]) for i, h in enumerate(holes0)],
            "after": [hole_dict(h, i, setup1.fixed_mask[i], setup1.movable_mask[i]) for i, h in enumerate(holes1)]}


def _design_matrix(setup: StudySetup, x: np.ndarray) -> JsonDict | None:
    try:
        from cadfeat.design.axiomatic import design_matrix
    except ImportError:
        return None
    dm = design_matrix(setup.problem, x)
    note = getattr(dm, "note", "") or ("sensitivities of each objective and kept requirement (rows) to each group "
                                       "of design parameters (columns) at the optimum, thesis §2.2.4")
    return {"rows": list(dm.rows), "cols": list(dm.cols), "matrix": np.asarray(dm.matrix, float),
            "verdict": dm.verdict, "note": note}


def _normalisation(setup: StudySetup) -> JsonDict:
    normaliser = getattr(setup.problem, "normaliser", None)
    if normaliser is None:
        return {"method": "none", "reference": {}, "note": "objectives in their own units"}
    d = normaliser.to_dict()
    return {"method": d.get("method"), "reference": d.get("reference", {}), "note": d.get("note", ""),
            **({"sources": d["sources"]} if "sources" in d else {})}


def trajectory_info(traj: Samples) -> JsonDict:
    """Kind, sample count, duration and the sampled camera poses (``T_task_cam`` (L, 4, 4), mm; ``time_s``)."""
    table_kind = getattr(traj, "name", "") or ""
    return {"kind": table_kind, "n_samples": len(traj), "duration_s": float(traj.duration_s),
            "time_s": np.asarray(traj.times_s, float), "T_task_cam": np.asarray(traj.T_task_cam, float)}


def half_image(camera: Camera) -> float:
    return 0.5 * min(camera.width, camera.height)


@dataclass
class _Start:
    """What the set-up phase gives: the base set-up (the part as it is), every set-up to optimise (one per
    integer combination), the measures, pre-flight and objectives of the design before."""

    scene: Scene
    base: StudySetup
    setups: list[StudySetup]
    m0: Measures
    pre: Preflight
    obj0: dict[str, float]
    comb0: float | None


@dataclass
class _Optimum:
    """What the optimise phase gives: the best set-up and its optimiser result, the history, interrupted?"""

    setup: StudySetup
    res: OptimResult
    history: list[HistoryPointData]
    interrupted: bool


@dataclass
class _Delivered:
    """The delivered design: variables ``x1``, its CAD rebuild (shape, holes, prediction error), the shop block
    and the model's rebuild failure at its optimum (if the CAD-in-the-loop search had to take over)."""

    x1: np.ndarray
    shape1: Shape
    holes1: list[Hole]
    pred_err: float
    shop: ShopData
    res: OptimResult
    rebuild_failure: str | None


def compute(config: StudyConfig, prog: StudyProgress, time_limit_s: float | None = None,
            cache: SetupCache | None = None) -> tuple[ResultsData, Delivery]:
    """The study's phases in order: set up, optimise, deliver (shop rounding, CAD rebuild, scores and
    requirement checks on the B-rep), analyse; returns (results, the designs for the export, the report and the
    closed-loop check).
    ``time_limit_s``: every part-script import and CAD build in a worker process within it (``run_study``:
    ``[study] build_timeout_s``); None: in this process. ``cache``: the set-up cache (``study.setup_cache``)."""
    check_robust(config)  # issue 18: a chance constraint names a measure of the study, before any work
    with prog.phase("setup"):
        start = _set_up(config, time_limit_s, cache)
    base = start.base  # issue 17: the closed-loop check tracks the original on another core meanwhile
    workers = TrackingWorkers(before=closed_loop_check.start_design(
        config, "before", base.shape0, base.holes0, len(base.trajectory.times_s)))
    try:
        return _after_set_up(config, prog, start, workers)
    except BaseException:
        workers.cancel()
        raise


def _after_set_up(config: StudyConfig, prog: StudyProgress, start: _Start, workers: TrackingWorkers
                  ) -> tuple[ResultsData, Delivery]:
    """``compute``'s phases after the set-up: optimise, deliver, analyse; ``workers`` gains the recommended
    design's closed loop (``closed_loop_check.start_design``, before the analysis)."""
    interrupts = prog.interrupts
    with prog.phase("optimise"):
        opt = _optimise_all(config, start, prog)
        robust_run = robust_phase(config, opt, prog, _history)  # issue 18: the robust optimum (opt.res if delivered)
    opt.interrupted = opt.interrupted or interrupts.requested  # (from here on, Ctrl-C finishes: study.interrupts)
    setup = opt.setup
    x1 = np.asarray(opt.res.x_best, float)
    if not opt.interrupted and getattr(opt.res, "feasible", True) is False:
        raise StudyError(f"{config.label}: no design meets the kept requirements ([constraints], "
                         f"objective.thresholds); the least violating design still breaks: "
                         f"{_violations(setup, x1)}; allowed: relax these requirements or widen design bounds")
    with prog.phase("shop"):
        x_opt = x1
        verified = getattr(opt.res, "holes", None)
        model = AnchoredModel(setup.model, x_opt, verified)
        x1, shop, targets = _shop(setup, x_opt, model)
    with prog.phase("rebuild"):
        done = _deliver(setup, opt, prog, (x_opt, x1, shop, targets, model, verified))
        mesh1 = _mesh_of(config, done.shape1)  # (one mesh: the pose prediction repeats its rays, cache_rays)
        m1 = measure_holes(setup, done.holes1, mesh=mesh1)
        obj1, comb1 = score(setup, done.holes1)
        checks = requirement_checks(setup, done.shape1, done.holes1, "brep")
    if not interrupts.requested:  # (interrupted: no closed loop, study.interrupts)
        worker = closed_loop_check.start_design(config, "after" if config.add_targets is None else "move_only",
                                                done.shape1, done.holes1, len(setup.trajectory.times_s))
        if config.add_targets is None:
            workers.after = worker
        else:  # with [add_targets] the move-only optimum may not be the delivered design: "move_only" until known
            workers.move_only = worker
    with prog.phase("analyse"):
        sweep = _sweep(setup)
        dmat = _design_matrix(setup, done.x1)
        robust = _optional(interrupts, _robustness, setup, start.base.holes0, done.holes1, start.comb0)
        pose = _optional(interrupts, _pose_accuracy, config, start, setup, done, mesh1)
    opt.interrupted = opt.interrupted or interrupts.requested
    results = _results(config, start, opt, done, (m1, obj1, comb1, checks), (sweep, dmat, robust))
    if pose is not None:
        results["pose_accuracy"] = pose
    designs = _optional(interrupts, robust_designs, setup, robust_run, start.base.holes0, done.holes1)
    if designs is not None:
        attach_robust(results, designs)  # issue 18
    delivery = Delivery(start.base.shape0, start.base.holes0, done.shape1, done.holes1, setup, start.base,
                        workers=workers)
    if config.add_targets is not None:  # issue 31: new target holes on the move-only optimum
        delivery = _add_targets(config, prog, start, opt, done, results, delivery)
    results["interrupted"] = bool(opt.interrupted or interrupts.requested)
    return results, delivery


def _optional(interrupts: RunInterrupts, func: Callable[_P, _T], *args: _P.args, **kwargs: _P.kwargs) -> _T | None:
    """``func(*args, **kwargs)``, an optional part of the run after the optimiser; None when the run is interrupted
    before or during it (``RunInterrupts.skippable``: the run finishes without it)."""
    try:
        with interrupts.skippable():
            return func(*args, **kwargs)
    except KeyboardInterrupt:
        return None


def _add_targets(config: StudyConfig, prog: StudyProgress, start: _Start, opt: _Optimum, done: _Delivered,
                 results: ResultsData, delivery: Delivery) -> Delivery:
    """The added-target phase (``study.added_targets``) on the move-only optimum; when it recommends holes, that
    design is delivered (``study.added_design.deliver``: the returned ``Delivery``) and its closed loop starts in a
    worker; otherwise the move-only optimum's worker is the delivered design's. An interrupted run
    (``study.interrupts``) delivers the move-only optimum: the phase is skipped, or abandoned when Ctrl-C comes
    during it."""
    base = start.base
    recommended = 0
    interrupts = prog.interrupts
    found: tuple[AddedTargetsData, AddedDesign] | None = None
    if not opt.interrupted and not interrupts.requested:
        with prog.phase("add targets"):
            found = _optional(interrupts, added_targets.run_phase, config, opt.setup, {
                "before": (base.shape0, base.holes0), "after": (done.shape1, done.holes1)}, prog, done.x1)
    if found is not None:
        block, added = found
        results["added_targets"] = block
        recommended = int(block["recommended"])
        if recommended:  # (from here on Ctrl-C is noted, not raised: the results are not left half-changed)
            with prog.phase("add targets"):
                delivery = added_design.deliver(config, opt.setup, base, results, delivery, added,
                                                lambda holes, shape: measure_holes(opt.setup, holes,
                                                                                   mesh=occlusion_mesh(config, shape)),
                                                lambda holes: _patterns(base, holes))
    workers = delivery.workers
    if recommended:
        workers.after = closed_loop_check.start_design(config, "after", delivery.shape1, delivery.holes1,
                                                       len(opt.setup.trajectory.times_s))
    else:
        workers.after, workers.move_only = workers.move_only, None
    return delivery


def _pose_accuracy(config: StudyConfig, start: _Start, setup: StudySetup, done: _Delivered,
                   mesh1: trimesh.Trimesh | None = None) -> JsonDict:
    """results.json ``pose_accuracy`` (``study.pose_accuracy``): predicted pose error before and after;
    ``mesh1``: the delivered design's occlusion mesh when the study built one (else one is made here)."""
    base = start.base
    return pose_accuracy(config, base, base.holes0, part_mesh(config, base.shape0, base.problem.occlusion_mesh),
                         setup, done.holes1, part_mesh(config, done.shape1, mesh1))


def _set_up(config: StudyConfig, time_limit_s: float | None, cache: SetupCache | None = None) -> _Start:
    """The part as it is and every set-up to optimise; the pre-flight refuses a study that cannot mean
    anything before any optimisation. ``cache``: the set-ups are read from it when these inputs were set up before
    and kept in it once their normaliser is built (``study.setup_cache``)."""
    scene = load_scene(config)
    # issue 16: refuse what cannot fit in memory, before any CAD work
    check_fits(len(scene.trajectory), occlusion=config.objective.occlusion,
               robustness_samples=config.robustness.samples, what=config.label)
    combos = int_grid(config) if config.study.part_kind == "script" else [dict[str, int]()]
    if config.study.part_kind == "step":
        base = cached_setup(config, time_limit_s=time_limit_s, cache=cache)
        setups = [base]
        m0 = measure_holes(base, base.holes0)
        pre = preflight_setup(config, base, m0)  # refuses a study that cannot mean anything, before any work
    else:  # "before" = the part's own integer values; the others share its objective scales
        defaults = {p.name: int(p.default) for p in config.design.parameters if p.is_int}
        base = cached_setup(config, defaults, scene=scene, time_limit_s=time_limit_s, cache=cache)
        m0 = measure_holes(base, base.holes0)
        pre = preflight_setup(config, base, m0)  # before the other combinations (and before any optimisation)
        setups = [base] + [cached_setup(config, c, scene=scene, normaliser=base.problem.normaliser,
                                        time_limit_s=time_limit_s, cache=cache) for c in combos if c != defaults]
        if defaults not in combos:  # the part's own integers are outside the study's bounds: "before" only
            setups = setups[1:]
    if config.add_targets is not None:  # issue 31: faces, drill and a feasible site, before any optimisation
        added_targets.preflight(config, base)
    obj0, comb0 = score(base, base.holes0)
    save([base, *setups])  # (the base's normaliser is built by now: kept with it)
    return _Start(scene, base, setups, m0, pre, obj0, comb0)


def _optimise_all(config: StudyConfig, start: _Start, prog: StudyProgress) -> _Optimum:
    """One optimisation per set-up (integer combination), the best kept; Ctrl-C keeps the best so far."""
    best = None
    interrupted = False
    history: list[HistoryPointData] = []
    setups = start.setups
    for s in setups:
        if best is not None and prog.interrupts.requested:  # interrupted: the combinations left are not tried
            interrupted = True
            break
        label = ", ".join(f"{k}={v}" for k, v in s.int_values.items()) if len(setups) > 1 else ""
        prog.best_x, prog.best_f = None, np.inf
        try:
            res, stopped = _optimise(s, prog, label)
        except KeyboardInterrupt:
            if best is None:
                raise
            interrupted = True
            break
        prog.interrupts.designing()  # a design exists: from now on Ctrl-C finishes with the best one
        history += _history(res, label)
        if not stopped and config.study.part_kind == "script":
            s, res, extra, stopped = _refresh_outlines(s, res, start.scene, start.base.problem.normaliser, prog,
                                                       label)
            history += extra
        if best is None or float(res.f_best) < float(best[1].f_best):
            best = (s, res)
        if stopped:
            interrupted = True
            break
    assert best is not None  # (an interrupt before the first result re-raises above)
    return _Optimum(best[0], best[1], history, interrupted or prog.interrupts.requested)


def _rebuild_delivered(setup: StudySetup, x1: np.ndarray, x_opt: np.ndarray, verified: Sequence[Hole] | None,
                       model: AnchoredModel, shop: ShopData, targets: ShopDesign | None
                       ) -> tuple[np.ndarray, ShopDesign | None, tuple[Shape, list[Hole], float]]:
    """The CAD rebuild of the delivered design: the shop-rounded ``x1``; when that does not build (a CAD failure
    is an infeasible point, issue 16), the optimum ``x_opt`` unrounded (``shop`` notes it). Returns (x, shop
    targets or None, ``rebuild``'s result); ``CadfeatError`` when neither builds."""
    try:
        return x1, targets, rebuild(setup, x1, verified if x1 is x_opt else model.holes_at(x1))
    except CadfeatError as exc:
        if x1 is x_opt or np.array_equal(x1, x_opt):
            raise
        shop["applied"] = False
        shop["notes"].append(f"the shop-rounded design does not build ({exc}); the optimiser's design is "
                             "delivered unrounded")
    return x_opt, None, rebuild(setup, x_opt, verified)


Shopped: TypeAlias = "tuple[np.ndarray, np.ndarray, ShopData, ShopDesign | None, AnchoredModel, Sequence[Hole] | None]"
"""The shop phase's outcome: (the optimum, the shop-rounded design, the results.json ``shop`` block, the rounding's
targets (None: not rounded), the anchored feature model, the holes the CAD loop verified at the optimum or None)."""


def _deliver(setup: StudySetup, opt: _Optimum, prog: StudyProgress, shopped: Shopped) -> _Delivered:
    """The CAD rebuild of the shop-rounded optimum; when the linear feature model's optimum does not build,
    an infeasible point: search again with CAD in the loop, round that optimum for the shop, rebuild."""
    x_opt, x1, shop, targets, model, verified = shopped
    res, rebuild_failure = opt.res, None
    try:
        x1, targets, (shape1, holes1, pred_err) = _rebuild_delivered(setup, x1, x_opt, verified, model, shop, targets)
    except CadfeatError as exc:
        if not setup.linear or opt.interrupted:
            raise
        # the optimum of the (linear) feature model does not build: an infeasible point; search again
        # with CAD in the loop (the region shrinks around the buildable start until a rebuild succeeds),
        # then round the new optimum for the shop as before
        rebuild_failure = str(exc)
        prog.log(f"the CAD rebuild of the optimum failed ({exc}); searching again with CAD in the loop")
        res = _with_cad(setup, prog)
        opt.history += _history(res, "CAD in the loop")
        x_opt = np.asarray(res.x_best, float)
        verified = getattr(res, "holes", None)
        model = AnchoredModel(setup.model, x_opt, verified)
        x1, shop, targets = _shop(setup, x_opt, model)
        x1, targets, (shape1, holes1, pred_err) = _rebuild_delivered(setup, x1, x_opt, verified, model, shop, targets)
    if targets is not None and not prog.interrupts.requested:  # (interrupted: the first rebuild is delivered)
        x1, shape1, holes1, pred_err = _shop_refine(setup, x1, (shape1, holes1, pred_err), targets, shop, model)
    return _Delivered(x1, shape1, holes1, pred_err, shop, res, rebuild_failure)


def _results(config: StudyConfig, start: _Start, opt: _Optimum, done: _Delivered,
             after: tuple[Measures, dict[str, float], float | None, list[RequirementData]],
             analysis: tuple[JsonDict | None, JsonDict | None, JsonDict | None]) -> ResultsData:
    """The results.json content of a run (before export: files, verification, timings and verdict follow)."""
    m1, obj1, comb1, checks = after
    sweep, dmat, robust = analysis
    base, setup, res = start.base, opt.setup, done.res
    traj = setup.trajectory
    return {
        "schema_version": SCHEMA_VERSION,
        "cadfeat_version": __version__,
        "created": now_iso(),
        "study": {"name": config.study.name, "file": str(config.file) if config.file else None,
                  "part": config.study.part, "part_kind": config.study.part_kind, "seed": config.study.seed,
                  "description": config.study.description},
        "inputs": config.to_dict(),
        "camera": setup.camera.to_dict(),
        "trajectory": {**trajectory_info(traj), "kind": config.trajectory.table.get("kind", "csv")},
        "part_pose": {"T_task_part": setup.T_task_part},
        "variables": _variables(setup, base.space.x0 if base is setup else _x0_like(setup, base), done.x1,
                                base.int_values, setup.int_values),
        "holes": _holes_block(base, base.holes0, setup, done.holes1),
        "objectives": {"names": list(start.obj0), "normalisation": _normalisation(setup),
                       "combine": config.objective.combine, "aggregate": config.objective.aggregate,
                       "before": start.obj0, "after": obj1, "combined_before": start.comb0, "combined_after": comb1,
                       "larger_is_better": True, **objective_changes(setup.problem, start.obj0, obj1),
                       "score": score_rule(config, base.holes0, scored_mask(base)),
                       "occlusion": bool(config.objective.occlusion)},
        "measures": {"before": measures_summary(start.m0, base.hole_names, base.trajectory.times_s,
                                                config.objective.min_axis_px, half_image(base.camera)),
                     "after": measures_summary(m1, hole_names(done.holes1),
                                               traj.times_s, config.objective.min_axis_px, half_image(setup.camera))},
        "constraints": checks,
        "requirements_used": _requirements_used(setup, done.x1),
        "shop": done.shop,
        "patterns": _patterns(base, done.holes1),
        "robustness": robust,
        "design_matrix": dmat,
        "history": opt.history,
        "sweep": sweep,
        "pareto": getattr(res, "pareto", None),
        "optimizer": {"method": config.optimizer.method, "n_evals": int(getattr(res, "n_evals", 0) or 0),
                      "linear_feature_map": bool(setup.linear), "prediction_error_mm": done.pred_err,
                      "integer_combinations": len(start.setups),
                      **({"rebuild_failed_at_model_optimum": done.rebuild_failure} if done.rebuild_failure
                         else {})},
        "interrupted": bool(opt.interrupted),
        "preflight": start.pre.to_dict(),
        "warnings": list(start.pre.warnings),
    }


def part_points(shape: Shape | None, mesh: trimesh.Trimesh | None = None, most: int = 4000) -> np.ndarray:
    """Points of the part (V, 3) mm, part frame, for the pre-flight: the occlusion mesh's vertices (or a coarse
    mesh of ``shape``), at most ``most`` of them (evenly strided)."""
    if mesh is None:
        if shape is None:
            raise ValueError("part_points: neither a mesh nor a shape")
        mesh = mesh_from_shape(shape, tolerance=0.5)
    v = np.asarray(mesh.vertices, float)
    return v[:: max(1, len(v) // most)]


def preflight_setup(config: StudyConfig, setup: StudySetup, m: Measures) -> Preflight:
    """``preflight.preflight`` of a set-up study with the measures ``m`` of its holes along the trajectory."""
    mesh = getattr(setup.problem, "occlusion_mesh", None)
    pts = part_points(setup.shape0 if mesh is None else None, mesh)  # (a cached set-up's solid: only if needed)
    return preflight(config, setup.camera, setup.trajectory, setup.T_task_part, pts, m, scored_mask(setup),
                     setup.hole_names)


def _mesh_of(config: StudyConfig, shape: Shape) -> trimesh.Trimesh | None:
    return occlusion_mesh(config, shape)


def scored_mask(setup: StudySetup) -> np.ndarray:
    mask = getattr(setup.problem, "feature_mask", None)
    return np.ones(len(setup.holes0), bool) if mask is None else np.asarray(mask, bool)


def _shop_refine(setup: StudySetup, x: np.ndarray, rebuilt: tuple[Shape, list[Hole], float], targets: ShopDesign,
                 info: ShopData, model: FeatureModel) -> tuple[np.ndarray, Shape, list[Hole], float]:
    """``shop.refine_on_rebuild`` on the study's CAD rebuild; ``info["rebuilt_off_target_mm"]``: what remains."""
    x, (shape, holes, err), off = refine_on_rebuild(setup.space, model, setup.problem, x, rebuilt, targets,
                                                    lambda x_new, guess: rebuild(setup, x_new, guess))
    info["rebuilt_off_target_mm"] = off
    info["x_shop"] = dict(zip(setup.space.names, map(float, x), strict=True))
    return x, shape, holes, err


def _shop(setup: StudySetup, x: np.ndarray, model: FeatureModel | None = None
          ) -> tuple[np.ndarray, ShopData, ShopDesign | None]:
    """The shop-ready design near the optimum ``x`` (``cadfeat.design.shop``, study ``[shop]``) and its
    results.json block; the optimum itself when rounding would break a kept requirement of the model (the
    rebuilt design is verified on the B-rep and the STEP either way)."""
    spec = setup.config.shop
    sizes = hole_sizes(spec.hole_sizes)
    info: ShopData = {"grid_mm": spec.grid_mm, "hole_sizes": spec.hole_sizes if isinstance(spec.hole_sizes, str)
                      else list(spec.hole_sizes), "applied": False, "notes": []}
    if spec.grid_mm <= 0 and not sizes:
        info["notes"].append("rounding off ([shop] grid_mm = 0, hole_sizes = \"none\")")
        return x, info, None
    sd = shop_design(setup.space, model if model is not None else setup.model, x, grid_mm=spec.grid_mm, sizes=sizes,
                     problem=setup.problem)
    info["notes"] += sd.notes
    margins = np.asarray(setup.problem.constraints(sd.x), float)
    names = setup.space.names
    info["x_optimum"] = dict(zip(names, map(float, x), strict=True))
    info["x_shop"] = dict(zip(names, map(float, sd.x), strict=True))
    info["residual_mm"] = sd.residual_mm
    info["moved"] = [h for h, m in zip(setup.hole_names, sd.moved, strict=True) if m]
    info["resized"] = [h for h, m in zip(setup.hole_names, sd.resized, strict=True) if m]
    if setup.config.objective.combine != "pareto":
        info["combined_optimum"] = float(setup.problem.combined(x))
        info["combined_shop"] = float(setup.problem.combined(sd.x))
    if margins.size and margins.min() < -1e-9:
        labels = setup.problem.constraint_labels()
        k = int(np.argmin(margins))
        info["notes"].append(f"rounding would break {labels[k][0]} {'/'.join(labels[k][1])} (margin "
                             f"{margins[k]:.3g}); the optimiser's design is delivered unrounded")
        return x, info, None
    info["applied"] = True
    return sd.x, info, sd


def _robustness(setup: StudySetup, holes0: Sequence[Hole], holes1: Sequence[Hole],
                combined_before: float | None) -> JsonDict | None:
    """Objective drops of the delivered design under the study's ``[robustness]`` tolerances (sampled on
    features, ``cadfeat.design.robustness``); the holes the shop makes anew are the moved or resized ones."""
    spec = setup.config.robustness
    if spec.samples <= 0 or len(holes0) != len(holes1):
        return None
    c0, _, r0 = holes_to_arrays(list(holes0))
    c1, a1, r1 = holes_to_arrays(list(holes1))
    changed = (np.linalg.norm(c1 - c0, axis=1) > 1e-6) | (np.abs(r1 - r0) > 1e-6)
    return robustness(setup.problem, c1, a1, r1, changed, position_tol_mm=spec.position_tol_mm,
                      size_steps=spec.size_steps, sizes=hole_sizes(setup.config.shop.hole_sizes),
                      camera_position_mm=setup.config.cell.camera_position_mm,
                      camera_angle_deg=setup.config.cell.camera_angle_deg,
                      samples=spec.samples, combined_before=combined_before, seed=setup.config.study.seed)


def _patterns(base: StudySetup, holes1: Sequence[Hole]) -> list[JsonDict]:
    """The original's hole patterns with a movable hole (``cadfeat.design.patterns``), each with ``broken``."""
    movable = np.asarray(base.movable_mask, bool)
    found = [p for p in find_patterns(base.holes0) if movable[list(p.holes)].any()]
    return check_patterns(found, list(holes1), base.hole_names) if len(holes1) == len(base.holes0) else []


def _requirements_used(setup: StudySetup, x: np.ndarray) -> list[JsonDict]:
    """The kept requirements the optimiser's model used (kind, hole names, its 2-D margin at ``x``): the report
    checks that each one was verified on the rebuilt geometry."""
    labels = setup.problem.constraint_labels()
    margins = np.asarray(setup.problem.constraints(x), float).reshape(-1)
    if len(labels) != margins.size:
        return [{"name": k, "holes": list(h)} for k, h in labels]
    return [{"name": k, "holes": list(h), "margin": float(m)} for (k, h), m in zip(labels, margins, strict=True)]


def _x0_like(setup: StudySetup, base: StudySetup) -> np.ndarray:
    """The before-values of ``setup``'s continuous variables (the part defaults, as in ``base``)."""
    return np.asarray(base.space.x0, float) if base.space.names == setup.space.names else setup.space.x0
