"""Run a redesign study end to end (DESIGN.md data flow) and score designs without optimising.

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
   check every kept requirement again on the re-imported solid; ``results.json``; the report
   (``cadfeat.report.write_report``) if that module is available; then publish the folder.

Nothing is written if validation, the CAD rebuild or a verification fails, or if the run is interrupted
before the optimiser found a design; the input part file is only read.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib.util
import io
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cadfeat.errors import CadfeatError
from cadfeat.study.outputs import (
    SCHEMA_VERSION,
    file_entry,
    hole_dict,
    measures_summary,
    normalise_step_header,
    now_iso,
    plain,
    versions,
    write_json,
)
from cadfeat.study.progress import StudyProgress
from cadfeat.study.schema import StudyConfig, StudyError, load_study
from cadfeat.study.trust import objective_changes

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.study.setup import StudySetup

__all__ = ["EXPORTS_DIR", "StudyResult", "evaluate_study", "run_study"]

EXPORTS_DIR = Path("exports")
"""Default parent of a study's output folder: ``exports/<study name>/`` (relative to the current folder)."""
SWEEP_SAMPLES = 41
OUTLINE_ROUNDS = 4
ROUNDTRIP_TOL_MM = 1e-6
PREDICTION_TOL_MM = 1e-6
OUTPUT_FILES = ("original.step", "optimised.step", "optimised.stl", "holes.csv", "results.json")


@dataclass(frozen=True)
class StudyResult:
    """Where a study wrote its outputs and the results (the content of results.json)."""

    out_dir: Path | None
    results: dict[str, Any]

    def summary(self) -> str:
        """A short human-readable before/after summary."""
        return summarise(self.results, self.out_dir)


def summarise(results: Mapping[str, Any], out_dir: Path | None) -> str:
    obj = results["objectives"]
    lines = [f"study {results['study']['name']}" + (" (INTERRUPTED: best design so far)"
                                                     if results.get("interrupted") else "")]
    for v in results["variables"]:
        lines.append(f"  {v['name']:<16} {_num(v['before']):>10} -> {_num(v['after']):>10} {v['unit']}")
    units = {c["name"]: c.get("unit", "") for c in obj.get("changes", [])}
    for name in obj["names"]:
        lines.append(f"  {name:<16} {_num(obj['before'].get(name)):>10} -> {_num(obj['after'].get(name)):>10}"
                     f"  {units.get(name, '')}")
    lines.append(f"  {'combined':<16} {_num(obj.get('combined_before')):>10} -> "
                 f"{_num(obj.get('combined_after')):>10}  ({obj['combine']}, larger is better)")
    if obj.get("limiting"):
        lines.append(f"  limiting objective: {obj['limiting']} (before: {obj.get('limiting_before')})")
    if obj.get("score"):
        lines.append(f"  scored holes: {obj['score']}")
    for w in obj.get("warnings", []) + list(results.get("warnings", [])):
        lines.append(f"  WARNING: {w}")
    for a in (results.get("preflight") or {}).get("assumptions", []):
        lines.append(f"  ASSUMED: {a}")
    failed = [c for c in results["constraints"] if not c["ok"]]
    lines.append(f"  kept requirements: {len(results['constraints']) - len(failed)} of {len(results['constraints'])} "
                 "hold (B-rep and re-imported STEP)")
    if out_dir is not None:
        lines.append(f"  outputs: {out_dir}")
        for name in ("optimised.step", "optimised.stl", "report.html"):
            if (out_dir / name).exists():
                lines.append(f"    {out_dir / name}")
    return "\n".join(lines)


def _num(x: Any) -> str:
    if x is None:
        return "-"
    if isinstance(x, int):
        return str(x)
    return f"{x:.6g}"


# ------------------------------------------------------------------------------------------ scoring
def measure_holes(setup: StudySetup, holes: Sequence[Any], trajectory: Any = None, *, mesh: Any = None) -> Any:
    """``measures.evaluate`` of real holes (part frame) along the study's trajectory (or ``trajectory``), with
    the occlusion test against ``mesh`` (default: the setup problem's part mesh, None when occlusion is off)."""
    from cadfeat import measures
    from cadfeat.cad.features import holes_to_arrays

    traj = trajectory if trajectory is not None else setup.trajectory
    o = setup.config.objective
    if mesh is None:
        mesh = getattr(getattr(setup, "problem", None), "occlusion_mesh", None)
    T_cam_part = np.linalg.inv(np.asarray(traj.T_task_cam)) @ setup.T_task_part
    c, a, r = holes_to_arrays(list(holes))
    return measures.evaluate(setup.camera, T_cam_part, traj.velocity_screws(), c, a, r, min_axis_px=o.min_axis_px,
                             rotation_length_mm=o.rotation_length_mm, occlusion_mesh=mesh)


def score(setup: StudySetup, holes: Sequence[Any]) -> tuple[dict[str, float], float | None]:
    """The aggregated objectives of real holes and their combined value (larger is better), computed exactly
    as the optimiser does (``Problem.features_objectives`` / ``combined_from``: same normalisation), with the
    exact occlusion ray test (the optimiser uses the part's depth maps, ``measures.depth``)."""
    from cadfeat.cad.features import holes_to_arrays

    problem = setup.problem
    G = problem.features_objectives(*holes_to_arrays(list(holes)), exact_occlusion=True)
    values = dict(zip(problem.names, map(float, G), strict=True))
    if setup.config.objective.combine == "pareto":
        return values, None
    return values, float(problem.combined_from(G))


# ------------------------------------------------------------------------------------------ optimise
def _optimise(setup: StudySetup, progress: StudyProgress, label: str = "") -> tuple[Any, bool]:
    """Optimise one setup; returns (OptimResult-like, interrupted)."""
    from cadfeat.design.optimize import optimise, solve_with_cad

    oc = setup.config.optimizer
    try:
        if setup.linear:
            res = optimise(setup.problem, oc, progress=progress.iteration)
        else:
            res = solve_with_cad(setup.problem, lambda x: setup.rebuild_holes(setup.rebuild_shape(x)), oc,
                                 progress=progress.iteration)
    except KeyboardInterrupt:
        if progress.best_x is None:
            raise
        res = _Interrupted(progress.best_x, progress.best_f)
    if getattr(res, "interrupted", False) and not getattr(res, "history", None) and progress.best_x is None:
        raise KeyboardInterrupt  # stopped before the optimiser evaluated any design: nothing to write
    return res, bool(getattr(res, "interrupted", False))


def _with_cad(setup: StudySetup, progress: StudyProgress) -> Any:
    """``solve_with_cad`` on ``setup`` (a rebuild that raises or times out is an infeasible point)."""
    from cadfeat.design.optimize import solve_with_cad

    return solve_with_cad(setup.problem, lambda x: setup.rebuild_holes(setup.rebuild_shape(x)), setup.config.optimizer,
                          progress=progress.iteration)


@dataclass
class _Interrupted:
    """Stand-in result when the optimiser itself was stopped by Ctrl-C before returning."""

    x_best: np.ndarray
    f_best: float
    history: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    interrupted: bool = True
    pareto: dict[str, Any] | None = None
    n_evals: int = 0


def _violations(setup: StudySetup, x: np.ndarray, most: int = 5) -> str:
    """The most violated 2-D constraints at ``x``: "kind (holes) by N mm", worst first."""
    C = np.asarray(setup.problem.constraints(x), float)
    labels = setup.problem.constraint_labels()
    order = [int(i) for i in np.argsort(C) if C[i] < 0][:most]
    return "; ".join(f"{labels[i][0]} ({', '.join(labels[i][1]) or '-'}) by {-C[i]:.4g}" for i in order) or \
        "(no 2-D constraint; see the optimiser's message)"


def _outlines_differ(a: Sequence[Any], b: Sequence[Any], tol_mm: float = 1e-6) -> bool:
    """Whether the host-face outlines of paired holes differ (outer polygon or keep-outs, mm)."""
    for h, g in zip(a, b, strict=True):
        oa, ob = h.outline, g.outline
        if (oa is None) != (ob is None):
            return True
        if oa is None:
            continue
        pa, pb = np.asarray(oa.outer, float), np.asarray(ob.outer, float)
        if pa.shape != pb.shape or np.abs(pa - pb).max(initial=0.0) > tol_mm:
            return True
        ka, kb = list(oa.keepouts), list(ob.keepouts)
        if len(ka) != len(kb) or any(np.asarray(x).shape != np.asarray(y).shape or
                                     np.abs(np.asarray(x) - np.asarray(y)).max(initial=0.0) > tol_mm
                                     for x, y in zip(ka, kb, strict=True)):
            return True
    return False


def _refresh_outlines(setup: StudySetup, res: Any, scene: Any, normaliser: Any, prog: StudyProgress,
                      label: str) -> tuple[Any, Any, list[dict[str, Any]], bool]:
    """The optimiser's 2-D constraints use the host-face outlines of the design it was linearised at; when a
    parameter also changes the faces (e.g. a block that grows with the hole spacing), rebuild at the
    optimum, linearise again there (new outlines) and re-optimise from it, until the outlines agree (at
    most ``OUTLINE_ROUNDS`` rounds; a round is kept only if it improves the objective)."""
    from cadfeat.study.setup import setup_script

    history: list[dict[str, Any]] = []
    stopped = False
    for k in range(OUTLINE_ROUNDS):
        x = np.asarray(res.x_best, float)
        try:
            _, holes, _ = _rebuild(setup, x)
            if not _outlines_differ(setup.model.holes, holes):
                break
            names = setup.space.names
            new = setup_script(setup.config, setup.int_values, scene, normaliser,
                               at=dict(zip(names, x, strict=True)))
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


def _history(res: Any, label: str) -> list[dict[str, Any]]:
    out = []
    for i, h in enumerate(getattr(res, "history", None) or []):
        h = dict(h) if isinstance(h, Mapping) else {"f": h}
        out.append({"iteration": int(h.get("iteration", i)), "f": h.get("f"), "combined": h.get("combined"),
                    "feasible": bool(h.get("feasible", True)), "phase": (label + " " if label else "")
                    + str(h.get("phase", "")).strip()})
    return out


def _sweep(setup: StudySetup) -> dict[str, Any] | None:
    """For a one-variable study: the objectives over the variable's range (thesis Figs. 5.10/5.11)."""
    space = setup.space
    if space.size != 1:
        return None
    v = space.variables[0]
    values = np.linspace(v.lower, v.upper, SWEEP_SAMPLES)
    objectives: dict[str, list[float]] = {}
    combined = []
    for x in values:
        obj = setup.problem.objectives(np.array([x]))
        for k, g in obj.items():
            objectives.setdefault(k, []).append(float(g))
        combined.append(-float(setup.problem.objective(np.array([x]))))
    return {"variable": v.name, "unit": v.unit, "values": values, "objectives": objectives, "combined": combined}


# ------------------------------------------------------------------------------------------ verification
def _order_like(reference: Sequence[Any], holes: Sequence[Any], tol_mm: float, what: str) -> list[Any]:
    """``holes`` reordered to pair with ``reference`` by geometry (nearest centres, one to one), each taking its
    reference's name."""
    from cadfeat.cad.features import match_holes

    if len(holes) != len(reference):
        raise CadfeatError(f"{what}: {len(holes)} holes found, {len(reference)} designed")
    try:
        idx = match_holes(list(reference), list(holes), tol_mm=tol_mm)
    except CadfeatError as exc:
        raise CadfeatError(f"{what}: holes do not match the design: {exc}") from exc
    return [dataclasses.replace(holes[i], name=r.name) if r.name else holes[i]
            for r, i in zip(reference, idx, strict=True)]


def _predicted_holes(setup: StudySetup, x: np.ndarray) -> list[Any]:
    c, a, r = setup.model.features(x)
    return [dataclasses.replace(h, centre=np.asarray(c[i]), axis=np.asarray(a[i]), radius_mm=float(r[i]))
            for i, h in enumerate(setup.model.holes)]


def _rebuild(setup: StudySetup, x: np.ndarray, verified: Sequence[Any] | None = None) -> tuple[Any, list[Any], float]:
    """The CAD rebuild at ``x``: solid, its holes in the design's order, and the largest centre/radius
    deviation from the prediction (mm): the feature model's, or ``verified`` (the holes the CAD trust-region
    loop extracted at ``x``, in model order) when given."""
    from cadfeat.cad.features import holes_to_arrays

    shape = setup.rebuild_shape(x)
    predicted = _predicted_holes(setup, x)
    if verified is not None and len(verified) == len(predicted):
        predicted = [dataclasses.replace(v, name=p.name) for v, p in zip(verified, predicted, strict=True)]
    holes = _order_like(predicted, setup.rebuild_holes(shape), 0.5, "CAD rebuild of the optimum")
    holes = [dataclasses.replace(h, name=p.name) if p.name else h for h, p in zip(holes, predicted, strict=True)]
    c0, _, r0 = holes_to_arrays(predicted)
    c1, _, r1 = holes_to_arrays(holes)
    err = float(max(np.linalg.norm(c1 - c0, axis=1).max(initial=0.0), np.abs(r1 - r0).max(initial=0.0)))
    return shape, holes, err


def _checks(setup: StudySetup, shape: Any, holes: Sequence[Any], where: str) -> list[dict[str, Any]]:
    """Every kept requirement measured on the solid ``shape`` whose holes are ``holes`` (design order).

    ``verify_on_brep`` re-extracts holes without a preferred direction (a through hole may then be reported
    from its other end), so the design and reference holes are given to it in that same convention, paired
    with the design order by their axis lines."""
    from cadfeat.design.constraints import verify_on_brep

    design = _pair_by_axis(holes, _extract_plain(shape), f"{where} holes")
    reference = _pair_by_axis(setup.holes0, _extract_plain(setup.shape0), "original holes")
    checks = verify_on_brep(shape, design, setup.constraints, setup.fixed_mask, reference=reference,
                            reference_shape=setup.shape0)
    return [{**c.to_dict(), "checked_on": where} for c in checks]


def _pair_by_axis(reference: Sequence[Any], holes: Sequence[Any], what: str, tol_mm: float = 1e-3) -> list[Any]:
    """``holes`` reordered to pair with ``reference`` hole by hole: same axis line (parallel axes, either
    sign, centre on the reference's axis line within ``tol_mm``), nearest centre first; each paired hole takes
    its reference's name (a hole keeps one name in every output, whatever order extraction found it in)."""
    if len(holes) != len(reference):
        raise CadfeatError(f"{what}: {len(holes)} holes found, {len(reference)} designed")
    c1 = np.array([h.centre for h in holes], float).reshape(-1, 3)
    a1 = np.array([h.axis for h in holes], float).reshape(-1, 3)
    out, used = [], set()
    for i, h in enumerate(reference):
        c0, a0 = np.asarray(h.centre, float), np.asarray(h.axis, float)
        d = c1 - c0
        off_line = np.linalg.norm(d - np.outer(d @ a0, a0), axis=1)
        parallel = np.abs(a1 @ a0) > 1 - 1e-9
        ok = [k for k in np.argsort(np.linalg.norm(d, axis=1)) if parallel[k] and off_line[k] <= tol_mm
              and k not in used]
        if not ok:
            raise CadfeatError(f"{what}: no hole on the axis of design hole {h.name or i + 1} at "
                               f"{np.round(c0, 6).tolist()}")
        used.add(ok[0])
        out.append(dataclasses.replace(holes[ok[0]], name=h.name) if h.name else holes[ok[0]])
    return out


def _fail_on(checks: Sequence[Mapping[str, Any]], label: str) -> None:
    bad = [c for c in checks if not c["ok"]]
    if bad:
        text = "; ".join(f"{c['name']} {'/'.join(c['holes'])}: {c['value']:.6g} {c['unit']} (required "
                         f"{c['required']:.6g}, checked on {c['checked_on']})" for c in bad[:6])
        raise CadfeatError(f"{label}: the optimised design violates kept requirement(s): {text}")


# ------------------------------------------------------------------------------------------ results
def _variables(setup: StudySetup, x0: np.ndarray, x1: np.ndarray, ints0: Mapping[str, int],
               ints1: Mapping[str, int]) -> list[dict[str, Any]]:
    out = []
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


def _holes_block(setup0: Any, holes0: Sequence[Any], setup1: Any, holes1: Sequence[Any]) -> dict[str, Any]:
    return {"before": [hole_dict(h, i, setup0.fixed_mask[i], setup0.movable_mask[i]) for i, h in enumerate(holes0)],
            "after": [hole_dict(h, i, setup1.fixed_mask[i], setup1.movable_mask[i]) for i, h in enumerate(holes1)]}


def _design_matrix(setup: StudySetup, x: np.ndarray) -> dict[str, Any] | None:
    try:
        from cadfeat.design.axiomatic import design_matrix
    except ImportError:
        return None
    dm = design_matrix(setup.problem, x)
    note = getattr(dm, "note", "") or ("sensitivities of each objective and kept requirement (rows) to each group "
                                       "of design parameters (columns) at the optimum, thesis §2.2.4")
    return {"rows": list(dm.rows), "cols": list(dm.cols), "matrix": np.asarray(dm.matrix, float),
            "verdict": dm.verdict, "note": note}


def _normalisation(setup: StudySetup) -> dict[str, Any]:
    normaliser = getattr(setup.problem, "normaliser", None)
    if normaliser is None:
        return {"method": "none", "reference": {}, "note": "objectives in their own units"}
    d = normaliser.to_dict()
    return {"method": d.get("method"), "reference": d.get("reference", {}), "note": d.get("note", ""),
            **({"sources": d["sources"]} if "sources" in d else {})}


def _trajectory_info(traj: Any) -> dict[str, Any]:
    """Kind, sample count, duration and the sampled camera poses (``T_task_cam`` (L, 4, 4), mm; ``time_s``)."""
    table_kind = getattr(traj, "name", "") or ""
    return {"kind": table_kind, "n_samples": len(traj), "duration_s": float(traj.duration_s),
            "time_s": np.asarray(traj.times_s, float), "T_task_cam": np.asarray(traj.T_task_cam, float)}


def _half_image(camera: Any) -> float:
    return 0.5 * min(camera.width, camera.height)


# ------------------------------------------------------------------------------------------ run
def _resolve(path_or_dict: Any, seed: int | None) -> StudyConfig:
    config = path_or_dict if isinstance(path_or_dict, StudyConfig) else load_study(path_or_dict)
    return config.with_seed(seed) if seed is not None else config


def default_out_dir(config: StudyConfig) -> Path:
    return EXPORTS_DIR / config.study.name


def run_study(path_or_dict: Any, out_dir: str | Path | None = None, *, seed: int | None = None,
              quiet: bool = False, progress: bool = True, force: bool = False) -> StudyResult:
    """Run a study (a TOML path, a dict or a ``StudyConfig``) and write its outputs to ``out_dir``
    (default ``exports/<study name>/``): original.step, optimised.step, optimised.stl, results.json and the
    report. ``seed`` overrides the study's seeds. Raises ``CadfeatError`` (nothing written) on bad input or a
    failed verification; ``KeyboardInterrupt`` before the optimiser found a design also writes nothing.

    The output folder is checked before any work (``cadfeat.cad.output_folder``): a non-empty folder cadfeat
    did not create is refused unless ``force`` (then cadfeat's files are added, other files untouched).
    Every part-script import and CAD build runs in a worker process within ``[study] build_timeout_s``.
    """
    from cadfeat.cad.output_folder import staged_output
    from cadfeat.cad.parts import build_time_limit

    config = _resolve(path_or_dict, seed)
    out = out_dir if out_dir is not None else default_out_dir(config)
    with staged_output(out, force) as stage, build_time_limit(config.study.build_timeout_s), \
            StudyProgress(config.study.name, enabled=progress and not quiet) as prog:
        results, shapes = _compute(config, prog)
        with prog.phase("export"):
            _write_outputs(config, stage, results, shapes, prog)
    return StudyResult(Path(out), results)


def _compute(config: StudyConfig, prog: StudyProgress) -> tuple[dict[str, Any], dict[str, Any]]:
    from cadfeat.study.setup import int_grid, load_scene, score_rule, setup_script, setup_study

    with prog.phase("setup"):
        scene = load_scene(config)
        combos = int_grid(config) if config.study.part_kind == "script" else [{}]
        if config.study.part_kind == "step":
            base = setup_study(config)
            setups = [base]
            m0 = measure_holes(base, base.holes0)
            pre = _preflight(config, base, m0)  # refuses a study that cannot mean anything, before any work
        else:  # "before" = the part's own integer values; the others share its objective scales
            defaults = {p.name: int(p.default) for p in config.design.parameters if p.is_int}
            base = setup_script(config, defaults, scene)
            m0 = measure_holes(base, base.holes0)
            pre = _preflight(config, base, m0)  # before the other combinations (and before any optimisation)
            setups = [base] + [setup_script(config, c, scene, base.problem.normaliser) for c in combos
                               if c != defaults]
            if defaults not in combos:  # the part's own integers are outside the study's bounds: "before" only
                setups = setups[1:]
        obj0, comb0 = score(base, base.holes0)
    best = None
    interrupted = False
    history: list[dict[str, Any]] = []
    with prog.phase("optimise"):
        for s in setups:
            label = ", ".join(f"{k}={v}" for k, v in s.int_values.items()) if len(setups) > 1 else ""
            prog.best_x, prog.best_f = None, np.inf
            try:
                res, stopped = _optimise(s, prog, label)
            except KeyboardInterrupt:
                if best is None:
                    raise
                interrupted = True
                break
            history += _history(res, label)
            if not stopped and config.study.part_kind == "script":
                s, res, extra, stopped = _refresh_outlines(s, res, scene, base.problem.normaliser, prog, label)
                history += extra
            if best is None or float(res.f_best) < float(best[1].f_best):
                best = (s, res)
            if stopped:
                interrupted = True
                break
    setup, res = best
    x1 = np.asarray(res.x_best, float)
    if not interrupted and getattr(res, "feasible", True) is False:
        raise StudyError(f"{config.label}: no design meets the kept requirements ([constraints], "
                         f"objective.thresholds); the least violating design still breaks: "
                         f"{_violations(setup, x1)}; allowed: relax these requirements or widen design bounds")
    rebuild_failure = None
    x_opt = x1
    verified = getattr(res, "holes", None)
    with prog.phase("shop"):
        model = _Anchored(setup.model, x_opt, verified)
        x1, shop, targets = _shop(setup, x_opt, model)
    with prog.phase("rebuild"):
        try:
            shape1, holes1, pred_err = _rebuild(setup, x1, verified if x1 is x_opt else model.holes_at(x1))
        except CadfeatError as exc:
            if not setup.linear or interrupted:
                raise
            # the optimum of the (linear) feature model does not build: an infeasible point; search again
            # with CAD in the loop (the region shrinks around the buildable start until a rebuild succeeds),
            # then round the new optimum for the shop as before
            rebuild_failure = str(exc)
            prog.log(f"the CAD rebuild of the optimum failed ({exc}); searching again with CAD in the loop")
            res = _with_cad(setup, prog)
            history += _history(res, "CAD in the loop")
            x_opt = np.asarray(res.x_best, float)
            verified = getattr(res, "holes", None)
            model = _Anchored(setup.model, x_opt, verified)
            x1, shop, targets = _shop(setup, x_opt, model)
            shape1, holes1, pred_err = _rebuild(setup, x1, verified if x1 is x_opt else model.holes_at(x1))
        if targets is not None:
            x1, shape1, holes1, pred_err = _shop_refine(setup, x1, (shape1, holes1, pred_err), targets, shop, model)
        m1 = measure_holes(setup, holes1, mesh=_mesh_of(config, shape1))
        obj1, comb1 = score(setup, holes1)
        checks = _checks(setup, shape1, holes1, "brep")
    with prog.phase("analyse"):
        sweep = _sweep(setup)
        dmat = _design_matrix(setup, x1)
        robust = _robustness(setup, base.holes0, holes1, comb0)
    traj = setup.trajectory
    results: dict[str, Any] = {
        "schema_version": SCHEMA_VERSION,
        "cadfeat_version": _version(),
        "created": now_iso(),
        "study": {"name": config.study.name, "file": str(config.file) if config.file else None,
                  "part": config.study.part, "part_kind": config.study.part_kind, "seed": config.study.seed,
                  "description": config.study.description},
        "inputs": config.to_dict(),
        "camera": setup.camera.to_dict(),
        "trajectory": {**_trajectory_info(traj), "kind": config.trajectory.table.get("kind", "csv")},
        "part_pose": {"T_task_part": setup.T_task_part},
        "variables": _variables(setup, base.space.x0 if base is setup else _x0_like(setup, base), x1,
                                base.int_values, setup.int_values),
        "holes": _holes_block(base, base.holes0, setup, holes1),
        "objectives": {"names": list(obj0), "normalisation": _normalisation(setup),
                       "combine": config.objective.combine, "aggregate": config.objective.aggregate,
                       "before": obj0, "after": obj1, "combined_before": comb0, "combined_after": comb1,
                       "larger_is_better": True, **objective_changes(setup.problem, obj0, obj1),
                       "score": score_rule(config, base.holes0, _scored(base)),
                       "occlusion": bool(config.objective.occlusion)},
        "measures": {"before": measures_summary(m0, base.hole_names, base.trajectory.times_s,
                                                config.objective.min_axis_px, _half_image(base.camera)),
                     "after": measures_summary(m1, [h.name or f"H{i + 1}" for i, h in enumerate(holes1)],
                                               traj.times_s, config.objective.min_axis_px, _half_image(setup.camera))},
        "constraints": checks,
        "requirements_used": _requirements_used(setup, x1),
        "shop": shop,
        "patterns": _patterns(base, holes1),
        "robustness": robust,
        "design_matrix": dmat,
        "history": history,
        "sweep": sweep,
        "pareto": getattr(res, "pareto", None),
        "optimizer": {"method": config.optimizer.method, "n_evals": int(getattr(res, "n_evals", 0) or 0),
                      "linear_feature_map": bool(setup.linear), "prediction_error_mm": pred_err,
                      "integer_combinations": len(setups),
                      **({"rebuild_failed_at_model_optimum": rebuild_failure} if rebuild_failure else {})},
        "interrupted": bool(interrupted),
        "preflight": pre.to_dict(),
        "warnings": list(pre.warnings),
    }
    shapes = {"shape0": base.shape0, "shape1": shape1, "holes0": base.holes0, "holes1": holes1, "setup": setup,
              "base": base}
    return results, shapes


def part_points(shape: Any, mesh: Any = None, most: int = 4000) -> np.ndarray:
    """Points of the part (V, 3) mm, part frame, for the pre-flight: the occlusion mesh's vertices (or a coarse
    mesh of ``shape``), at most ``most`` of them (evenly strided)."""
    if mesh is None:
        from cadfeat.cad.export import mesh_from_shape

        mesh = mesh_from_shape(shape, tolerance=0.5)
    v = np.asarray(mesh.vertices, float)
    return v[:: max(1, len(v) // most)]


def _preflight(config: StudyConfig, setup: Any, m: Any) -> Any:
    """``preflight.preflight`` of a set-up study with the measures ``m`` of its holes along the trajectory."""
    from cadfeat.study.preflight import preflight

    pts = part_points(setup.shape0, getattr(setup.problem, "occlusion_mesh", None))
    return preflight(config, setup.camera, setup.trajectory, setup.T_task_part, pts, m, _scored(setup),
                     setup.hole_names)


def preflight_study(path_or_dict: Any) -> Any:
    """The pre-flight of a study on its part as it is (``cadfeat validate``): every hole counts as scored
    (which holes the design moves needs the design map, which ``run`` builds)."""
    from cadfeat import measures
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.study.preflight import preflight
    from cadfeat.study.setup import load_scene, occlusion_mesh

    config = _resolve(path_or_dict, None)
    camera, traj, T_task_part = load_scene(config)
    shape, holes, _, names = _current_design(config)
    mesh = occlusion_mesh(config, shape)
    o = config.objective
    T_cam_part = np.linalg.inv(np.asarray(traj.T_task_cam)) @ T_task_part
    m = measures.evaluate(camera, T_cam_part, traj.velocity_screws(), *holes_to_arrays(list(holes)),
                          min_axis_px=o.min_axis_px, rotation_length_mm=o.rotation_length_mm, occlusion_mesh=mesh)
    return preflight(config, camera, traj, T_task_part, part_points(shape, mesh), m, np.ones(len(holes), bool),
                     names)


def _mesh_of(config: StudyConfig, shape: Any) -> Any:
    from cadfeat.study.setup import occlusion_mesh

    return occlusion_mesh(config, shape)


def _scored(setup: Any) -> np.ndarray:
    mask = getattr(setup.problem, "feature_mask", None)
    return np.ones(len(setup.holes0), bool) if mask is None else np.asarray(mask, bool)


class _Anchored:
    """The feature model anchored on the CAD-verified holes at ``x0`` (when the trust-region loop gave them):
    ``features(x) = verified(x0) + model(x) − model(x0)``, so a nonlinear part's small shop rounding is
    predicted around the real optimum, not around the linearisation point."""

    def __init__(self, model: Any, x0: np.ndarray, verified: Sequence[Any] | None) -> None:
        from cadfeat.cad.features import holes_to_arrays

        self.model, self.holes = model, model.holes
        c0, _, r0 = model.features(x0)
        self.dc, self.dr = np.zeros_like(c0), np.zeros_like(r0)
        if verified is not None and len(verified) == len(r0):
            cv, _, rv = holes_to_arrays(list(verified))
            self.dc, self.dr = cv - c0, rv - r0

    def features(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        c, a, r = self.model.features(x)
        return c + self.dc, a, r + self.dr

    def features_batch(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        c, a, r = self.model.features_batch(X)
        return c + self.dc, a, r + self.dr

    def holes_at(self, x: np.ndarray) -> list[Any]:
        c, a, r = self.features(x)
        return [dataclasses.replace(h, centre=np.asarray(c[i]), axis=np.asarray(a[i]), radius_mm=float(r[i]))
                for i, h in enumerate(self.holes)]


def _off_target(holes: Sequence[Any], targets: Any) -> float:
    """Largest distance (mm) of the rebuilt holes' centres and diameters from the shop targets."""
    from cadfeat.cad.features import holes_to_arrays

    c, _, r = holes_to_arrays(list(holes))
    return float(max(np.abs(c - targets.target_centres).max(initial=0.0),
                     np.abs(2 * r - targets.target_diameters).max(initial=0.0)))


def _shop_refine(setup: StudySetup, x: np.ndarray, rebuilt: tuple[Any, list[Any], float], targets: Any,
                 info: dict[str, Any], model: Any, rounds: int = 6) -> tuple[np.ndarray, Any, list[Any], float]:
    """Where the feature model is only a linearisation (a nonlinear part script), the rebuilt holes may miss the
    grid/table targets: up to ``rounds`` Newton steps on the real CAD rebuild (model Jacobian, the rebuilt
    holes' error), each kept only if it gets closer. ``info["rebuilt_off_target_mm"]``: what remains."""
    from cadfeat.design.shop import _jacobian

    shape, holes, err = rebuilt
    off = _off_target(holes, targets)
    for _ in range(rounds):
        if off <= 1e-6:
            break
        from cadfeat.cad.features import holes_to_arrays

        c, _, r = holes_to_arrays(holes)
        resid = np.concatenate([(targets.target_centres - c).reshape(-1), (targets.target_diameters / 2 - r)])
        step = np.linalg.lstsq(_jacobian(model, x), resid, rcond=None)[0]
        x_new = setup.space.snap(setup.space.clip(x + step))
        if np.asarray(setup.problem.constraints(x_new), float).min(initial=0.0) < -1e-9:
            break
        try:
            cand = _rebuild(setup, x_new, [dataclasses.replace(h, centre=h.centre + d, radius_mm=h.radius_mm + e)
                                           for h, d, e in zip(holes, model.features(x_new)[0] - model.features(x)[0],
                                                              model.features(x_new)[2] - model.features(x)[2],
                                                              strict=True)])
        except CadfeatError:
            break
        off_new = _off_target(cand[1], targets)
        if off_new >= off:
            break
        x, (shape, holes, err), off = x_new, cand, off_new
    info["rebuilt_off_target_mm"] = off
    info["x_shop"] = dict(zip(setup.space.names, map(float, x), strict=True))
    return x, shape, holes, err


def _shop(setup: StudySetup, x: np.ndarray, model: Any = None) -> tuple[np.ndarray, dict[str, Any], Any]:
    """The shop-ready design near the optimum ``x`` (``cadfeat.design.shop``, study ``[shop]``) and its
    results.json block; the optimum itself when rounding would break a kept requirement of the model (the
    rebuilt design is verified on the B-rep and the STEP either way)."""
    from cadfeat.design.shop import hole_sizes, shop_design

    spec = setup.config.shop
    sizes = hole_sizes(spec.hole_sizes)
    info: dict[str, Any] = {"grid_mm": spec.grid_mm, "hole_sizes": spec.hole_sizes if isinstance(spec.hole_sizes, str)
                            else list(spec.hole_sizes), "applied": False, "notes": []}
    if spec.grid_mm <= 0 and not sizes:
        info["notes"].append("rounding off ([shop] grid_mm = 0, hole_sizes = \"none\")")
        return x, info, None
    sd = shop_design(setup.space, model if model is not None else setup.model, x, grid_mm=spec.grid_mm, sizes=sizes,
                     problem=setup.problem)
    info["notes"] += sd.notes
    margins = np.asarray(setup.problem.constraints(sd.x), float)
    names = setup.space.names
    info.update(x_optimum=dict(zip(names, map(float, x), strict=True)),
                x_shop=dict(zip(names, map(float, sd.x), strict=True)), residual_mm=sd.residual_mm,
                moved=[h for h, m in zip(setup.hole_names, sd.moved, strict=True) if m],
                resized=[h for h, m in zip(setup.hole_names, sd.resized, strict=True) if m])
    if setup.config.objective.combine != "pareto":
        info.update(combined_optimum=float(setup.problem.combined(x)),
                    combined_shop=float(setup.problem.combined(sd.x)))
    if margins.size and margins.min() < -1e-9:
        labels = setup.problem.constraint_labels()
        k = int(np.argmin(margins))
        info["notes"].append(f"rounding would break {labels[k][0]} {'/'.join(labels[k][1])} (margin "
                             f"{margins[k]:.3g}); the optimiser's design is delivered unrounded")
        return x, info, None
    info["applied"] = True
    return sd.x, info, sd


def _robustness(setup: StudySetup, holes0: Sequence[Any], holes1: Sequence[Any],
                combined_before: float | None) -> dict[str, Any] | None:
    """Objective drops of the delivered design under the study's ``[robustness]`` tolerances (sampled on
    features, ``cadfeat.design.robustness``); the holes the shop makes anew are the moved or resized ones."""
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.design.robustness import robustness
    from cadfeat.design.shop import hole_sizes

    spec = setup.config.robustness
    if spec.samples <= 0 or len(holes0) != len(holes1):
        return None
    c0, _, r0 = holes_to_arrays(list(holes0))
    c1, a1, r1 = holes_to_arrays(list(holes1))
    changed = (np.linalg.norm(c1 - c0, axis=1) > 1e-6) | (np.abs(r1 - r0) > 1e-6)
    return robustness(setup.problem, c1, a1, r1, changed, position_tol_mm=spec.position_tol_mm,
                      size_steps=spec.size_steps, sizes=hole_sizes(setup.config.shop.hole_sizes),
                      camera_position_mm=spec.camera_position_mm, camera_angle_deg=spec.camera_angle_deg,
                      samples=spec.samples, combined_before=combined_before, seed=setup.config.study.seed)


def _patterns(base: StudySetup, holes1: Sequence[Any]) -> list[dict[str, Any]]:
    """The original's hole patterns with a movable hole (``cadfeat.design.patterns``), each with ``broken``."""
    from cadfeat.design.patterns import check_patterns, find_patterns

    movable = np.asarray(base.movable_mask, bool)
    found = [p for p in find_patterns(base.holes0) if movable[list(p.holes)].any()]
    return check_patterns(found, list(holes1), base.hole_names) if len(holes1) == len(base.holes0) else []


def _requirements_used(setup: StudySetup, x: np.ndarray) -> list[dict[str, Any]]:
    """The kept requirements the optimiser's model used (kind, hole names, its 2-D margin at ``x``): the report
    checks that each one was verified on the rebuilt geometry."""
    labels = setup.problem.constraint_labels()
    margins = np.asarray(setup.problem.constraints(x), float).reshape(-1)
    if len(labels) != margins.size:
        return [{"name": k, "holes": list(h)} for k, h in labels]
    return [{"name": k, "holes": list(h), "margin": float(m)} for (k, h), m in zip(labels, margins, strict=True)]


def _x0_like(setup: StudySetup, base: Any) -> np.ndarray:
    """The before-values of ``setup``'s continuous variables (the part defaults, as in ``base``)."""
    return np.asarray(base.space.x0, float) if base.space.names == setup.space.names else setup.space.x0


def _version() -> str:
    from cadfeat import __version__

    return __version__


def _write_outputs(config: StudyConfig, stage: Path, results: dict[str, Any], shapes: Mapping[str, Any],
                   prog: StudyProgress) -> None:
    """Write and verify the outputs into the staging folder ``stage`` (published by the caller)."""
    from cadfeat.cad.export import (
        check_solid,
        check_stl,
        export_step,
        export_stl,
        import_step,
        shape_volume_mm3,
        stl_watertight,
        verify_step_roundtrip,
    )

    setup = shapes["setup"]
    t0 = time.perf_counter()
    problems = check_solid(shapes["shape1"])
    if problems:
        raise CadfeatError(f"{config.label}: the rebuilt optimum is not a valid solid: {'; '.join(problems[:3])}")
    for name, shape in (("original.step", shapes["shape0"]), ("optimised.step", shapes["shape1"])):
        export_step(shape, stage / name)
        normalise_step_header(stage / name, f"{config.study.name} {name[:-5]}")
    # (the rebuild's holes extracted the way verify_step_roundtrip extracts them: no preferred direction)
    trip = verify_step_roundtrip(stage / "optimised.step", _extract_plain(shapes["shape1"]),
                                 tol_mm=ROUNDTRIP_TOL_MM, expected_volume_mm3=shape_volume_mm3(shapes["shape1"]),
                                 volume_rtol=1e-7)
    reimported = import_step(stage / "optimised.step")
    step_holes = _order_like(shapes["holes1"], setup.rebuild_holes(reimported), 1e-3, "re-imported STEP")
    step_checks = _checks(setup, reimported, step_holes, "step")
    results["constraints"] = results["constraints"] + step_checks
    _fail_on(results["constraints"], config.label)
    export_stl(shapes["shape1"], stage / "optimised.stl")
    stl_problems = check_stl(stage / "optimised.stl", shapes["shape1"],
                             original=shapes["shape0"] if config.study.part_kind == "step" else None)
    if stl_problems:
        raise CadfeatError(f"{config.label}: optimised.stl: {'; '.join(stl_problems[:3])}")
    results["verification"] = {
        "step_roundtrip_max_error_mm": max(trip.max_centre_error_mm, trip.max_radius_error_mm,
                                           trip.max_depth_error_mm),
        "step_roundtrip_max_axis_error_rad": trip.max_axis_error_rad, "brep_valid": True,
        "stl_watertight": stl_watertight(stage / "optimised.stl"), "tolerance_mm": ROUNDTRIP_TOL_MM}
    from cadfeat.report.holes import write_holes_csv

    write_holes_csv(stage / "holes.csv", plain(results))
    results["files"] = [file_entry(stage / n, stage) for n in ("original.step", "optimised.step", "optimised.stl",
                                                                 "holes.csv")]
    results["timings_s"] = {**prog.timings, "export": time.perf_counter() - t0}
    results["versions"] = versions()
    if config.tracking is not None:  # [tracking]: the closed loop on both designs (cadfeat.vision)
        from cadfeat.study.tracking import run_tracking

        with prog.phase("tracking"):
            results["tracking"] = run_tracking(config, {"before": (shapes["shape0"], shapes["holes0"]),
                                                        "after": (shapes["shape1"], shapes["holes1"])}, stage)
    write_json(stage / "results.json", results)
    _report(stage, results, shapes, prog)


def _extract_plain(shape: Any) -> list[Any]:
    from cadfeat.cad.features import extract_holes

    return extract_holes(shape)


def _report(stage: Path, results: dict[str, Any], shapes: Mapping[str, Any], prog: StudyProgress) -> None:
    """``cadfeat.report.write_report`` if that module exists (the report helper's)."""
    if importlib.util.find_spec("cadfeat.report") is None:
        return
    from cadfeat import report

    setup = shapes["setup"]
    fixed = getattr(setup, "fixed_mask", None)
    context = report.ReportContext(  # camera views at each hole's worst pose (the report's default)
        shape_before=shapes["shape0"], shape_after=shapes["shape1"], holes_before=shapes["holes0"],
        holes_after=shapes["holes1"], fixed_mask=np.asarray(fixed, bool), camera=setup.camera,
        trajectory=setup.trajectory, T_task_part=setup.T_task_part)
    with prog.phase("report"):
        report.write_report(stage, plain(results), context)


# ------------------------------------------------------------------------------------------ evaluate
def evaluate_study(path_or_dict: Any, out_dir: str | Path | None = None, *, pose: int | None = None,
                   quiet: bool = True, echo: bool = False, seed: int | None = None,
                   force: bool = False) -> dict[str, Any]:
    """Score the study's current design without optimising (the thesis GUI's single-pose mode when ``pose``
    is given: one trajectory sample). Returns the results dict; prints the per-feature table (thesis
    Table 5.1: FOV, focus, resolution margins, visibility, worst pose) and a per-pose summary when ``echo``;
    writes results.json (+ report) into ``out_dir`` if given (checked before any work, as by ``run_study``;
    ``force``: add the files to a folder cadfeat did not create)."""
    from cadfeat.cad.output_folder import staged_output
    from cadfeat.cad.parts import build_time_limit

    config = _resolve(path_or_dict, seed)
    with contextlib.ExitStack() as stack:
        stage = stack.enter_context(staged_output(out_dir, force)) if out_dir is not None else None
        stack.enter_context(build_time_limit(config.study.build_timeout_s))
        results = _evaluate(config, stage, pose, quiet, echo)
    return results


def _evaluate(config: StudyConfig, stage: Path | None, pose: int | None, quiet: bool, echo: bool) -> dict[str, Any]:
    from cadfeat.study.setup import load_scene, score_rule, setup_study

    with StudyProgress(config.study.name, enabled=not quiet) as prog:
        with prog.phase("setup"):
            camera, traj, T_task_part = load_scene(config)
            if pose is not None and not 0 <= pose < len(traj):
                raise StudyError(f"{config.label}: --pose {pose}: allowed: 0..{len(traj) - 1} "
                                 f"(the trajectory has {len(traj)} samples)")
            setup = setup_study(config)  # the same holes, names, scored holes and occlusion mesh as ``run``
            shape, holes, fixed, names = setup.shape0, setup.holes0, setup.fixed_mask, setup.hole_names
        full_traj = traj
        if pose is not None:
            traj = _single_pose(traj, pose)
        with prog.phase("measures"):
            m = measure_holes(setup, holes, traj)
            values = _plain_objectives(config, m, setup.problem)
            pre = _preflight(config, setup, m if pose is None else measure_holes(setup, holes, full_traj))
            trust = objective_changes(setup.problem, values, None) if pose is None else {}
            combined = float(setup.problem.combined_from(np.array([values[n] for n in setup.problem.names]))) \
                if pose is None and config.objective.combine != "pareto" else None
        summary = measures_summary(m, names, traj.times_s, config.objective.min_axis_px, _half_image(camera))
        if pose is not None:  # pose indices of the full trajectory
            for f in summary["per_feature"]:
                f["worst_pose"] = pose
        results = {
            "schema_version": SCHEMA_VERSION, "cadfeat_version": _version(), "created": now_iso(),
            "evaluation_only": True,
            "study": {"name": config.study.name, "file": str(config.file) if config.file else None,
                      "part": config.study.part, "part_kind": config.study.part_kind, "seed": config.study.seed,
                      "description": config.study.description},
            "inputs": config.to_dict(), "camera": camera.to_dict(),
            "trajectory": {**_trajectory_info(traj), "kind": config.trajectory.table.get("kind", "csv"),
                           "pose": pose},
            "holes": {"before": [hole_dict(h, i, fixed[i], setup.movable_mask[i]) for i, h in enumerate(holes)]},
            "objectives": {"names": list(values), "combine": config.objective.combine,
                           "aggregate": config.objective.aggregate, "before": values, "combined_before": combined,
                           **trust, "score": score_rule(config, holes, _scored(setup)),
                           "occlusion": bool(config.objective.occlusion)},
            "measures": {"before": summary}, "timings_s": dict(prog.timings), "versions": versions(),
            "preflight": pre.to_dict(), "warnings": list(pre.warnings),
        }
    if echo:
        print(format_table(results, pose))
    if stage is not None:
        write_json(stage / "results.json", results)
        same = {**results,
                "holes": {"before": results["holes"]["before"], "after": results["holes"]["before"]},
                "measures": {"before": summary, "after": summary},
                "objectives": {**results["objectives"], "after": values}}
        shapes = {"shape0": shape, "shape1": shape, "holes0": holes, "holes1": holes,
                  "setup": _EvalSetup(config, camera, full_traj, T_task_part, holes, fixed)}
        _report(stage, same, shapes, prog)
    return plain(results)


@dataclass
class _EvalSetup:
    config: StudyConfig
    camera: Any
    trajectory: Any
    T_task_part: np.ndarray
    holes0: list[Any]
    fixed_mask: np.ndarray


def _current_design(config: StudyConfig) -> tuple[Any, list[Any], np.ndarray, list[str]]:
    """The part as it is (defaults / the STEP file): solid, holes, fixed mask (STEP: holes not in the design;
    scripts: the holes the script declares functional)."""
    if config.study.part_kind == "step":
        from cadfeat.cad.step_parts import load_step

        step = load_step(config.study.part_path)
        holes = list(step.holes)
        fixed = np.ones(len(holes), bool)
        for h in config.design.holes:
            with contextlib.suppress(CadfeatError):
                fixed[holes.index(step.select(list(h.select) if isinstance(h.select, tuple) else h.select))] = False
        return step.shape, holes, fixed, [h.name for h in holes]
    from cadfeat.cad.parts import load_part

    part = load_part(config.study.part_path)
    shape = part.build()
    holes = part.holes()
    fixed = np.asarray(part.fixed_mask(holes), bool)
    return shape, holes, fixed, [h.name or f"H{i + 1}" for i, h in enumerate(holes)]


def _single_pose(traj: Any, k: int) -> Any:
    """A one-sample view of a trajectory at sample ``k`` (with the full trajectory's velocity screw there)."""
    return _OnePose(traj, k)


class _OnePose:
    """A trajectory view with exactly one sample (``len == 1``), for single-pose evaluation."""

    def __init__(self, traj: Any, k: int) -> None:
        self.T_task_cam = np.asarray(traj.T_task_cam)[k:k + 1]
        self.times_s = np.asarray(traj.times_s)[k:k + 1]
        self._screws = np.asarray(traj.velocity_screws())[k:k + 1]
        self.name = getattr(traj, "name", "")
        self.duration_s = 0.0

    def __len__(self) -> int:
        return 1

    def velocity_screws(self) -> np.ndarray:
        return self._screws


def _plain_objectives(config: StudyConfig, m: Any, problem: Any) -> dict[str, float]:
    """The aggregated objectives of measures ``m`` exactly as the optimiser scores them (the problem's scored
    holes ``feature_mask`` and natural units for the smooth min)."""
    from cadfeat.design.objectives import objective_values

    return objective_values(m, config.objective, problem.units, problem.feature_mask)


def format_table(results: Mapping[str, Any], pose: int | None = None) -> str:
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
                      _num(f["resolution_px_min"]), f"{100 * f['visible_frac']:.0f}%", str(f["worst_pose"]))
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
        console.print(f"{name} = {_num(g)} ({results['objectives']['aggregate']} over the trajectory)")
    return buffer.getvalue().rstrip()
