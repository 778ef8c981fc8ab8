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

from typing import Any

import numpy as np

from cadfeat.design.objectives import POSE_AGGREGATES, POSE_UNOBSERVABLE_MM, _choice

__all__ = ["hole_attributes", "pose_aggregate_batch", "pose_of_features", "pose_values", "stacked_information"]

#: rim samples of the occlusion test (``rim_occlusion``)
RIM_SAMPLES = 16


def hole_attributes(problem: Any, radii: np.ndarray,
                    depth_mm: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(through (N,) bool, depth (N,) or like ``radii`` mm, depth/diameter like ``radii``) of the problem's
    reference holes at ``radii``; ``depth_mm`` (the design's depths, ``design.hole_form``) replaces theirs."""
    holes = list(problem.model.holes)
    through = np.array([bool(getattr(h, "through", False)) for h in holes])
    depth = np.array([float(getattr(h, "depth_mm", 0.0)) for h in holes]) if depth_mm is None else \
        np.asarray(depth_mm, float)
    return through, depth, depth / (2.0 * np.maximum(np.asarray(radii, float), 1e-9))


def pose_of_features(problem: Any, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                     exact_occlusion: bool = False, occlusion: np.ndarray | None = None,
                     depth_mm: np.ndarray | None = None) -> Any:
    """``measures.pose_information`` (L poses × N holes) of one design's features (module docstring).

    ``occlusion`` (L, N) overrides the rim test (e.g. held fixed for finite differences); ``depth_mm`` (N,) the
    design's hole depths (default: the reference holes')."""
    from cadfeat.measures import pose_information
    from cadfeat.measures.rim_occlusion import rim_occlusion

    cfg = problem.objective_config
    through, depth, ratio = hole_attributes(problem, radii, depth_mm)
    T = problem.T_cam_part
    if occlusion is None:
        mesh = problem.occlusion_mesh if exact_occlusion else problem.occlusion
        if mesh is not None:
            occlusion = rim_occlusion(mesh, T, centres, axes, radii, samples=RIM_SAMPLES, through=through,
                                      depth_mm=depth)
    return pose_information(problem.camera, T, centres, axes, radii, occlusion=occlusion, depth_ratio=ratio,
                            through=through, rotation_length_mm=cfg.pose_rotation_length_mm)


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
    sign, logdet = np.linalg.slogdet(np.asarray(information, float) * s[:, None] * s[None, :])
    floor = -12.0 * np.log(POSE_UNOBSERVABLE_MM)
    logdet = np.where((sign > 0) & np.isfinite(logdet), np.maximum(logdet, floor), floor)
    return -np.exp(-np.mean(logdet, axis=-1) / 12.0)


def pose_values(problem: Any, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                exact_occlusion: bool = False, depth_mm: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(g_POSE (B,), per-pose value −e (B, L)) of B designs' features (B, N, 3), (B, N, 3), (B, N); ``depth_mm``
    (B, N) their hole depths (``design.hole_form.design_depths``; None: the reference holes').

    The optimiser's path (depth-map occlusion or none) is ONE ``pose_information`` call on the B·L stacked poses,
    each with its own design's holes; the exact ray test (reported values) takes one design at a time."""
    cfg = problem.objective_config
    ell = cfg.pose_rotation_length_mm
    B, N = np.shape(radii)
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


def stacked_information(problem: Any, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                        noise_grey: Any = None, depth_mm: np.ndarray | None = None) -> Any:
    """``pose_information`` of B designs as B·L poses (design-major), holes per pose; occlusion by the problem's
    depth maps (every design's rims at each of the L poses in one ``rim_occlusion`` call). ``noise_grey``: the
    sensor's grey-level noise, a number or (L, 1) per pose (a robustness draw's pixel noise); None: the model's
    default."""
    from cadfeat.measures import pose_information
    from cadfeat.measures.rim_occlusion import rim_occlusion

    B, N = radii.shape
    T = problem.T_cam_part
    L = len(T)
    TT = np.tile(T, (B, 1, 1))

    def per_pose(a: np.ndarray) -> np.ndarray:  # (B, N, ...) → (B·L, N, ...)
        return np.repeat(a, L, axis=0)
    c, a, r = per_pose(centres), per_pose(axes), per_pose(radii)
    through, depth, ratio = hole_attributes(problem, r, None if depth_mm is None else per_pose(np.asarray(depth_mm,
                                                                                                        float)))
    maps = problem.occlusion
    occlusion = None
    if maps is not None:  # the B·N holes side by side at the L poses (one depth map per pose), then design-major
        hidden = rim_occlusion(maps, T, centres.reshape(B * N, 3), axes.reshape(B * N, 3), radii.reshape(B * N),
                               samples=RIM_SAMPLES)
        occlusion = np.moveaxis(hidden.reshape(L, B, N), 1, 0).reshape(B * L, N)
    noise: dict[str, Any] = {}
    if noise_grey is not None:
        n = np.asarray(noise_grey, float)
        noise["noise_grey"] = float(n) if n.ndim == 0 else np.tile(n.reshape(L, 1), (B, 1))
    return pose_information(problem.camera, TT, c, a, r, occlusion=occlusion, depth_ratio=ratio, through=through,
                            rotation_length_mm=problem.objective_config.pose_rotation_length_mm, **noise)
