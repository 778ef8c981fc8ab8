"""Robustness of an optimum: how much the objectives drop under shop tolerances and a camera mounting error.

Sampled on features (cheap, no CAD): ``robustness(problem, centres, axes, radii, changed, ...)``

- manufacturing: each changed hole (moved or resized) displaced uniformly within ±``position_tol_mm`` along
  two directions across its axis, and its diameter moved by a random whole number of steps in
  [−``size_steps``, ``size_steps``] of the size table (a drill one size off); the ``samples`` draws evaluated
  batched (``Problem.batch_objectives``, chunked to the memory budget);
- camera mount: the camera frame displaced by a rigid ``ΔT`` (translation uniform within ±``camera_position_mm``
  per axis, rotation vector within ±``camera_angle_deg`` per axis), the same for every pose of a draw (a
  mounting error is constant): ``T_cam'_part = ΔT⁻¹ T_cam_part`` and the camera twist
  ``v' = Rᵀ (v − p × ω)``, ``ω' = Rᵀ ω``; the ``samples`` draws are evaluated as stacks of L·S poses
  (one ``measures.evaluate`` call per chunk of draws within the memory budget, ``cadfeat.design.memory``) and
  aggregated per draw.

For each objective and the combined value: nominal, mean, 5th percentile and minimum over the draws. The
optimum is a *razor edge* when the combined value's 5th percentile under either perturbation keeps less than
``RAZOR_KEEP`` of the gain over the original design (or falls below the original when there is no gain).
Units: mm, degrees; objectives in their own units, larger = better.
"""

from __future__ import annotations

import copy
import types
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["RAZOR_KEEP", "robustness"]

RAZOR_KEEP = 0.5
"""Share of the combined objective's gain the 5th percentile must keep under a perturbation."""


def _rotvec_to_R(w: np.ndarray) -> np.ndarray:
    """(S, 3) rotation vectors (rad) → (S, 3, 3) rotation matrices (Rodrigues)."""
    theta = np.linalg.norm(w, axis=-1, keepdims=True)
    k = np.where(theta > 0, w / np.where(theta > 0, theta, 1.0), 0.0)
    K = np.zeros(w.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -k[..., 2], k[..., 1], -k[..., 0]
    K = K - np.swapaxes(K, -1, -2)
    t = theta[..., None]
    return np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * (K @ K)


def _across(axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors across each axis (N, 3)."""
    helper = np.eye(3)[np.argmin(np.abs(axes), axis=1)]
    u = helper - np.sum(helper * axes, axis=1, keepdims=True) * axes
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return u, np.cross(axes, u)


def _stats(G: np.ndarray, nominal: np.ndarray) -> dict[str, np.ndarray]:
    return {"nominal": nominal, "mean": G.mean(axis=0), "p05": np.percentile(G, 5, axis=0), "min": G.min(axis=0)}


def camera_objectives(problem: Any, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                      dT: np.ndarray) -> np.ndarray:
    """Raw objectives (S, K) of one design seen by S displaced cameras ``dT`` (S, 4, 4) (camera frame), the draws
    evaluated in chunks within the memory budget (``cadfeat.design.memory``: each draw stacks L poses and, with
    occlusion, its own copy of the L depth maps)."""
    from cadfeat.design.memory import chunked, design_bytes

    per_draw = design_bytes(len(problem.screws), len(radii), depth_maps=problem.occlusion_mesh is not None)
    _ = problem.occlusion  # the nominal poses' depth maps, built once and shared by every chunk's stacked copy
    return chunked(lambda sl: _camera_objectives(problem, centres, axes, radii, dT[sl]), len(dT), per_draw,
                   "robustness analysis (camera-mount draws)")


def _camera_objectives(problem: Any, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                       dT: np.ndarray) -> np.ndarray:
    """``camera_objectives`` of one chunk of draws, as one stack of S·L poses."""
    from cadfeat.design.objectives import aggregate, per_pose_values

    S = len(dT)
    L = len(problem.screws)
    R, p = dT[:, :3, :3], dT[:, :3, 3]
    Rt = np.swapaxes(R, 1, 2)
    inv = np.zeros_like(dT)
    inv[:, :3, :3], inv[:, :3, 3], inv[:, 3, 3] = Rt, -np.einsum("sij,sj->si", Rt, p), 1.0
    T = (inv[:, None] @ problem.T_cam_part[None]).reshape(S * L, 4, 4)
    v, w = problem.screws[None, :, :3], problem.screws[None, :, 3:]
    v2 = np.einsum("sij,slj->sli", Rt, v - np.cross(p[:, None, :], w))
    w2 = np.einsum("sij,slj->sli", Rt, np.broadcast_to(w, (S, L, 3)))
    stacked = copy.copy(problem)
    stacked.T_cam_part, stacked.screws = T, np.concatenate([v2, w2], axis=-1).reshape(S * L, 6)
    m = stacked.measures_from_features(centres, axes, radii)
    cfg = problem.objective_config

    class _PerDraw:  # the (S·L, …) arrays seen as S designs of L poses
        def __getattr__(self, name: str) -> np.ndarray:
            a = np.asarray(getattr(m, name))
            return a.reshape((S, L) + a.shape[1:])

    g_pose = None
    if "pose" in cfg.measures:  # g_POSE: one pose_information on the S·L stacked poses (``design.pose_terms``)
        from cadfeat.design.pose_terms import pose_aggregate_batch, pose_of_features

        info = pose_of_features(stacked, centres, axes, radii)
        e = info.error_mm(cfg.pose_rotation_length_mm).reshape(S, L)
        g_pose = pose_aggregate_batch(e, info.information.reshape(S, L, 6, 6), cfg.pose_aggregate,
                                      cfg.pose_rotation_length_mm)
        _PerDraw.pose = types.SimpleNamespace(error_mm=lambda _ell=None: e)  # type: ignore[attr-defined]
    values = per_pose_values(_PerDraw(), cfg, problem.feature_mask)
    return np.stack([g_pose if k == "pose" else aggregate(values[k], cfg.aggregate, cfg.smoothmin_beta,
                                                          problem.units[k])
                     for k in cfg.measures], axis=-1)


def robustness(problem: Any, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray, changed: np.ndarray, *,
               position_tol_mm: float = 0.1, size_steps: int = 1, sizes: Sequence[float] = (),
               camera_position_mm: float = 2.0, camera_angle_deg: float = 1.0, samples: int = 200,
               combined_before: float | None = None, seed: int = 0) -> dict[str, Any]:
    """The robustness block of results.json for the design with features (N,3), (N,3), (N,) (part frame, mm);
    ``changed`` (N,) bool: the holes the shop makes anew (moved or resized)."""
    rng = np.random.default_rng(seed)
    c, a, r = (np.asarray(v, float) for v in (centres, axes, radii))
    changed = np.asarray(changed, bool)
    names = list(problem.names)
    nominal = problem.features_objectives(c, a, r)
    pareto = problem.objective_config.combine == "pareto"
    comb = (lambda G: problem.combined_from(G)) if not pareto else None  # noqa: E731
    out: dict[str, Any] = {"position_tol_mm": position_tol_mm, "size_steps": size_steps,
                           "camera_position_mm": camera_position_mm, "camera_angle_deg": camera_angle_deg,
                           "samples": samples, "names": names, "razor_edge": []}
    if samples <= 0:
        return out
    # manufacturing
    u, v = _across(a)
    du = rng.uniform(-1, 1, (samples, len(r), 2)) * position_tol_mm * changed[None, :, None]
    C = c[None] + du[..., :1] * u[None] + du[..., 1:] * v[None]
    Rr = np.broadcast_to(r, (samples, len(r))).copy()
    if size_steps and len(sizes):
        table = np.asarray(sorted(sizes), float)
        k0 = np.argmin(np.abs(table[None] - 2 * r[:, None]), axis=1)
        steps = rng.integers(-size_steps, size_steps + 1, (samples, len(r))) * changed[None]
        Rr = np.where(changed[None], table[np.clip(k0[None] + steps, 0, len(table) - 1)] / 2, Rr)
    G_man = problem.batch_objectives(C, np.broadcast_to(a, C.shape), Rr)
    # camera mount
    dT = np.tile(np.eye(4), (samples, 1, 1))
    dT[:, :3, :3] = _rotvec_to_R(np.radians(rng.uniform(-camera_angle_deg, camera_angle_deg, (samples, 3))))
    dT[:, :3, 3] = rng.uniform(-camera_position_mm, camera_position_mm, (samples, 3))
    G_cam = camera_objectives(problem, c, a, r, dT)
    for key, G in (("manufacturing", G_man), ("camera", G_cam)):
        st = _stats(G, nominal)
        block = {n: {s: float(st[s][k]) for s in st} for k, n in enumerate(names)}
        if comb is not None:
            cv = np.asarray(comb(G), float)
            c0 = float(comb(nominal))
            block["combined"] = {"nominal": c0, "mean": float(cv.mean()), "p05": float(np.percentile(cv, 5)),
                                 "min": float(cv.min())}
            if combined_before is not None:
                gain = c0 - combined_before
                floor = combined_before + RAZOR_KEEP * gain if gain > 0 else combined_before
                if block["combined"]["p05"] < floor:
                    out["razor_edge"].append(key)
        out[key] = block
    return out
