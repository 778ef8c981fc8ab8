"""From a validated ``StudyConfig`` to everything the optimiser and the exporter need (docs/design.md "Data flow").

``setup_study(config)`` loads the part (a CadQuery script via ``cadfeat.cad.parts.load_part`` or a STEP file via
``cadfeat.cad.step_parts.load_step``), the camera, the trajectory and the part pose, then builds the design
space and the feature model:

- script parts: the geometric design matrix of the varying parameters (``design_map``: finite differences
  of real CAD rebuilds) → ``LinearFeatureModel``; integer parameters are NOT variables of the continuous
  optimiser (a hole count changes the topology): the study enumerates their values (``int_grid``) and
  builds one setup per combination;
- STEP parts: the selected holes → ``HoleMoveModel`` (in-plane offsets (s, t) mm in the host face frame,
  optionally the diameter), patterns moving together, mirror pairs for ``constraints.symmetry``.

Holes that no variable moves, and the holes listed in ``design.fixed``, are fixed (``fixed_mask``); a fixed
hole that a design parameter moves is a ``StudyError``.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple, Protocol

import numpy as np

from cadfeat.cad.design_map import design_map, reference_design_map
from cadfeat.cad.export import import_step, mesh_from_shape, shape_volume_mm3
from cadfeat.cad.features import extract_holes
from cadfeat.cad.features.identity import hole_name, hole_names
from cadfeat.cad.parts import load_part
from cadfeat.cad.sandbox import call_with_time_limit
from cadfeat.cad.step_parts import dry_run, load_step, redrill
from cadfeat.design.constraints import ConstraintConfig, SymmetryPair
from cadfeat.design.design_space import DesignSpace, HoleMoveModel, LinearFeatureModel, Variable
from cadfeat.design.hole_form import variable_kind
from cadfeat.design.patterns import find_patterns
from cadfeat.design.problem import Problem
from cadfeat.errors import CadfeatError
from cadfeat.measures.raycache import cache_rays
from cadfeat.study.schema import StudyConfig, StudyError

if TYPE_CHECKING:  # pragma: no cover
    import trimesh
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.cad.parts import Part
    from cadfeat.cad.step_parts import HoleMove, StepPart
    from cadfeat.cad.tolerance import ModelTolerance
    from cadfeat.camera import Camera
    from cadfeat.design.constraints import ConstraintConfig
    from cadfeat.design.design_space import DesignSpace, FeatureModel
    from cadfeat.design.objectives import Normaliser
    from cadfeat.design.problem import Problem
    from cadfeat.measures.glare import GlareMaps
    from cadfeat.study.settings.design import DesignSpec, Selector
    from cadfeat.trajectory import Trajectory

__all__ = ["MAX_INT_COMBINATIONS", "ProblemPieces", "Scene", "ScriptValues", "StudySetup", "build_problem",
           "int_grid", "script_rebuilders", "setup_study", "step_rebuilders"]

MAX_INT_COMBINATIONS = 64
"""Largest number of integer-parameter combinations a study enumerates."""
SYMMETRY_NORMALS = {"x": [(1.0, 0.0, 0.0)], "y": [(0.0, 1.0, 0.0)], "xy": [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]}


class Scene(NamedTuple):
    """A study's scene (``load_scene``): its camera, the trajectory (``T_task_cam``) and where the part sits in the
    task frame (``T_task_part`` (4, 4), mm); unpacks as the (camera, trajectory, T_task_part) it replaces."""

    camera: Camera
    trajectory: Trajectory
    T_task_part: np.ndarray


class CacheRecord(Protocol):
    """What a set-up tells of its place in the set-up cache (``setup_cache.CacheEntry``, which keeps the rest): its
    key, whether it was read from the cache, and the seconds the fresh set-up took."""

    @property
    def key(self) -> str: ...

    @property
    def hit(self) -> bool: ...

    @property
    def setup_s(self) -> float: ...


@dataclass
class StudySetup:
    """The loaded study: part, camera, trajectory, design space, feature model, problem.

    ``rebuild_shape(x)`` is the real CAD model at design ``x``; ``rebuild_holes(x)`` its extracted holes;
    ``values(x)`` the design as named values (part parameters for scripts, with integers as ``int``).
    """

    config: StudyConfig
    camera: Camera
    trajectory: Trajectory          # T_task_cam
    T_task_part: np.ndarray
    shape0: Shape                   # cq.Solid
    holes0: list[Hole]
    fixed_mask: np.ndarray          # (N,) bool
    movable_mask: np.ndarray        # (N,) bool
    space: DesignSpace
    model: FeatureModel
    problem: Problem
    constraints: ConstraintConfig
    rebuild_shape: Callable[[np.ndarray], Shape]
    rebuild_holes: Callable[[Shape], list[Hole]]
    values: Callable[[np.ndarray], Mapping[str, object]]
    linear: bool = True
    int_values: dict[str, int] = field(default_factory=dict[str, int])
    part: Part | StepPart | None = None
    time_limit_s: float | None = None
    """The time limit of each CAD rebuild (s, a worker process); None: in this process (``setup_study``)."""
    view_direction: np.ndarray | None = None
    """(3,) unit vector, part frame, from the part towards the camera (``study_view_direction``): the end of a
    through hole that is its entrance, in set-up, rebuilds and every check alike; None: extraction's own rule."""
    cache_entry: CacheRecord | None = field(default=None, repr=False, compare=False)
    """Where the set-up cache keeps this set-up (``setup_cache.CacheEntry``), None when it was not cached."""

    @property
    def hole_names(self) -> list[str]:
        return hole_names(self.holes0)


# ----------------------------------------------------------------------------------------- common
def load_scene(config: StudyConfig) -> Scene:
    """Camera, trajectory (T_task_cam) and T_task_part of a study."""
    return Scene(config.camera.build(), config.trajectory.build(), config.part_pose.T_task_part)


def constraint_config(config: StudyConfig, holes: Sequence[Hole] = (), movable: Sequence[int] | np.ndarray = (),
                      volume_mm3: float | None = None, mirror_tol_mm: float = 1e-6) -> ConstraintConfig:
    """``constraints.ConstraintConfig`` of a study; ``symmetry`` becomes the mirror pairs among the movable
    ``holes`` (about the part's x = 0 / y = 0 planes); ``volume_mm3`` is the original part volume."""
    c = config.constraints
    frac = None if c.volume_change_max_percent is None else c.volume_change_max_percent / 100.0
    pairs = tuple(SymmetryPair(i, j, (0.0, 0.0, 0.0), normal)
                  for i, j, normal in _mirror_pairs(holes, movable, (), c.symmetry, tol_mm=mirror_tol_mm))
    if c.symmetry != "none" and not pairs:
        raise StudyError(f"{config.label}: constraints.symmetry: no two movable holes mirror each other about the "
                         f"plane(s) {c.symmetry} = 0 of the part; allowed: none, or a symmetry the part has")
    return ConstraintConfig(edge_distance_mm=c.edge_distance_mm, ligament_mm=c.ligament_mm,
                            volume_change_max_frac=frac, part_volume_mm3=volume_mm3, symmetry=pairs)


@dataclass(frozen=True)
class ProblemPieces:
    """What ``build_problem`` builds a set-up's ``Problem`` from besides the study: its design space and feature
    model, the scene (camera, trajectory, ``T_task_part``) and the fixed holes' mask (a fresh set-up's or one read
    from the set-up cache)."""

    space: DesignSpace
    model: FeatureModel
    camera: Camera
    trajectory: Trajectory
    T_task_part: np.ndarray
    fixed_mask: np.ndarray


@dataclass(frozen=True)
class _ProblemParts(ProblemPieces):
    """What ``_problem`` builds the ``Problem`` from (a script part's set-up or a STEP part's): the pieces, the
    part's holes and solid (and a STEP part)."""

    holes: list[Hole]
    shape0: Shape
    part: StepPart | None = None

    def pieces(self) -> ProblemPieces:
        return ProblemPieces(self.space, self.model, self.camera, self.trajectory, self.T_task_part, self.fixed_mask)


def _problem(args: _ProblemParts, config: StudyConfig, normaliser: Normaliser | None = None
             ) -> tuple[Problem, ConstraintConfig]:
    """The ``Problem`` and its ``ConstraintConfig`` (``normaliser``: share another problem's scales)."""
    movable = np.flatnonzero(~np.asarray(args.fixed_mask, bool))
    part = args.part
    tol = max(1e-6, 10 * part.tolerance.linear_mm) if part is not None else 1e-6
    cc = constraint_config(config, args.holes, movable, shape_volume_mm3(args.shape0), mirror_tol_mm=tol)
    problem = build_problem(config, args.pieces(), cc, occlusion_mesh(config, args.shape0),
                            score_mask(config, args.holes, ~np.asarray(args.fixed_mask, bool)), normaliser)
    glare = glare_maps_for(config, args.shape0, args.holes, args.camera, problem.T_cam_part)
    if glare is not None:
        problem.set_glare(glare)
    return problem, cc


def build_problem(config: StudyConfig, args: ProblemPieces, cc: ConstraintConfig, mesh: trimesh.Trimesh | None,
                  feature_mask: np.ndarray | None, normaliser: Normaliser | None = None) -> Problem:
    """The set-up's ``Problem`` from its pieces (``args``: space, model, camera, trajectory, T_task_part,
    fixed_mask): the one constructor of a fresh set-up and of one read from the set-up cache (which sets the glare
    maps it kept, ``glare_maps_for``'s)."""
    return Problem(args.space, args.model, args.camera, args.trajectory, args.T_task_part,
                   config.objective, cc, args.fixed_mask, normaliser=normaliser, occlusion_mesh=mesh,
                   feature_mask=feature_mask, cell=config.cell)


def glare_maps_for(config: StudyConfig, shape: Shape, holes: Sequence[Hole], camera: Camera,
                   T_cam_part: np.ndarray) -> GlareMaps | None:
    """g_POSE's glare maps (``measures.glare``; ``render.glare.glare_maps``: the part rendered physically in the
    study's cell at its poses) when the study predicts the pose (``pose`` among the measures), its ``[cell]`` asks
    (``glare``, default on) and the part's material returns light from its bores (a metal); else None."""
    from cadfeat.cell.material import bores_return_light

    cell = config.cell
    if "pose" not in config.objective.measures or not cell.glare or not bores_return_light(cell.material):
        return None
    from cadfeat.render.glare import glare_maps  # lazy: Mitsuba

    return glare_maps(shape, holes, camera, T_cam_part, cell)


def occlusion_mesh(config: StudyConfig, shape: Shape) -> trimesh.Trimesh | None:
    """The part's triangle mesh (part frame, mm) for the occlusion ray test (``objective.occlusion``, default
    on), or None. Built once per setup from the part as loaded; each hole's OWN position (as the design moves
    it) is tested against it, so a hole moved behind an upright is hidden, one moved out from behind it seen.
    Its exact ray tests keep their answers ray by ray (``measures.raycache.cache_rays``: the same numbers; a study
    asks for the original's rim rays in its measures, its score and its pose prediction)."""
    if not getattr(config.objective, "occlusion", True):
        return None
    return cache_rays(mesh_from_shape(shape, tolerance=0.05))


def score_mask(config: StudyConfig, holes: Sequence[Hole], movable: np.ndarray) -> np.ndarray:
    """(N,) bool: the holes whose FOV/focus/resolution are scored (``objective.score``): "movable" (default;
    every hole when none moves), "all", or a list of hole names (``H<i>`` or the part's own names) — the same
    rule in ``evaluate`` and ``run``."""
    rule = getattr(config.objective, "score", "movable")
    n = len(holes)
    if rule == "all":
        return np.ones(n, bool)
    if rule == "movable":
        movable = np.asarray(movable, bool)
        return movable.copy() if movable.any() else np.ones(n, bool)
    names = hole_names(holes)
    mask = np.zeros(n, bool)
    for name in rule:
        hits = [i for i in range(len(holes)) if name in (names[i], f"H{i + 1}")]
        if not hits:
            raise StudyError(f"{config.label}: objective.score: no hole named {name!r} in {config.study.part}; "
                             f"allowed: \"movable\", \"all\" or names from {', '.join(names)}")
        mask[hits[0]] = True
    return mask


def score_rule(config: StudyConfig, holes: Sequence[Hole], mask: np.ndarray) -> str:
    """One line naming the scored holes and the rule that chose them (output and report)."""
    rule = getattr(config.objective, "score", "movable")
    names = hole_names(holes)
    label = rule if isinstance(rule, str) else "names"
    return f"objective.score = {label}: " + ", ".join(n for n, m in zip(names, mask, strict=True) if m)


def _select(config: StudyConfig, holes: Sequence[Hole], spec: Selector, key: str, tol_mm: float = 0.01) -> int:
    """Index of the hole a selector names: 1-based index, name ("H2" or the hole's name), or position."""
    listing = ", ".join(f"{h.name or f'H{i + 1}'} ({', '.join(f'{x:.6g}' for x in h.centre)})"
                        for i, h in enumerate(holes)) or "none"
    if isinstance(spec, int):
        if 1 <= spec <= len(holes):
            return spec - 1
    elif isinstance(spec, str):
        for i, h in enumerate(holes):  # the hole's own name first (names are not positions in the list)
            if h.name and spec in (h.name, h.name.lower()):
                return i
        for i, h in enumerate(holes):
            if not h.name and spec in (f"H{i + 1}", f"h{i + 1}", str(i + 1)):
                return i
    else:
        centres = np.array([h.centre for h in holes], dtype=float).reshape(-1, 3)
        if len(centres):
            d = np.linalg.norm(centres - np.asarray(spec, float), axis=1)
            if d.min() <= tol_mm:
                return int(np.argmin(d))
    raise StudyError(f"{config.label}: {key}: no hole {list(spec) if isinstance(spec, tuple) else spec!r} in "
                     f"{config.study.part}; allowed: a 1-based index 1..{len(holes)}, a name or a position within "
                     f"{tol_mm:g} mm of one of: {listing}")


# ----------------------------------------------------------------------------------------- scripts
def int_grid(config: StudyConfig) -> list[dict[str, int]]:
    """Every combination of the varying integer parameters (one empty dict if there are none)."""
    ints = [p for p in config.design.parameters if p.is_int]
    ranges = [range(int(p.lower), int(p.upper) + 1) for p in ints]
    combos = [dict(zip([p.name for p in ints], values, strict=True)) for values in itertools.product(*ranges)]
    if len(combos) > MAX_INT_COMBINATIONS:
        raise StudyError(f"{config.label}: design.parameters: {len(combos)} combinations of the integer parameters "
                         f"{', '.join(p.name for p in ints)}; allowed: at most {MAX_INT_COMBINATIONS} (narrow "
                         "their bounds)")
    return combos


def setup_script(config: StudyConfig, int_values: Mapping[str, int] | None = None,
                 scene: Scene | None = None, normaliser: Normaliser | None = None,
                 at: Mapping[str, float] | None = None, time_limit_s: float | None = None) -> StudySetup:
    """Setup of a part-script study with the integer parameters at ``int_values`` (default: their defaults);
    ``normaliser``: the objective scales of another setup (so that integer combinations compare); ``at``:
    linearise at these continuous parameter values instead of the part's defaults; ``time_limit_s``: as
    ``setup_study``'s."""
    camera, trajectory, T_task_part = scene or load_scene(config)
    part = load_part(config.study.part_path, time_limit_s)
    specs = [p for p in config.design.parameters if not p.is_int]
    ints = {p.name: int(p.default if p.start is None else p.start) for p in config.design.parameters if p.is_int}
    ints.update({k: int(v) for k, v in (int_values or {}).items()})
    names = [p.name for p in specs]
    linearise_at = at is not None
    starts = {p.name: float(p.start) for p in specs if p.start is not None}  # [design.parameters] NAME.start
    at = {**part.defaults(), **ints, **starts, **{k: float(v) for k, v in (at or {}).items() if k in names}}

    values = ScriptValues(dict(at), tuple(names), frozenset(n for n in names if part.parameters[n].is_int))
    shape0 = part.build(**at)
    view = study_view_direction(config, shape0, trajectory, T_task_part, part)
    part = dataclasses.replace(part, view_direction=view)  # every extraction of the part enters on the camera's side
    if not names:  # only integer parameters vary: nothing continuous to optimise at this combination
        raise StudyError(f"{config.label}: design.parameters: only integer parameters "
                         f"({', '.join(ints)}) vary; allowed: at least one continuous parameter of {config.study.part}")
    if linearise_at:  # the optimum of an earlier round: linearise there
        dm = design_map(part, names, at=at)
        holes0 = list(dm.holes0)
    else:  # a reference design that does not depend on the part's current values (issue 16)
        dm, holes0 = reference_design_map(part, names, at, [p.lower for p in specs], [p.upper for p in specs])
    x0 = np.array([float(at[n]) for n in names])
    model = LinearFeatureModel.from_design_map(dm, names, [float(dm.at[n]) for n in names])
    variables: list[Variable] = []
    for p in specs:
        j = names.index(p.name)
        dB, dD = (None if m is None else np.asarray(m)[:, j] for m in (dm.dB, dm.dD))
        kind = variable_kind(np.asarray(dm.dR)[:, j], dB, dD, through=[h.through for h in dm.holes0],
                             plain=[h.base_kind == "plain" for h in dm.holes0])
        variables.append(Variable(p.name, float(p.lower), float(p.upper), p.unit or "mm", kind, p.standard_sizes))
    space = DesignSpace(variables, np.clip(x0, [v.lower for v in variables], [v.upper for v in variables]))
    moved = np.zeros(len(holes0), bool)
    for name in names:
        moved[list(dm.moved_by.get(name, []))] = True
    fixed = ~moved
    declared = np.asarray(part.fixed_mask(holes0, at), bool) if hasattr(part, "fixed_mask") else fixed & False
    for j in np.flatnonzero(declared & moved):
        movers = [n for n in names if j in dm.moved_by.get(n, [])]
        raise StudyError(f"{config.label}: design.parameters: {', '.join(movers)} would move hole "
                         f"{holes0[j].name or j + 1}, which {config.study.part} declares functional (fixed); "
                         f"allowed: parameters that move only free holes ({part.fixed_holes or 'see the script'})")
    for i, spec in enumerate(config.design.fixed):
        j = _select(config, holes0, spec, f"design.fixed[{i}]")
        if moved[j]:
            movers = [n for n in names if j in dm.moved_by.get(n, [])]
            raise StudyError(f"{config.label}: design.fixed[{i}]: hole {holes0[j].name or j + 1} is moved by the "
                             f"design parameter(s) {', '.join(movers)}; allowed: holes no design parameter moves")
        fixed[j] = True
    args = _ProblemParts(space=space, model=model, camera=camera, trajectory=trajectory, T_task_part=T_task_part,
                         fixed_mask=fixed, holes=holes0, shape0=shape0)
    problem, cc = _problem(args, config, normaliser)
    rebuild_shape, rebuild_holes = script_rebuilders(lambda: part, values, view)
    return StudySetup(config=config, camera=camera, trajectory=trajectory, T_task_part=T_task_part, shape0=shape0,
                      holes0=holes0, fixed_mask=fixed, movable_mask=moved, space=space, model=model,
                      problem=problem, constraints=cc, rebuild_shape=rebuild_shape, rebuild_holes=rebuild_holes,
                      values=values, linear=bool(getattr(dm, "linear", True)), int_values=ints, part=part,
                      time_limit_s=time_limit_s, view_direction=view)


@dataclass(frozen=True)
class ScriptValues:
    """``StudySetup.values`` of a part-script study: the design vector x as the part's named values — the values
    the set-up linearised at, with the design variables (``names``, in x's order) replaced (``ints``: cast to
    int). A class, not a closure, so that a set-up's products can be kept in the set-up cache."""

    at: dict[str, float]
    names: tuple[str, ...]
    ints: frozenset[str] = frozenset()

    def __call__(self, x: np.ndarray) -> dict[str, float]:
        out = dict(self.at)
        for name, value in zip(self.names, np.asarray(x, float).reshape(-1), strict=True):
            out[name] = int(round(value)) if name in self.ints else float(value)
        return out


def script_rebuilders(part: Callable[[], Part], values: Callable[[np.ndarray], Mapping[str, object]],
                      view: np.ndarray | None) -> tuple[Callable[[np.ndarray], Shape], Callable[[Shape], list[Hole]]]:
    """(``rebuild_shape``, ``rebuild_holes``) of a part-script set-up; ``part()`` gives the loaded part (the set-up
    cache loads it on first use)."""
    return (lambda x: part().build(**values(x))), (lambda shape: _extract(shape, view))


def step_rebuilders(config: StudyConfig, step: Callable[[], StepPart], model: HoleMoveModel,
                    view: np.ndarray | Sequence[float] | None, time_limit_s: float | None
                    ) -> tuple[Callable[[np.ndarray], Shape], Callable[[Shape], list[Hole]]]:
    """(``rebuild_shape``, ``rebuild_holes``) of a STEP set-up: re-drilled within the time limit; holes extracted
    as the part was read (the same entrance side and tolerances), named H1.. in extraction order."""

    def rebuild_holes(shape: Shape) -> list[Hole]:
        holes = _extract(shape, view, step().tolerance)
        return [dataclasses.replace(h, name=f"H{i + 1}") for i, h in enumerate(holes)]

    return (lambda x: _timed_redrill(config, step(), model.hole_moves(x), time_limit_s)), rebuild_holes


def _extract(shape: Shape, prefer_direction: Sequence[float] | np.ndarray | None = None,
             tol: ModelTolerance | None = None) -> list[Hole]:
    return extract_holes(shape, prefer_direction=prefer_direction, tol=tol)


# ----------------------------------------------------------------------------------------- STEP
def setup_step(config: StudyConfig, scene: Scene | None = None,
               time_limit_s: float | None = None) -> StudySetup:
    """Setup of a STEP study: the selected holes move in their host face planes (``HoleMoveModel``)."""
    camera, trajectory, T_task_part = scene or load_scene(config)
    view = config.design.view_direction or camera_direction(config.study.part_path, trajectory, T_task_part)
    step = load_step(config.study.part_path, prefer_direction=view)
    holes0 = list(step.holes)
    design = config.design
    movable = [_select(config, holes0, h.select, f"design.holes[{i}].select") for i, h in enumerate(design.holes)]
    if len(set(movable)) != len(movable):
        raise StudyError(f"{config.label}: design.holes: two selectors name the same hole; allowed: each hole once")
    step_dry_run(config, step, movable)
    model, space = step_design(config, step, movable)
    check_start_requirements(config, step, movable, model, space)  # as validate: refused before optimising
    movable_mask = np.zeros(len(holes0), bool)
    movable_mask[movable] = True
    fixed = ~movable_mask
    args = _ProblemParts(space=space, model=model, camera=camera, trajectory=trajectory, T_task_part=T_task_part,
                         fixed_mask=fixed, holes=holes0, shape0=step.shape, part=step)
    problem, cc = _problem(args, config)
    rebuild_shape, rebuild_holes = step_rebuilders(config, lambda: step, model, view, time_limit_s)
    return StudySetup(config=config, camera=camera, trajectory=trajectory, T_task_part=T_task_part,
                      shape0=step.shape, holes0=holes0, fixed_mask=fixed, movable_mask=movable_mask, space=space,
                      model=model, problem=problem, constraints=cc, rebuild_shape=rebuild_shape,
                      rebuild_holes=rebuild_holes, values=space.as_dict, part=step,
                      time_limit_s=time_limit_s, view_direction=None if view is None else np.asarray(view, float))


def step_design(config: StudyConfig, step: StepPart, movable: Sequence[int]) -> tuple[HoleMoveModel, DesignSpace]:
    """The hole-move model and design space of a STEP study: fixed holes, patterns, mirror pairs, ``[shop]
    keep_patterns`` (a movable hole of a pattern whose other holes are fixed is pinned) and the offset limits."""
    holes0 = list(step.holes)
    design = config.design
    max_offsets = step_offset_limits(config, step, movable)
    fixed_idx = [_select(config, holes0, s, f"design.fixed[{i}]") for i, s in enumerate(design.fixed)]
    for i, j in enumerate(fixed_idx):
        if j in movable:
            raise StudyError(f"{config.label}: design.fixed[{i}]: hole {holes0[j].name} is also in design.holes; "
                             "allowed: fixed holes that are not movable")
    patterns = [[_select(config, holes0, s, f"design.patterns[{i}][{k}]") for k, s in enumerate(p)]
                for i, p in enumerate(design.patterns)]
    for i, p in enumerate(patterns):
        if not set(p) <= set(movable):
            raise StudyError(f"{config.label}: design.patterns[{i}]: every hole of a pattern must be in design.holes; "
                             f"allowed: holes {', '.join(holes0[j].name for j in movable)}")
    mirrors = _mirror_pairs(holes0, movable, patterns, config.constraints.symmetry,
                            tol_mm=max(1e-6, 10 * step.tolerance.linear_mm))
    pinned: list[int] = []
    if config.shop.keep_patterns:
        patterns, mirrors, pinned = _keep_patterns(holes0, movable, patterns, mirrors)
    resized = [j for spec, j in zip(design.holes, movable, strict=True) if spec.resize]
    model = HoleMoveModel(holes0, movable, diameter=resized, patterns=patterns, mirrors=mirrors)
    space = model.design_space(standard_sizes=design.standard_diameters_mm, max_offsets_mm=max_offsets)
    space = _limit_offsets(space, holes0, design, movable, pinned)
    return model, space


def _timed_redrill(config: StudyConfig, step: StepPart, moves: Sequence[HoleMove], time_limit_s: float | None
                   ) -> Shape:
    """``step_parts.redrill`` within ``time_limit_s`` (a worker process, as part-script builds; None: here)."""
    return call_with_time_limit(redrill, (step.shape, list(moves), step.tolerance, step.path),
                                f"{config.study.part_path}: re-drilling {len(moves)} hole(s)", time_limit_s)


def study_view_direction(config: StudyConfig, shape: Shape, trajectory: Trajectory, T_task_part: np.ndarray,
                         part: Part | StepPart | None = None) -> np.ndarray | None:
    """The study's view (unit vector, part frame, towards the camera) that decides which end of a through hole is
    its entrance: ``design.view_direction`` (STEP studies), else the part script's ``VIEW_DIRECTION``, else the
    mean direction from ``shape``'s bounding-box centre to the trajectory's cameras (``camera_direction``)."""
    if config.design.view_direction is not None:
        return np.asarray(config.design.view_direction, float)
    own = getattr(part, "view_direction", None)
    if own is not None:
        return np.asarray(own, float)
    return camera_direction(shape, trajectory, T_task_part)


def camera_direction(part: Path | Shape, trajectory: Trajectory, T_task_part: np.ndarray) -> np.ndarray | None:
    """Unit direction (part frame) from the part (a STEP file or a solid) towards the camera: the mean of the
    directions from the part's bounding-box centre to the trajectory's camera positions (None if they cancel
    out)."""
    box = (import_step(part) if isinstance(part, str | Path) else part).BoundingBox()
    centre = np.array([box.center.x, box.center.y, box.center.z])
    T_part_task = np.linalg.inv(np.asarray(T_task_part, float))
    cams = np.asarray(trajectory.T_task_cam, float)[:, :, 3] @ T_part_task.T
    d = cams[:, :3] - centre
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    mean = d.mean(axis=0)
    n = float(np.linalg.norm(mean))
    return mean / n if n > 1e-9 else None


def step_offset_limits(config: StudyConfig, step: StepPart, movable: Sequence[int]) -> dict[int, float]:
    """``max_offset_mm`` per movable hole index (1 µm for ``move = false``). A hole whose host face is not
    planar must give one: ``StudyError`` naming the study, the key and the part file otherwise."""
    limits: dict[int, float] = {}
    for i, (spec, j) in enumerate(zip(config.design.holes, movable, strict=True)):
        limit = 1e-3 if not spec.move else spec.max_offset_mm
        if limit is not None:
            limits[j] = float(limit)
        elif step.holes[j].outline is None:
            raise StudyError(f"{config.label}: design.holes[{i}].max_offset_mm: missing for hole {step.holes[j].name} "
                             f"of {step.path}, whose host face is not planar; allowed: a positive offset bound in mm")
    return limits


def check_step_study(config: StudyConfig) -> str:
    """What ``cadfeat validate`` adds for a STEP study: load the part (holes, entrances from the camera side),
    resolve the hole selectors, the offset limits, and dry-run every movable hole (``step_dry_run``).
    Returns a one-line summary; raises ``StudyError`` naming the study, key, hole and why."""
    _, trajectory, T_task_part = load_scene(config)
    view = config.design.view_direction or camera_direction(config.study.part_path, trajectory, T_task_part)
    step = load_step(config.study.part_path, prefer_direction=view)
    holes = list(step.holes)
    movable = [_select(config, holes, h.select, f"design.holes[{i}].select")
               for i, h in enumerate(config.design.holes)]
    if len(set(movable)) != len(movable):
        raise StudyError(f"{config.label}: design.holes: two selectors name the same hole; allowed: each hole once")
    step_offset_limits(config, step, movable)
    model, space = step_design(config, step, movable)  # before the dry run: bad selectors fail fast
    step_dry_run(config, step, movable)
    occlusion_mesh(config, step.shape)  # as run's set-up does: a part BRepMesh cannot mesh is refused now
    start = check_start_requirements(config, step, movable, model, space)
    names = ", ".join(holes[j].name for j in movable)
    return f"dry run re-drilled {names} of {step.path.name} (moved and, where asked, resized)" + start


START_SAMPLES = 4096
"""Designs drawn in the design box when the start breaks a kept requirement, to tell whether any meets it."""
PINNED_MM = 1e-2
"""A hole whose offset bounds are narrower than this (``move = false``, pinned to its pattern) does not move."""


def check_start_requirements(config: StudyConfig, step: StepPart, movable: Sequence[int], model: HoleMoveModel,
                             space: DesignSpace) -> str:
    """The kept 2-D requirements (edge distance, keep-outs, ligaments, symmetry, volume) at the start design,
    for ``cadfeat validate``: "" if the start meets them. If it breaks one, the design box is sampled
    (``START_SAMPLES`` seeded draws): ``StudyError`` naming the requirement, the holes and by how much if no
    draw meets them all (e.g. the hole is pinned: ``move = false``, or ``[shop] keep_patterns`` keeps it on its
    pattern), else a note for the summary that the optimiser has to move it."""
    from cadfeat.design.constraints import ConstraintSet

    holes = list(step.holes)
    fixed = np.ones(len(holes), bool)
    fixed[list(movable)] = False
    tol = max(1e-6, 10 * step.tolerance.linear_mm)
    cc = constraint_config(config, holes, list(movable), shape_volume_mm3(step.shape), mirror_tol_mm=tol)
    cset = ConstraintSet(holes, cc, fixed)
    x0 = np.asarray(space.x0, float)
    c0, _, r0 = model.features(x0)
    margins = cset.margins(c0, r0)
    labels = cset.labels()
    broken = sorted(((float(v), kind, names) for kind, values in margins.items()
                     for v, names in zip(np.asarray(values).reshape(-1), labels.get(kind, []), strict=False)
                     if v < 0), key=lambda b: b[0])
    if not broken:
        return ""
    text = "; ".join(f"{kind} ({', '.join(names) or '-'}) by {-v:.4g} mm" for v, kind, names in broken[:5])
    lower = np.array([v.lower for v in space.variables], float)
    upper = np.array([v.upper for v in space.variables], float)
    rng = np.random.default_rng(config.study.seed)
    X = np.concatenate([x0[None], lower + (upper - lower) * rng.random((START_SAMPLES, x0.size))])
    C, _, R = model.features_batch(X)
    worst = np.min(cset.stacked(C, R), axis=-1)
    if np.max(worst) >= 0:
        return f"; the start breaks {text}: the optimiser has to move the holes (designs within the bounds meet it)"
    width = upper - lower
    stuck = sorted({v.name.rsplit(".", 1)[0] for v, w in zip(space.variables, width, strict=True)
                    if v.kind == "position" and w < PINNED_MM})
    why = (f"; {', '.join(stuck)} cannot move (design.holes move = false, or [shop] keep_patterns keeps a hole on "
           "its pattern while the pattern's other holes are fixed)") if stuck else ""
    raise StudyError(f"{config.label}: the start design already breaks the kept requirements: {text}{why}; no "
                     f"design within the bounds meets them (the start and {START_SAMPLES} designs drawn in the design "
                     "box tried); allowed: relax constraints.edge_distance_mm / ligament_mm, widen "
                     "design.holes max_offset_mm, or let the pattern move ([shop] keep_patterns = false or all its "
                     "holes in design.holes)")


def step_dry_run(config: StudyConfig, step: StepPart, movable: Sequence[int]) -> None:
    """Re-drill every movable hole once, slightly moved (and resized where asked), before any optimisation:
    ``StudyError`` naming the study, the key, the hole and why, if one cannot be re-drilled."""
    for i, (spec, j) in enumerate(zip(config.design.holes, movable, strict=True)):
        try:
            dry_run(step, [step.holes[j]], [spec.resize])
        except CadfeatError as exc:
            raise StudyError(f"{config.label}: design.holes[{i}]: {exc}") from None


def _keep_patterns(holes: Sequence[Hole], movable: Sequence[int], patterns: list[list[int]],
                   mirrors: list[tuple[int, int, tuple[float, float, float]]]
                   ) -> tuple[list[list[int]], list[tuple[int, int, tuple[float, float, float]]], list[int]]:
    """``[shop] keep_patterns``: the bolt circles and grids of the original (``cadfeat.design.patterns``) whose
    holes are all movable move together (one shared offset: the pattern is translated); mirror pairs of movable
    holes move as mirror images; a movable hole of a pattern whose other holes are fixed is pinned (a single
    bolt moved off its circle breaks the circle). Explicit ``design.patterns`` and symmetry pairs come first."""
    mov = set(movable)
    taken = {i for p in patterns for i in p} | {i for m in mirrors for i in m[:2]}
    patterns, mirrors, pinned = list(patterns), list(mirrors), list[int]()
    for p in find_patterns(holes):
        idx = list(p.holes)
        if taken & set(idx) or not mov & set(idx):
            continue
        if set(idx) <= mov and p.kind in ("bolt_circle", "grid"):
            patterns.append(idx)
        elif set(idx) <= mov and p.kind == "opposite":  # not enforced (a mirror in the axis needs both normals)
            continue
        else:
            pinned += [i for i in idx if i in mov]
        taken |= set(idx)
    return patterns, mirrors, pinned


def _limit_offsets(space: DesignSpace, holes: Sequence[Hole], design: DesignSpec, movable: Sequence[int],
                   pinned: Sequence[int] = ()) -> DesignSpace:
    """Per-hole ``max_offset_mm`` (and ``move = false`` or ``pinned`` to keep a pattern: position pinned to
    ±1 µm) applied to the (s, t) bounds of ``HoleMoveModel.design_space``."""
    limits: dict[str, float] = {}
    for spec, j in zip(design.holes, movable, strict=True):
        label = hole_name(holes[j], j)
        limit = 1e-3 if not spec.move or j in pinned else spec.max_offset_mm
        if limit is not None:
            limits[f"{label}.s"] = limits[f"{label}.t"] = float(limit)
    variables: list[Variable] = []
    for v in space.variables:
        if v.name in limits:
            m = limits[v.name]
            v = dataclasses.replace(v, lower=max(v.lower, -m), upper=min(v.upper, m))
        variables.append(v)
    return DesignSpace(variables, space.x0)


def _mirror_pairs(holes: Sequence[Hole], movable: Sequence[int] | np.ndarray, patterns: Sequence[Sequence[int]],
                  symmetry: str, tol_mm: float = 1e-6) -> list[tuple[int, int, tuple[float, float, float]]]:
    """(leader, follower, plane normal) for movable holes that mirror each other about x = 0 / y = 0 (centres
    reflected onto each other, equal radii)."""
    pairs: list[tuple[int, int, tuple[float, float, float]]] = []
    taken = {i for p in patterns for i in p[1:]}
    for normal in SYMMETRY_NORMALS.get(symmetry, []):
        M = np.eye(3) - 2 * np.outer(normal, normal)
        for a in movable:
            for b in movable:
                if a < b and a not in taken and b not in taken and \
                        np.linalg.norm(M @ holes[a].centre - holes[b].centre) < tol_mm and \
                        abs(holes[a].radius_mm - holes[b].radius_mm) < tol_mm:
                    pairs.append((a, b, normal))
                    taken.add(b)
    return pairs


def setup_study(config: StudyConfig, int_values: Mapping[str, int] | None = None,
                time_limit_s: float | None = None) -> StudySetup:
    """The setup of a study (script or STEP part). ``time_limit_s``: the part-script import and every CAD build
    or re-drill run in a worker process killed after that many seconds (``run_study`` gives ``[study]
    build_timeout_s``); None (the default): in this process, without a limit."""
    if config.study.part_kind == "step":
        return setup_step(config, time_limit_s=time_limit_s)
    return setup_script(config, int_values, time_limit_s=time_limit_s)
