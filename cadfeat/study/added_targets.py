"""The added-target phase of a study (``[add_targets]``, issue 31): where to drill new target holes.

After the move-only optimum is delivered (rebuilt in CAD and verified), cadfeat proposes new blind holes on the
allowed faces of that design:

1. **Sites** (``design.added_targets.sites``): a grid of ``pitch_mm`` on each allowed face, kept where the rim
   keeps ``[constraints]`` edge distance to the face's edges, the ligament to every hole of the part and the
   keep-out distance to slots and pockets, and stays out of the study's keep-out boxes.
2. **Choice** (``design.added_targets.greedy``): lazy greedy by the study's g_POSE with occlusion
   (``design.added_targets.objective``: the study's camera, trajectory, cell and rotation length — the numbers of
   ``study.pose_accuracy.predict``), up to ``max_added`` holes: the curve of the predicted error against the
   number added. The recommended number is the first at which ``target_error_mm`` is reached, else the last
   whose hole lowered the error by at least ``min_gain_percent``.
3. **Joint refinement** (``design.added_targets.refine``): the recommended holes moved continuously in their faces
   together with the study's position variables (``movable``: the movable holes through the feature model); when
   a variable moved, the part is rebuilt at the refined design (``_base_design``).
4. **CAD** (``cad.drill_targets``): the holes cut into the delivered solid (a part script's after ``build``, a STEP
   part's B-rep), verified (volume, valid solid, every hole found where it was put, every old hole unchanged),
   every kept requirement measured on the B-rep (``brep_checks``: ``constraints.verify_on_brep`` with the added
   holes' edge, keep-out and ligament distances, and the keep-out boxes).
5. **Delivery** (``study.added_design``): with k ≥ 1 that design is the study's answer — ``optimised.step`` /
   ``.stl``, results.json's after-sections, ``holes.csv``, the closed-loop check (original, move-only optimum and
   the added design in the same paired runs) and the verdict; ``move_only.step`` beside it. The predicted error
   of the original, the move-only optimum and the added design (``pose_accuracy.predict`` on each design's own
   mesh) is in ``predicted``.

Bad input — an allowed face the part does not have, a drill not in the shop's sizes or larger than a face, no
feasible site — is one ``StudyError`` naming the file, the key and what is allowed, before any optimisation
(``preflight``). Units: mm.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from cadfeat.cad.drill_targets import AddedHole, PlanarFace, drill_targets, planar_faces
from cadfeat.cad.features import holes_to_arrays
from cadfeat.cad.features.identity import hole_names
from cadfeat.design.added_targets import (
    FaceRules,
    Movable,
    PoseScene,
    Sites,
    TargetObjective,
    conflicts,
    lazy_greedy,
    refine,
    site_margins,
    sites_on_faces,
)
from cadfeat.design.added_targets.sites import box_distance, face_grid, keepin_margin
from cadfeat.design.shop import hole_sizes
from cadfeat.errors import CadfeatError
from cadfeat.poses import cam_from_part
from cadfeat.study.delivery import AddedDesign
from cadfeat.study.schema import StudyError

if TYPE_CHECKING:  # pragma: no cover
    import trimesh
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.results import AddedTargetsData, JsonDict, RequirementData
    from cadfeat.study.progress import StudyProgress
    from cadfeat.study.schema import StudyConfig
    from cadfeat.study.settings.add_targets import AddTargetsSettings
    from cadfeat.study.setup import StudySetup

__all__ = ["Allowed", "allowed_sites", "as_added", "brep_checks", "choose", "most_that_fit", "preflight",
           "preflight_part", "recommend", "run_phase"]

_AXES = {"x": 0, "y": 1, "z": 2}
REFINE_MIN_STEP_MM = 0.5
"""The refinement's last step (mm): the added holes stay on a 0.5 mm grid (the sites' grid is even), a drawing
dimension the shop's 0.1 mm grid holds."""


@dataclass
class Allowed:
    """The allowed faces of a design, each face's rules and the feasible candidate sites."""

    faces: list[PlanarFace]
    rules: list[FaceRules]
    sites: Sites


# ------------------------------------------------------------------------------------------- faces, sites
def _spec(config: StudyConfig) -> AddTargetsSettings:
    spec = getattr(config, "add_targets", None)
    if spec is None:
        raise CadfeatError(f"{config.label}: the study has no [add_targets] section")
    return spec


def _face_list(faces: Sequence[PlanarFace]) -> str:
    return "; ".join(f.describe() for f in sorted(faces, key=lambda f: -f.area_mm2)[:8])


def _select(selector: str, faces: Sequence[PlanarFace], names: Sequence[str], label: str) -> PlanarFace:
    """The planar face of one ``[add_targets] faces`` selector (``settings.add_targets.FACE_TEXT``)."""
    if selector.startswith("host:"):
        name = selector[5:]
        if name not in names:
            raise StudyError(f"{label}: add_targets.faces: {selector!r}: the part has no hole {name!r}; allowed: "
                             f"host:<one of {', '.join(names)}>")
        i = list(names).index(name)
        on = [f for f in faces if i in f.holes]
        if not on:
            raise StudyError(f"{label}: add_targets.faces: {selector!r}: hole {name} does not open into a planar "
                             "face; allowed: host:<a hole on a planar face> or a direction (+x, -x, +y, -y, +z, -z)")
        return on[0]
    axis = np.zeros(3)
    axis[_AXES[selector[1]]] = 1.0 if selector[0] == "+" else -1.0
    on = [f for f in faces if float(f.normal @ axis) > 1 - 1e-6]
    if not on:
        raise StudyError(f"{label}: add_targets.faces: {selector!r}: the part has no planar face facing {selector}; "
                         f"allowed: a face the part has — its largest planar faces: {_face_list(faces)}")
    return max(on, key=lambda f: f.area_mm2)


def resolve_faces(config: StudyConfig, shape: Shape, holes: Sequence[Hole]) -> list[PlanarFace]:
    """The planar faces of ``shape`` the study's ``[add_targets] faces`` select, in their order; the part's holes
    ``holes`` (their names) for ``host:`` selectors. One ``StudyError`` for a face the part does not have."""
    spec = _spec(config)
    faces = planar_faces(shape)
    chosen = [_select(s, faces, hole_names(holes), config.label) for s in spec.faces]
    idx = [f.index for f in chosen]
    if len(set(idx)) != len(idx):
        raise StudyError(f"{config.label}: add_targets.faces: {list(spec.faces)} select the same face twice; "
                         "allowed: each face once")
    return chosen


def _rules(config: StudyConfig, face: PlanarFace, holes: Sequence[Hole]) -> FaceRules:
    """What a site on ``face`` keeps: every hole of ``holes`` whose rim lies on the face's plane, the boxes, the
    study's ``[constraints]``."""
    spec, c = _spec(config), config.constraints
    o = face.outline
    on = [h for h in holes if abs(float((np.asarray(h.centre) - o.origin) @ o.normal)) < 1e-4
          and float(np.asarray(h.axis) @ o.normal) > 1 - 1e-6]
    centres = np.array([h.centre for h in on], float).reshape(-1, 3)
    radii = np.array([h.radius_mm for h in on], float)
    boxes = np.array(spec.keepout_boxes, float).reshape(-1, 6)
    return FaceRules(o, centres, radii, boxes, spec.rim_radius_mm, c.edge_distance_mm, c.ligament_mm, c.ligament_mm,
                     np.array(spec.keepin_boxes, float).reshape(-1, 6))


def _face_extent(face: PlanarFace) -> str:
    """"x −30..30, y 0, z 3..55": a face's bounding box in the part frame (mm), for error messages."""
    pts = face.outline.to_3d(face.outline.outer)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return ", ".join(f"{a} {lo[i]:.4g}" + ("" if hi[i] - lo[i] < 1e-6 else f"..{hi[i]:.4g}")
                     for i, a in enumerate("xyz"))


def _check_keepin(config: StudyConfig, faces: Sequence[PlanarFace]) -> None:
    """Each ``keepin_boxes`` box must meet an allowed face (a point of it inside the box): one ``StudyError``
    naming the box and the faces' extents otherwise."""
    spec = _spec(config)
    for box in spec.keepin_boxes:
        b = np.array([box], float)
        if not any(np.any(keepin_margin(f.outline.to_3d(face_grid(f.outline, 0.25)), f.normal, 0.0, b) >= 0)
                   for f in faces):
            raise StudyError(f"{config.label}: add_targets.keepin_boxes: {list(box)} meets none of the allowed faces "
                             f"({'; '.join(f'{f.describe()}: {_face_extent(f)}' for f in faces)}); allowed: boxes "
                             "[xmin, ymin, zmin, xmax, ymax, zmax] (mm, part frame) that hold part of an allowed face")


def most_that_fit(sites: Sites, rim_radius_mm: float, ligament_mm: float, cell_mm: float = 0.25) -> int:
    """An upper bound on how many holes the sites can hold at once: two added rims keep ``ligament_mm`` apart, so
    discs of radius ρ = rim + ligament/2 around the chosen centres do not overlap and lie in the union of such
    discs around the sites; per face the count is at most that union's area / πρ² (the area from a raster of
    ``cell_mm``, each cell counted when its centre is within ρ + half its diagonal of a site: never less than the
    union's area)."""
    from scipy.spatial import cKDTree  # pyright: ignore[reportMissingTypeStubs, reportAttributeAccessIssue, reportUnknownVariableType]

    kdtree = cast("Callable[[np.ndarray], Any]", cKDTree)  # (scipy.spatial has no stubs)

    rho = rim_radius_mm + 0.5 * ligament_mm
    total = 0
    for f in np.unique(sites.face):
        uv = sites.uv[sites.face == f]
        lo, hi = uv.min(axis=0) - rho - cell_mm, uv.max(axis=0) + rho + cell_mm
        s = np.arange(lo[0], hi[0], cell_mm) + 0.5 * cell_mm
        t = np.arange(lo[1], hi[1], cell_mm) + 0.5 * cell_mm
        S, T = np.meshgrid(s, t, indexing="ij")
        cells = np.stack([S.ravel(), T.ravel()], axis=-1)
        d: np.ndarray = kdtree(uv).query(cells, distance_upper_bound=rho + cell_mm)[0]
        area = float(np.sum(d <= rho + cell_mm * np.sqrt(0.5))) * cell_mm ** 2
        total += int(np.floor(area / (np.pi * rho ** 2) + 1e-9))
    return total


def _check_count(config: StudyConfig, found: Allowed) -> None:
    """``max_added`` holes must fit on the sites at once (``most_that_fit``): one ``StudyError`` otherwise."""
    spec = _spec(config)
    most = most_that_fit(found.sites, spec.rim_radius_mm, config.constraints.ligament_mm)
    if spec.max_added > most:
        raise StudyError(f"{config.label}: add_targets.max_added: {spec.max_added} holes cannot be placed: at most "
                         f"{most} Ø{spec.diameter_mm:g} mm hole(s) fit on {', '.join(spec.faces)} at once "
                         f"({len(found.sites)} candidate sites; added rims keep [constraints] ligament_mm = "
                         f"{config.constraints.ligament_mm:g} to each other); allowed: max_added ≤ {most}, or more "
                         "faces, fewer keepout_boxes or a smaller diameter_mm")


def _check_drill(config: StudyConfig) -> None:
    """The drill's diameter is one of the shop's sizes (``[shop] hole_sizes``; any with "none")."""
    spec = _spec(config)
    sizes = hole_sizes(config.shop.hole_sizes)
    if sizes and not any(abs(spec.diameter_mm - s) < 1e-9 for s in sizes):
        table = config.shop.hole_sizes if isinstance(config.shop.hole_sizes, str) else "[shop] hole_sizes"
        raise StudyError(f"{config.label}: add_targets.diameter_mm: {spec.diameter_mm:g} is not a size of the shop's "
                         f"table ({table}); allowed: {', '.join(f'{s:g}' for s in sizes)} mm")


def _check_fits(config: StudyConfig, face: PlanarFace, rules: FaceRules) -> None:
    """A drill (rim plus edge distance) larger than the face: one ``StudyError`` with the largest that fits."""
    spec = _spec(config)
    uv = face_grid(face.outline, min(0.25, spec.pitch_mm))
    edge = site_margins(uv, rules)["edge"]
    if edge.size and float(edge.max()) >= 0:
        return
    inscribed = float(edge.max()) + rules.rim_radius_mm + rules.edge_distance_mm if edge.size else 0.0
    largest = 2.0 * (inscribed - rules.edge_distance_mm - spec.chamfer_mm)
    raise StudyError(f"{config.label}: add_targets.diameter_mm: a Ø{spec.diameter_mm:g} mm drill (rim radius "
                     f"{spec.rim_radius_mm:g} mm, [constraints] edge_distance_mm = {rules.edge_distance_mm:g}) is "
                     f"larger than {face.describe()}; allowed: a diameter ≤ {max(largest, 0.0):.3g} mm on this face, "
                     "or other faces")


def allowed_sites(config: StudyConfig, shape: Shape, holes: Sequence[Hole]) -> Allowed:
    """The allowed faces of ``shape`` (whose holes are ``holes``), their rules and the feasible candidate sites;
    ``StudyError`` when a face does not exist, the drill does not fit a face or no site is feasible."""
    spec = _spec(config)
    _check_drill(config)
    faces = resolve_faces(config, shape, holes)
    _check_keepin(config, faces)
    rules = [_rules(config, f, holes) for f in faces]
    for f, r in zip(faces, rules, strict=True):
        _check_fits(config, f, r)
    sites = sites_on_faces(rules, spec.pitch_mm)
    if not len(sites):
        raise StudyError(f"{config.label}: add_targets: no feasible site on {', '.join(spec.faces)}: "
                         f"{_blocking(rules, spec)}; "
                         "allowed: other faces, fewer or smaller keepout_boxes, larger keepin_boxes, a smaller "
                         "diameter_mm, a smaller [constraints] edge_distance_mm or ligament_mm, or a finer pitch_mm")
    return Allowed(faces, rules, sites)


def _blocking(rules: Sequence[FaceRules], spec: AddTargetsSettings) -> str:
    """Which requirements rule out the grid sites (share of the sites each breaks)."""
    counts: dict[str, int] = {}
    total = 0
    for r in rules:
        m = site_margins(face_grid(r.outline, spec.pitch_mm), r)
        total += len(next(iter(m.values())))
        for k, v in m.items():
            counts[k] = counts.get(k, 0) + int(np.sum(v < 0))
    words = {"edge": "edge distance", "keepout": "keep-out distance to slots and pockets",
             "ligament": "ligament to the part's holes", "box": "keepout_boxes", "keepin": "keepin_boxes"}
    return "every site breaks a requirement (" + ", ".join(f"{words[k]}: {100 * n / max(total, 1):.0f} % of the sites"
                                                            for k, n in counts.items() if n) + ")"


def preflight(config: StudyConfig, setup: StudySetup) -> JsonDict:
    """Before any optimisation, on the study's original part (``preflight_part``); returns {"faces", "sites"}."""
    return preflight_part(config, setup.shape0, setup.holes0, setup.view_direction)


def preflight_part(config: StudyConfig, shape: Shape, holes: Sequence[Hole],
                   view: Sequence[float] | np.ndarray | None) -> JsonDict:
    """What ``[add_targets]`` needs of the part ``shape`` (its holes ``holes``, extracted with the study's view
    ``view``), before any work — ``cadfeat run``'s set-up and ``cadfeat validate``: the drill a shop size, the
    allowed faces present, each keep-in box on one of them, the drill no larger than a face, a feasible site
    (``allowed_sites``), ``max_added`` holes that can fit at once (``most_that_fit``), and a dry run of the
    drilling (the most central site drilled into the part and verified: what fails at the end is tried at the
    start). Raises ``StudyError`` naming the file, the key and what is allowed; returns {"faces", "sites"}."""
    spec = _spec(config)
    found = allowed_sites(config, shape, holes)
    _check_count(config, found)
    sites = found.sites
    i = int(np.argmax(sites.margin))
    names = _next_names(holes, 1)
    trial = AddedHole(sites.centres[i], sites.axes[i], 0.5 * spec.diameter_mm, spec.depth_mm, spec.chamfer_mm,
                      names[0])
    try:
        drill_targets(shape, [trial], list(holes), label=f"{config.label}: [add_targets] dry run",
                      prefer_direction=view)
    except CadfeatError as exc:
        at = np.round(np.asarray(sites.centres[i], float), 3).tolist()
        raise StudyError(f"{config.label}: add_targets: a hole cannot be drilled into the part (dry run at {at} mm): "
                         f"{exc}; allowed: other faces, a shallower depth_mm or a smaller diameter_mm") from None
    return {"faces": [f.describe() for f in found.faces], "sites": len(sites), "most_that_fit":
            most_that_fit(sites, spec.rim_radius_mm, config.constraints.ligament_mm)}


# ---------------------------------------------------------------------------------------------- choice
def pose_scene(config: StudyConfig, setup: StudySetup) -> PoseScene:
    """The prediction's scene of the study (``pose_accuracy.predict``'s: camera, poses, ℓ, cell models)."""
    from cadfeat.design.pose_terms import cell_models

    T = cam_from_part(setup.trajectory.T_task_cam, setup.T_task_part)
    o = config.objective
    return PoseScene(setup.camera, T, float(o.pose_rotation_length_mm), o.pose_aggregate, cell_models(config.cell),
                     float(config.cell.noise_sigma_grey), setup.problem.glare, config.cell)


def _occlude(mesh: trimesh.Trimesh | None, T: np.ndarray) -> Any:
    """Rim hidden fraction (L, n) of n holes (centres, axes (n, 3), rim radii, through, depth (n,)) against the
    part's ``mesh`` (the exact ray test, as ``pose_accuracy.predict``)."""
    from cadfeat.measures.rim_occlusion import rim_occlusion

    def occlude(centres: np.ndarray, axes: np.ndarray, radii: np.ndarray, through: np.ndarray,
                depth: np.ndarray) -> np.ndarray:
        return rim_occlusion(mesh, T, centres, axes, radii, samples=16, through=through, depth_mm=depth)
    return occlude


def target_objective(config: StudyConfig, scene: PoseScene, holes: Sequence[Hole], mesh: trimesh.Trimesh | None,
                     sites: Sites) -> TargetObjective:
    """g_POSE of ``holes`` plus added holes at ``sites``, each rim's hidden fraction against ``mesh``."""
    from cadfeat.design.pose_terms import hole_kinds
    from cadfeat.measures.rim_occlusion import rim_occlusion

    spec = _spec(config)
    c, a, r = holes_to_arrays(list(holes))
    through = np.array([bool(h.through) for h in holes])
    depth = np.array([float(h.depth_mm) for h in holes])
    occ0 = rim_occlusion(mesh, scene.T_cam_part, c, a, r, samples=16, through=through, depth_mm=depth)
    m = len(sites)
    occ_sites = _occlude(mesh, scene.T_cam_part)(sites.centres, sites.axes, np.full(m, spec.rim_radius_mm),
                                                 np.zeros(m, bool), np.full(m, spec.depth_mm))
    kind = "plain, chamfered rim" if spec.chamfer_mm > 0 else "plain"
    return TargetObjective(scene, (c, a, r, through, depth), hole_kinds(holes), occ0, spec.rim_radius_mm,
                           spec.depth_mm, kind, sites.centres, sites.axes, occ_sites)


def recommend(errors_mm: Sequence[float], target_error_mm: float | None, min_gain_percent: float) -> tuple[int, str]:
    """(the recommended number of added holes, why) from the predicted errors (k = 0, 1, …): the first k that
    reaches ``target_error_mm``; else the last k whose hole lowered the error by ≥ ``min_gain_percent``."""
    e = np.asarray(errors_mm, float)
    if target_error_mm is not None:
        hit = np.flatnonzero(e <= target_error_mm)
        if hit.size:
            k = int(hit[0])
            return k, f"{k} added hole(s) reach the target error {target_error_mm:g} mm (predicted {e[k]:.4g} mm)"
    gains = 100.0 * (e[:-1] - e[1:]) / np.maximum(e[:-1], 1e-300)
    k = 0
    while k < len(gains) and gains[k] >= min_gain_percent:
        k += 1
    why = (f"each of the first {k} hole(s) lowers the predicted error by ≥ {min_gain_percent:g} %"
           if k else f"no added hole lowers the predicted error by {min_gain_percent:g} % or more")
    if k < len(gains):
        why += f"; hole {k + 1} would gain only {gains[k]:.1f} %"
    else:
        why += f" (the most the curve reaches: {len(gains)}, max_added or every feasible site used)"
    if target_error_mm is not None:
        why += f"; the target {target_error_mm:g} mm is not reached with up to {len(gains)}"
    return k, why


@dataclass
class Choice:
    """The greedy curve and the recommended design: the sites chosen in order, the predicted error after each
    step (k = 0..), the recommended k and why, and the refined holes (face coordinates, centres)."""

    allowed: Allowed
    order: list[int]
    errors_mm: list[float]
    k: int
    why: str
    refined: Any
    evaluations: int
    seconds: float


def movable(setup: StudySetup, x: np.ndarray, holes: Sequence[Hole]) -> Movable | None:
    """The study's movable holes as functions of its position variables around the delivered design ``x`` whose
    holes are ``holes`` (the feature model anchored on them: ``verify.AnchoredModel``), for the joint refinement;
    None when the study has no position variable."""
    from cadfeat.study.verify import AnchoredModel

    index = np.array([i for i, v in enumerate(setup.space.variables) if v.kind == "position"], int)
    if not index.size or len(holes) != len(setup.holes0):
        return None
    model = AnchoredModel(setup.model, np.asarray(x, float), list(holes))
    lower, upper = np.asarray(setup.space.lower, float), np.asarray(setup.space.upper, float)

    def feasible(X: np.ndarray) -> np.ndarray:
        c, _, r = setup.model.features_batch(X)
        inside = np.all((X >= lower - 1e-9) & (X <= upper + 1e-9), axis=1)
        margins = np.asarray(setup.problem.cset.stacked(c, r, X), float).reshape(len(X), -1)
        return inside & np.all(margins >= -1e-9, axis=1)
    return Movable(np.asarray(x, float), index, model.features_batch, feasible,
                   np.asarray(setup.movable_mask, bool))


def choose(config: StudyConfig, setup: StudySetup, shape: Shape, holes: Sequence[Hole], mesh: trimesh.Trimesh | None,
           x: np.ndarray | None = None) -> Choice:
    """Sites, lazy greedy up to ``max_added``, the recommended number and its refinement on the design
    (``shape``, ``holes``; ``x`` its design vector: the study's position variables are refined with the added
    holes) with its occlusion ``mesh`` (module docstring)."""
    import time

    t0 = time.perf_counter()
    spec = _spec(config)
    allowed = allowed_sites(config, shape, holes)
    scene = pose_scene(config, setup)
    objective = target_objective(config, scene, holes, mesh, allowed.sites)
    clash = conflicts(allowed.sites, spec.rim_radius_mm, config.constraints.ligament_mm)
    res = lazy_greedy(objective.of_sets, clash, spec.max_added)
    errors = [-g for g in res.values]
    k, why = recommend(errors, spec.target_error_mm, spec.min_gain_percent)
    refined = None
    if k and spec.refine:
        idx = np.asarray(res.order[:k])
        refined = refine(objective, allowed.rules, allowed.sites.face[idx], allowed.sites.uv[idx],
                         _occlude(mesh, scene.T_cam_part), step_mm=spec.pitch_mm / 2, min_step_mm=REFINE_MIN_STEP_MM,
                         movable=None if x is None else movable(setup, x, holes))
    return Choice(allowed, res.order, errors, k, why, refined, objective.evaluations, time.perf_counter() - t0)


def _next_names(holes: Sequence[Hole], k: int) -> list[str]:
    """k names continuing the part's (H10, H11, … after H9)."""
    numbers = [int(m.group(1)) for n in hole_names(holes) if (m := re.fullmatch(r"H(\d+)", n))]
    first = max(numbers, default=len(holes)) + 1
    return [f"H{first + i}" for i in range(k)]


def added_holes(config: StudyConfig, choice: Choice, holes: Sequence[Hole]) -> list[AddedHole]:
    """The recommended holes (refined when refined), named after the part's."""
    spec = _spec(config)
    idx = np.asarray(choice.order[:choice.k], int)
    sites = choice.allowed.sites
    centres = choice.refined.centres if choice.refined is not None else sites.centres[idx]
    names = _next_names(holes, choice.k)
    return [AddedHole(np.asarray(c, float), np.asarray(sites.axes[i], float), 0.5 * spec.diameter_mm, spec.depth_mm,
                      spec.chamfer_mm, n) for c, i, n in zip(centres, idx, names, strict=True)]


# ------------------------------------------------------------------------------------------------- phase
def brep_checks(config: StudyConfig, setup: StudySetup, shape: Shape, holes: Sequence[Hole], n_old: int,
                where: str) -> list[RequirementData]:
    """Every kept requirement of the added design measured on the solid ``shape`` (its holes ``holes``: the
    part's ``n_old`` then the added): OCCT edge, keep-out and ligament distances of the movable and added holes,
    the fixed holes unchanged from the original (``verify_on_brep``), and the keep-out boxes (distance of each
    added rim to each box)."""
    from cadfeat.cad.drill_targets import added_hole
    from cadfeat.design.constraints import verify_on_brep

    spec = _spec(config)
    holes = list(holes)
    k = len(holes) - n_old
    same = n_old == len(setup.holes0)
    fixed = np.concatenate([np.asarray(setup.fixed_mask, bool), np.zeros(k, bool)]) if same else \
        np.arange(len(holes)) < n_old
    reference = list(setup.holes0) + [added_hole(as_added(h)) for h in holes[n_old:]] if same else None
    checks: list[RequirementData] = [{**c.to_dict(), "checked_on": where}
              for c in verify_on_brep(shape, holes, setup.constraints, fixed, reference=reference,
                                      reference_shape=setup.shape0 if same else None,
                                      prefer_direction=setup.view_direction)]
    boxes = np.array(spec.keepout_boxes, float).reshape(-1, 6)
    keepin = np.array(spec.keepin_boxes, float).reshape(-1, 6)
    for h in holes[n_old:]:
        if len(keepin):
            inside = float(keepin_margin(np.asarray(h.centre, float), np.asarray(h.axis, float), h.radius_mm, keepin))
            checks.append({"name": "keepin_box", "holes": [h.name], "required": 0.0, "value": inside,
                           "margin": inside, "unit": "mm", "ok": bool(inside >= -1e-6), "checked_on": where})
        if len(boxes):
            gap = float(np.min(box_distance(np.asarray(h.centre, float), boxes))) - h.radius_mm
            need = config.constraints.ligament_mm
            checks.append({"name": "keepout_box", "holes": [h.name], "required": need, "value": gap,
                           "margin": gap - need, "unit": "mm", "ok": bool(gap - need >= -1e-6), "checked_on": where})
    return checks


def _predicted(config: StudyConfig, setup: StudySetup, holes: Sequence[Hole], mesh: trimesh.Trimesh | None
               ) -> dict[str, float]:
    """RMS predicted errors (mm; translation mm, rotation deg) of a design with ``pose_accuracy.predict``."""
    from cadfeat.study.pose_accuracy import predict

    T = cam_from_part(setup.trajectory.T_task_cam, setup.T_task_part)
    ell = float(config.objective.pose_rotation_length_mm)
    info, _ = predict(setup.camera, T, holes, mesh, ell, cell=config.cell, glare=setup.problem.glare)

    def rms(v: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.square(np.minimum(v, 1e6)))))

    return {"error_mm": rms(info.error_mm(ell)), "translation_mm": rms(info.error_translation_mm),
            "rotation_deg": rms(info.error_rotation_deg)}


def _base_design(setup: StudySetup, x: np.ndarray | None, choice: Choice, shape1: Shape,
                 holes1: Sequence[Hole]) -> tuple[Any, list[Hole], dict[str, float] | None]:
    """The design the added holes are drilled into: the move-only optimum, or — when the joint refinement moved
    the study's position variables — its CAD rebuild at the refined x (with x as named values)."""
    from cadfeat.study.verify import rebuild

    ref = choice.refined
    if x is None or ref is None or ref.x is None or np.allclose(ref.x, x, atol=1e-12):
        return shape1, list(holes1), None
    shape, holes, _ = rebuild(setup, ref.x)
    return shape, list(holes), setup.space.as_dict(ref.x)


def run_phase(config: StudyConfig, setup: StudySetup, designs: Mapping[str, tuple[Shape, Sequence[Hole]]],
              progress: StudyProgress | None = None, x: np.ndarray | None = None
              ) -> tuple[AddedTargetsData, AddedDesign]:
    """The added-target phase on the move-only optimum ``designs["after"]`` (its design vector ``x``;
    ``designs["before"]``: the original, for the comparison): returns (results.json ``added_targets``, the added
    design)."""
    from cadfeat.study.pose_accuracy import part_mesh

    shape1, holes1 = designs["after"]
    mesh1 = part_mesh(config, shape1)
    choice = choose(config, setup, shape1, holes1, mesh1, x)
    base_shape, base_holes, moved_x = _base_design(setup, x, choice, shape1, holes1)
    added = added_holes(config, choice, base_holes)
    shape2, holes2 = drill_targets(base_shape, added, base_holes, label=f"{config.label}: [add_targets]",
                                   prefer_direction=setup.view_direction)
    checks = brep_checks(config, setup, shape2, holes2, len(base_holes), "brep")
    mesh2 = part_mesh(config, shape2)
    predicted = {"original": _predicted(config, setup, designs["before"][1], part_mesh(config, designs["before"][0])),
                 "move_only": _predicted(config, setup, holes1, mesh1),
                 "added": _predicted(config, setup, holes2, mesh2)}
    block = _block(config, _spec(config), choice, added, checks, predicted)
    refinement = block["refinement"]
    if moved_x is not None and refinement is not None:
        refinement["variables"] = moved_x
        refinement["moved_holes"] = [
            {"name": b.name, "before": np.asarray(a.centre).tolist(), "after": np.asarray(b.centre).tolist()}
            for a, b in zip(holes1, base_holes, strict=True) if np.linalg.norm(np.asarray(a.centre) - b.centre) > 1e-9]
    if progress is not None:
        progress.log(f"added targets: {choice.k} recommended ({choice.why}); predicted RMS error "
                     f"{predicted['move_only']['error_mm']:.4g} → {predicted['added']['error_mm']:.4g} mm")
    return block, AddedDesign(shape2, holes2, len(base_holes))


def _block(config: StudyConfig, spec: AddTargetsSettings, choice: Choice, added: Sequence[AddedHole],
           checks: list[RequirementData], predicted: Mapping[str, Mapping[str, float]]) -> AddedTargetsData:
    sites = choice.allowed.sites
    ref = choice.refined
    drop = 1.0 - predicted["added"]["error_mm"] / max(predicted["move_only"]["error_mm"], 1e-300)
    return {
        "settings": spec.model_dump(mode="json"),
        "faces": [f.describe() for f in choice.allowed.faces],
        "candidate_sites": len(sites),
        "curve": {"added": list(range(len(choice.errors_mm))), "error_mm": [float(e) for e in choice.errors_mm],
                  "aggregate": config.objective.pose_aggregate,
                  "sites": [sites.centres[i].tolist() for i in choice.order]},
        "recommended": choice.k, "reason": choice.why,
        "refinement": None if ref is None else {"error_before_mm": -ref.value_before, "error_mm": -ref.value,
                                                "moves": ref.moves, "evaluations": ref.evaluations},
        "holes": [{"name": a.name, "centre": np.asarray(a.centre).tolist(), "axis": np.asarray(a.axis).tolist(),
                   "diameter_mm": 2 * a.radius_mm, "depth_mm": a.depth_mm, "chamfer_mm": a.chamfer_mm,
                   "rim_radius_mm": a.rim_radius_mm, "face": choice.allowed.faces[int(sites.face[i])].describe(),
                   "status": "added"} for a, i in zip(added, choice.order[:choice.k], strict=True)],
        "predicted": {k: dict(v) for k, v in predicted.items()},
        "drop_vs_move_only": drop,
        "constraints": checks,
        "requirements_hold": all(bool(c["ok"]) for c in checks),
        "evaluations": choice.evaluations, "seconds": choice.seconds,
    }


def as_added(h: Hole) -> AddedHole:
    """An extracted added hole as the ``AddedHole`` it was drilled as (bore radius, chamfer from the rim)."""
    return AddedHole(np.asarray(h.centre, float), np.asarray(h.axis, float), float(h.bore_radius_mm),
                     float(h.depth_mm), float(h.radius_mm - h.bore_radius_mm), h.name)
