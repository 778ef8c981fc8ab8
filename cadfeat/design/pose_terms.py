"""g_POSE inside the optimisation problem: the pose information of a design's holes along the trajectory.

``pose_of_features`` is ``measures.pose_information`` of hole features (part frame) at the problem's poses, with
each rim's hidden fraction from ``measures.rim_occlusion``: the optimiser's depth maps (``Problem.occlusion``),
or the exact ray test against the part's mesh for reported values (as the other measures do). The hole depth
and through flag of the reference holes feed the offset model (depth/diameter at the design's radii).

``pose_values`` gives g_POSE of B designs (``objectives.pose_objective``, batched over the B designs): in the
optimiser, ONE ``pose_information`` call on the B·L stacked poses, each pose with its own design's holes (the
rims of all B designs tested against each pose's depth map in one call); the exact ray test of reported
values goes one design at a time (a few seconds). Cost on the flagship (40 poses × 9 holes): ~2.6 ms per design
(0.17 s for a batch of 64, vs 0.02 s for the four thesis measures).
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Callable, Hashable, Sequence
from functools import lru_cache
from typing import TYPE_CHECKING, Any, Protocol, cast

import numpy as np

from cadfeat.design.memory import budget_bytes
from cadfeat.design.objectives import (
    POSE_AGGREGATES,
    POSE_UNOBSERVABLE_MM,
    _choice,  # pyright: ignore[reportPrivateUsage] (the same refusal)
)

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

    from cadfeat.cad.features import Hole
    from cadfeat.camera import Camera
    from cadfeat.cell import Cell
    from cadfeat.design.design_space import FeatureModel
    from cadfeat.design.objectives import ObjectiveConfig
    from cadfeat.measures.depth import DepthMaps
    from cadfeat.measures.glare import GlareMaps
    from cadfeat.measures.pose_information import PoseInformation
    from cadfeat.measures.pose_models import HoleGeometry, PoseModels

__all__ = ["StackedPose", "designs_glare_rate", "glare_rate", "hole_attributes", "pose_aggregate_batch",
           "pose_of_features", "pose_values",
           "stacked_information"]

#: rim samples of the occlusion test (``rim_occlusion``)
RIM_SAMPLES = 16


class PoseProblem(Protocol):
    """What g_POSE reads of the optimisation problem (``design.problem.Problem``; a protocol: ``problem`` imports
    this module): the reference holes, the objective's settings, the poses ``T_cam_part`` (L, 4, 4), the part's
    mesh (exact rim test) and the optimiser's depth maps, the camera, the cell and the fixed holes (N,) bool."""

    @property
    def model(self) -> FeatureModel: ...
    @property
    def objective_config(self) -> ObjectiveConfig: ...
    @property
    def T_cam_part(self) -> np.ndarray: ...
    @property
    def occlusion_mesh(self) -> trimesh.Trimesh | None: ...
    @property
    def occlusion(self) -> DepthMaps | None: ...
    @property
    def camera(self) -> Camera: ...
    @property
    def cell(self) -> Cell: ...
    @property
    def fixed_mask(self) -> np.ndarray: ...
    @property
    def glare(self) -> GlareMaps | None: ...


def hole_attributes(problem: PoseProblem, radii: np.ndarray,
                    depth_mm: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(through (N,) bool, depth (N,) or like ``radii`` mm, depth/diameter like ``radii``) of the problem's
    reference holes at ``radii``; ``depth_mm`` (the design's depths, ``design.hole_form``) replaces theirs."""
    holes = list(problem.model.holes)
    through = np.array([bool(getattr(h, "through", False)) for h in holes])
    depth = np.array([float(getattr(h, "depth_mm", 0.0)) for h in holes]) if depth_mm is None else \
        np.asarray(depth_mm, float)
    return through, depth, depth / (2.0 * np.maximum(np.asarray(radii, float), 1e-9))


def hole_kinds(holes: Sequence[Hole]) -> list[str]:
    """(N,) the holes' kinds (``Hole.kind``, "plain" where a hole has none; the offset model treats a
    counterbore's rim apart)."""
    return [str(getattr(h, "kind", "plain")) for h in holes]


def pose_of_features(problem: PoseProblem, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                     exact_occlusion: bool = False, occlusion: np.ndarray | None = None,
                     depth_mm: np.ndarray | None = None) -> PoseInformation:
    """``measures.pose_information`` (L poses × N holes) of one design's features (module docstring).

    ``occlusion`` (L, N) overrides the rim test (e.g. held fixed for finite differences); ``depth_mm`` (N,) the
    design's hole depths (default: the reference holes')."""
    from cadfeat.measures import pose_information  # lazy: would import scipy.spatial at module load
    from cadfeat.measures.rim_occlusion import rim_occlusion

    cfg = problem.objective_config
    through, depth, ratio = hole_attributes(problem, radii, depth_mm)
    T = problem.T_cam_part
    if occlusion is None:
        mesh = problem.occlusion_mesh if exact_occlusion else problem.occlusion
        if mesh is not None:
            occlusion = rim_occlusion(mesh, T, centres, axes, radii, samples=RIM_SAMPLES, through=through,
                                      depth_mm=depth)
    rate = glare_rate(problem, centres[None], axes[None], radii[None], through, problem.cell.noise_sigma_grey)
    return pose_information(problem.camera, T, centres, axes, radii, occlusion=occlusion, depth_ratio=ratio,
                            through=through, kinds=hole_kinds(problem.model.holes),
                            rotation_length_mm=cfg.pose_rotation_length_mm, model=cell_models(problem.cell),
                            noise_grey=problem.cell.noise_sigma_grey, contrast_rate=rate)


def glare_rate(problem: PoseProblem, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
               through: np.ndarray, noise_grey: float | np.ndarray) -> np.ndarray | None:
    """(B·L, N) the detection rate's factor from the part's own light of B designs' holes (B, N, …) at the
    problem's L poses (``designs_glare_rate`` with the problem's glare maps, poses and cell)."""
    return designs_glare_rate(problem.glare, problem.cell, problem.T_cam_part, centres, axes, radii, through,
                              noise_grey)


def designs_glare_rate(glare: GlareMaps | None, cell: Cell, T_cam_part: np.ndarray, centres: np.ndarray,
                       axes: np.ndarray, radii: np.ndarray, through: np.ndarray,
                       noise_grey: float | np.ndarray) -> np.ndarray | None:
    """(B·L, N) the detection rate's factor from the part's own light (``measures.glare.contrast_rate``) of B
    designs' holes (B, N, …) at the L poses ``T_cam_part`` (those of the ``glare`` maps), design-major; 1 for
    through holes; None without maps or when the cell's material does not return light from its bores
    (``cell.material.bores_return_light``). ``noise_grey``: σ, a number or (L, 1) per pose."""
    from cadfeat.cell.material import bores_return_light

    if glare is None or not bores_return_light(cell.material):
        return None
    from cadfeat.measures.glare import contrast_rate  # lazy: as the other measures

    B, N = radii.shape
    L = len(T_cam_part)
    noise = np.asarray(noise_grey, float)
    flat_radii = np.asarray(radii, float).reshape(B * N)
    rate = contrast_rate(glare, T_cam_part, np.reshape(centres, (B * N, 3)), np.reshape(axes, (B * N, 3)),
                         flat_radii, noise if noise.ndim == 0 else noise.reshape(L, 1))
    rate = np.moveaxis(rate.reshape(L, B, N), 1, 0).reshape(B * L, N)
    return np.where(np.asarray(through, bool), 1.0, rate)


#: The cells whose g_POSE models a physically based panel has checked (docs/results.md "Under physical light"),
#: by the calibration's file key (``measures.pose_models.model_key``) → what the panel found. A study in another
#: cell is told so.
CONFIRMED_CELLS = {
    "cadfeat-pbr-machined_aluminium-ring-as_modelled":
        "16 designs ranked as the physical loop ranks them (Spearman ρ 0.76–0.92)",
}
#: The cells whose models a panel found wrong, and how.
FAILED_CELLS = {
    "cadfeat-pbr-machined_aluminium-dome-as_modelled":
        "on the industrial plate they called blind dowels undetectable that the renders find in 94 % of frames "
        "(Spearman ρ 0.31–0.58)",
}


def model_confirmation(cell: Cell) -> str | None:
    """A warning when g_POSE's models for ``cell`` have not been confirmed against the physically based closed
    loop (``CONFIRMED_CELLS``), saying whether a panel found them wrong (``FAILED_CELLS``); None when they were."""
    from cadfeat.measures.pose_models import model_key

    key = model_key(str(cell.detector), "pbr", str(cell.material.name), str(cell.light.kind), str(cell.hole_ends))
    if key in CONFIRMED_CELLS:
        return None
    where = f"{cell.detector} detector, {cell.material.name}, {cell.light.kind} light, hole ends {cell.hole_ends}"
    found = FAILED_CELLS.get(key)
    said = (f"a physically based panel found them wrong there: {found}" if found is not None else
            "no physically based panel has checked them there (the ring light on machined aluminium is checked)")
    return (f"g_POSE's detection models for this cell ({where}): {said}; confirm the recommendation with "
            "`cadfeat run --track pbr` or `cadfeat track --renderer pbr`")


def cell_models(cell: Cell) -> PoseModels:
    """g_POSE's detection and measurement models (``measures.pose_models``) in the study's cell (``Cell``): the
    calibration of the cell's detector under its light, material and hole ends in the physical world
    (``pose_models.models_for``; the nearest one where none matches, said in ``source``), with the cell's gate
    and placement σ (``PoseModels.for_cell``). Cached per cell (a frozen, hashable model): every g_POSE evaluation
    asks, and choosing the calibration reads the package's data folder (~1 ms)."""
    return _cell_models(cast("Hashable", cell))  # (frozen: pydantic hashes it; the checker cannot tell)


@lru_cache(maxsize=16)
def _cell_models(cell: Hashable) -> PoseModels:
    from cadfeat.measures import pose_models  # lazy: would import scipy.spatial at module load

    c = cast("Cell", cell)
    return pose_models.models_for(c).for_cell(c)


def pose_aggregate_batch(errors_mm: np.ndarray, information: np.ndarray, how: str,
                         rotation_length_mm: float) -> np.ndarray:
    """g_POSE (...,) of per-pose predicted errors (..., L) mm and information (..., L, 6, 6): the batched form of
    ``objectives.pose_objective`` (same formulas; tests compare the two)."""
    _choice("pose_aggregate", how, POSE_AGGREGATES)
    e = np.where(np.isfinite(errors_mm), np.minimum(errors_mm, POSE_UNOBSERVABLE_MM), POSE_UNOBSERVABLE_MM)
    if how == "rms":
        return -np.sqrt(np.mean(e * e, axis=-1))
    if how == "worst":
        return -np.max(e, axis=-1)
    s = np.array([1.0, 1.0, 1.0] + [1.0 / rotation_length_mm] * 3)
    sign, raw = np.linalg.slogdet(np.asarray(information, float) * s[:, None] * s[None, :])
    floor = -12.0 * np.log(POSE_UNOBSERVABLE_MM)
    logdet = cast(np.ndarray, np.where((sign > 0) & np.isfinite(raw), np.maximum(raw, floor), floor))
    return -np.exp(-np.mean(logdet, axis=-1) / 12.0)


def pose_values(problem: PoseProblem, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                exact_occlusion: bool = False, depth_mm: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(g_POSE (B,), per-pose value −e (B, L)) of B designs' features (B, N, 3), (B, N, 3), (B, N); ``depth_mm``
    (B, N) their hole depths (``design.hole_form.design_depths``; None: the reference holes').

    The optimiser's path (depth-map occlusion or none) is ONE ``pose_information`` call on the B·L stacked poses,
    each with its own design's holes; the exact ray test (reported values) takes one design at a time."""
    cfg = problem.objective_config
    ell = cfg.pose_rotation_length_mm
    B, _ = np.shape(radii)
    L = len(problem.T_cam_part)
    if exact_occlusion and problem.occlusion_mesh is not None:
        depths = [None] * B if depth_mm is None else np.asarray(depth_mm, float)
        infos = [pose_of_features(problem, c, a, r, True, depth_mm=d)
                 for c, a, r, d in zip(centres, axes, radii, depths, strict=True)]
        errors = np.stack([p.error_mm(ell) for p in infos])
        information = np.stack([p.information for p in infos])
    else:
        info = stacked_information(problem, np.asarray(centres, float), np.asarray(axes, float),
                                   np.asarray(radii, float), depth_mm=depth_mm)
        errors = info.error_mm(ell).reshape(B, L)
        information = info.information.reshape(B, L, 6, 6)
    g = pose_aggregate_batch(errors, information, cfg.pose_aggregate, ell)
    per_pose = -np.where(np.isfinite(errors), np.minimum(errors, POSE_UNOBSERVABLE_MM), POSE_UNOBSERVABLE_MM)
    return g, per_pose


def stacked_information(problem: PoseProblem, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                        noise_grey: float | np.ndarray | None = None, depth_mm: np.ndarray | None = None
                        ) -> StackedPose:
    """g_POSE's pose information of B designs as B·L poses (design-major), holes per pose; occlusion by the
    problem's depth maps (every design's rims at each of the L poses in one ``rim_occlusion`` call).
    ``noise_grey``: the sensor's grey-level noise, a number or (L, 1) per pose (a robustness draw's pixel noise);
    None: the cell's (``problem.cell.noise_sigma_grey``).

    The same numbers as ONE ``measures.pose_information`` call on the B·L stacked poses with all N holes (tested,
    bit for bit on the flagship), computed faster: a hole's image geometry, rim occlusion and measurement
    Jacobian depend on that hole alone, so for the fixed holes (``problem.fixed_mask``) that are the same in every
    design they are computed once at the L poses and kept (``_fixed_terms``: the same poses, e.g. a robust
    problem's fixed draws, give the same terms in every evaluation); only the designs' other holes are computed
    at the B·L poses. What couples the holes — the detection model's gap to the nearest other rim — and the sums
    over holes are then evaluated on all N holes as ``pose_information`` does (its steps and expressions)."""

    B, N = radii.shape
    L = len(problem.T_cam_part)
    through, depth, ratio = hole_attributes(problem, radii, depth_mm)
    depth = np.broadcast_to(depth, (B, N))
    noise = np.asarray(problem.cell.noise_sigma_grey if noise_grey is None else noise_grey, float)
    fixed = np.asarray(problem.fixed_mask, bool) & _same_in_every_design(centres, axes, radii, depth)
    parts: list[tuple[np.ndarray, Terms]] = []
    if fixed.any():
        idx = np.flatnonzero(fixed)
        terms = _fixed_terms(problem, centres[0, idx], axes[0, idx], radii[0, idx])
        parts.append((idx, _map(lambda a: np.tile(a, (B,) + (1,) * (a.ndim - 1)), terms)))
    if not fixed.all():
        idx = np.flatnonzero(~fixed)
        parts.append((idx, _hole_terms(problem, centres[:, idx], axes[:, idx], radii[:, idx])))
    geo, J, occ = _assemble(parts, B * L, N)
    models = cell_models(problem.cell)
    # measures.pose_information's steps (detection=True, the measurement model's σ and offsets, no prior)
    ratio_bl = np.broadcast_to(ratio, (B, N)).repeat(L, axis=0)
    p = models.detection_probability(geo, occ, depth_ratio=ratio_bl, through=through)
    rate = glare_rate(problem, centres, axes, radii, through, noise)
    if rate is not None:
        p = p * rate
    kw = {"noise_grey": float(noise) if noise.ndim == 0 else np.tile(noise.reshape(L, 1), (B, 1))}
    sig, off = models.measurement_model(geo, depth_ratio=ratio_bl,
                                        kinds=hole_kinds(problem.model.holes), through=through,
                                        **kw)  # pyright: ignore[reportArgumentType] (a (B·L, 1) noise per pose)
    from cadfeat.measures.pose_information import weighted_information  # lazy: as pose_models above

    _, per_hole, rhs = weighted_information(p, J, sig, off)
    return _pose_error(per_hole.sum(axis=1), rhs, problem.objective_config.pose_rotation_length_mm)


class StackedPose:
    """``stacked_information``'s result: ``information`` (B·L, 6, 6) and the predicted errors of
    ``measures.pose_information`` (``error_mm`` as ``PoseInformation.error_mm``)."""

    def __init__(self, information: np.ndarray, error_translation_mm: np.ndarray, error_rotation_deg: np.ndarray,
                 rotation_length_mm: float):
        self.information = information
        self.error_translation_mm, self.error_rotation_deg = error_translation_mm, error_rotation_deg
        self.rotation_length_mm = rotation_length_mm

    def error_mm(self, rotation_length_mm: float | None = None) -> np.ndarray:
        """(B·L,) √(e_t² + (ℓ e_r)²) mm (``PoseInformation.error_mm``)."""
        ell = self.rotation_length_mm if rotation_length_mm is None else rotation_length_mm
        return np.hypot(self.error_translation_mm, ell * np.radians(self.error_rotation_deg))


def _same_in_every_design(centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                          depth: np.ndarray) -> np.ndarray:
    """(N,) bool: holes whose centre, axis, radius and depth are the same in all B designs."""
    return (np.all(centres == centres[:1], axis=(0, 2)) & np.all(axes == axes[:1], axis=(0, 2))
            & np.all(radii == radii[:1], axis=0) & np.all(depth == depth[:1], axis=0))


Terms = tuple["HoleGeometry", np.ndarray, np.ndarray]
"""What depends on each hole alone: (``pose_models.HoleGeometry``, measurement Jacobian, rim hidden fraction)."""


def _map(fn: Callable[[np.ndarray], np.ndarray], terms: Terms) -> Terms:
    """``fn`` applied to every array of (HoleGeometry, J, occlusion) (the geometry's ``rims`` tuple included)."""
    geo, J, occ = terms
    fields: list[Any] = [tuple(fn(a) for a in cast("tuple[np.ndarray, ...]", v)) if isinstance(v, tuple) else
                         None if v is None else fn(v) for v in geo]
    return type(geo)(*fields), fn(J), fn(occ)


def _assemble(parts: list[tuple[np.ndarray, Terms]], M: int, N: int) -> Terms:
    """(HoleGeometry, J, occlusion) of all N holes (M, N, …) from parts (hole indices, the same of those holes)."""
    def put(pieces: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
        a0 = pieces[0][1]
        out = np.empty((M, N) + a0.shape[2:], dtype=a0.dtype)
        for idx, a in pieces:
            out[:, idx] = a
        return out
    geos = [t[0] for _, t in parts]
    fields: list[Any] = []
    for k, v in enumerate(geos[0]):
        if isinstance(v, tuple):
            fields.append(tuple(put([(idx, cast("tuple[np.ndarray, ...]", g[k])[j])
                                     for (idx, _), g in zip(parts, geos, strict=True)])
                                for j in range(len(v))))
        elif v is None:
            fields.append(None)
        else:
            fields.append(put([(idx, cast(np.ndarray, g[k])) for (idx, _), g in zip(parts, geos, strict=True)]))
    return (type(geos[0])(*fields), put([(idx, t[1]) for idx, t in parts]),
            put([(idx, t[2]) for idx, t in parts]))


def _pose_error(info: np.ndarray, rhs: np.ndarray, ell: float) -> StackedPose:
    """The predicted errors of ``measures.pose_information`` from the summed information and bias right-hand
    side (its steps): covariance (its ``_inverse``), bias δ_b = cov · rhs, √(bias² + σ²) per part."""
    from cadfeat.measures.pose_information import (
        _inverse,  # pyright: ignore[reportPrivateUsage] (its steps, as the module docstring says)
        pose_errors,
    )

    cov = _inverse(info, ell)[0]
    _, sig_t, sig_r, b_t, b_r = pose_errors(cov, rhs)
    return StackedPose(info, np.hypot(b_t, sig_t), np.hypot(b_r, sig_r), float(ell))


def _hole_terms(problem: PoseProblem, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray) -> Terms:
    """What depends on each hole alone, for B designs' holes (B, n, …) at the problem's L poses as B·L stacked
    poses: ``pose_models.hole_geometry``, the measurement Jacobian (``rim_centre.measure``) (B·L, n, 2, 6) and
    the rims' hidden fraction (``rim_occlusion`` against the depth maps; 0 without them) (B·L, n)."""
    from cadfeat.measures import pose_models  # lazy: would import scipy.spatial at module load
    from cadfeat.measures.rim_centre import measure
    from cadfeat.measures.rim_occlusion import rim_occlusion

    B, n = radii.shape
    T = problem.T_cam_part
    L = len(T)

    def per_pose(a: np.ndarray) -> np.ndarray:  # (B, n, ...) → (B·L, n, ...)
        return np.repeat(a, L, axis=0)
    maps = problem.occlusion
    occlusion = np.zeros((B * L, n))
    if maps is not None:  # the B·n holes side by side at the L poses (one depth map per pose), then design-major
        hidden = rim_occlusion(maps, T, centres.reshape(B * n, 3), axes.reshape(B * n, 3), radii.reshape(B * n),
                               samples=RIM_SAMPLES)
        occlusion = np.moveaxis(hidden.reshape(L, B, n), 1, 0).reshape(B * L, n)
    TT, c, a, r = np.tile(T, (B, 1, 1)), per_pose(centres), per_pose(axes), per_pose(radii)
    geo = pose_models.hole_geometry(problem.camera, TT, c, a, r)
    J = measure(problem.camera, TT, c, a, r)[1]
    assert J is not None  # (measure with jacobian=True)
    return geo, J, occlusion


_CACHE: OrderedDict[bytes, tuple[tuple[object, ...], Terms, int]] = OrderedDict()
#: fixed holes' terms kept (one entry per pose set: the nominal poses, each robust source's and held-out draws)
CACHE_ENTRIES = 8
#: the most the kept terms may hold, as a share of the memory budget (``design.memory.budget_bytes``)
CACHE_BUDGET_SHARE = 0.25


def _fixed_terms(problem: PoseProblem, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray) -> Terms:
    """``_hole_terms`` of one set of holes (n, …) at the problem's L poses, kept for the same poses, occlusion
    maps, camera and holes (a key of their bytes; the camera and maps objects are held with the entry so their
    ids stay theirs); at most ``CACHE_ENTRIES`` pose sets and ``CACHE_BUDGET_SHARE`` of the memory budget, the
    least recently used dropped first."""
    maps = problem.occlusion
    parts = [np.asarray(problem.T_cam_part, float), centres, axes, radii]
    if maps is not None:
        for name in ("rows", "to_nominal"):
            a = getattr(maps, name, None)
            if a is not None:
                parts.append(np.asarray(a))
    h = hashlib.blake2b(digest_size=20)
    for a in parts:
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    objects = (problem.camera, None if maps is None else maps.maps)
    h.update(repr(tuple(id(o) for o in objects)).encode())
    key = h.digest()
    hit = _CACHE.get(key)
    if hit is not None:
        _CACHE.move_to_end(key)
        return hit[1]
    terms = _map(lambda a: a, _hole_terms(problem, centres[None], axes[None], radii[None]))
    _CACHE[key] = (objects, terms, _nbytes(terms))
    cap = budget_bytes() * CACHE_BUDGET_SHARE  # the kept terms stay a small part of the memory budget
    while len(_CACHE) > CACHE_ENTRIES or (_CACHE and sum(e[2] for e in _CACHE.values()) > cap):
        _CACHE.popitem(last=False)
    return terms


def _nbytes(terms: Terms) -> int:
    """Bytes of the arrays of (HoleGeometry, J, occlusion)."""
    total = [0]

    def add(a: np.ndarray) -> np.ndarray:
        total[0] += int(np.asarray(a).nbytes)
        return a
    _map(add, terms)
    return total[0]
