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
import dataclasses
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.design.uncertainty import Draws
from cadfeat.poses import rotvec_matrix

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.design.problem import Problem
    from cadfeat.results import JsonDict

__all__ = ["RAZOR_KEEP", "camera_objectives", "cell_objectives", "cell_poses", "robustness", "shop_features",
           "shop_objectives"]

RAZOR_KEEP = 0.5
"""Share of the combined objective's gain the 5th percentile must keep under a perturbation."""


def _across(axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors across each axis (N, 3)."""
    helper = np.eye(3)[np.argmin(np.abs(axes), axis=1)]
    u = helper - np.sum(helper * axes, axis=1, keepdims=True) * axes
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return u, np.cross(axes, u)


def _stats(G: np.ndarray, nominal: np.ndarray) -> dict[str, np.ndarray]:
    return {"nominal": nominal, "mean": G.mean(axis=0), "p05": np.percentile(G, 5, axis=0), "min": G.min(axis=0)}


def camera_objectives(problem: Problem, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                      dT: np.ndarray) -> np.ndarray:
    """Raw objectives (S, K) of one design seen by S displaced cameras ``dT`` (S, 4, 4) (camera frame):
    ``cell_objectives`` with only a camera mounting error."""
    S = len(dT)
    draws = Draws.nominal(S, len(radii))
    draws = dataclasses.replace(draws, dC=np.asarray(dT, float))
    return cell_objectives(problem, np.asarray(centres, float)[None], np.asarray(axes, float)[None],
                           np.asarray(radii, float)[None], draws)[0]


def cell_objectives(problem: Problem, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                    draws: Draws, depth_mm: np.ndarray | None = None) -> np.ndarray:
    """Raw objectives (B, S, K) of B designs' features (B, N, 3), (B, N, 3), (B, N) in S cells that differ from
    the nominal one by ``draws`` (camera mount, part placement, path offset, time scaling, pixel noise; the
    shop's hole errors are ``shop_objectives``'). The draws are evaluated in chunks within the memory budget
    (``cadfeat.design.memory``), each chunk as ONE stack of S·L poses (``Problem.pose_arrays``) aggregated per
    (design, draw) — no loop over designs, poses, holes or draws beyond the chunks. ``depth_mm`` (B, N): the
    designs' hole depths for g_POSE (None: the reference holes')."""
    from cadfeat.design.memory import chunked, design_bytes  # lazy: looked up per call (tests replace it)

    B, N = np.shape(radii)
    per_draw = B * design_bytes(len(problem.screws), N)
    _ = problem.occlusion  # the nominal poses' depth maps, built once and shared (a view) by every chunk's stack
    out = chunked(lambda sl: np.moveaxis(_cell_chunk(problem, centres, axes, radii, draws.take(sl), depth_mm),
                                              1, 0),
                  draws.size, per_draw, "robustness (cell draws)")
    return np.moveaxis(out, 0, 1)


def cell_poses(problem: Problem, draws: Draws) -> tuple[np.ndarray, np.ndarray]:
    """The S·L poses ``T_cam_part`` (S·L, 4, 4) and camera screws (S·L, 6) of the S drawn cells (draw-major).

    Camera mount ``ΔC`` (camera frame, the same at every pose): ``T' = ΔC⁻¹ T`` and ``v' = Rᵀ (v − p × ω)``,
    ``ω' = Rᵀ ω``; part placement ``ΔP`` (part frame) and path offset δ (task frame; ``T_task_cam' = Tr(δ)
    T_task_cam``, the same as the part displaced by −δ): ``T' = … T Tr(−R_tpᵀ δ) ΔP`` — a static part does not
    change the camera's screw; time scaling k: the screws × k (the same path k times faster)."""
    S, L = draws.size, len(problem.screws)
    dC = draws.dC
    R, p = dC[:, :3, :3], dC[:, :3, 3]
    Rt = np.swapaxes(R, 1, 2)
    inv = np.zeros_like(dC)
    inv[:, :3, :3], inv[:, :3, 3], inv[:, 3, 3] = Rt, -np.einsum("sij,sj->si", Rt, p), 1.0
    R_tp = problem.T_task_part[:3, :3]
    right = draws.dP.copy()
    right[:, :3, 3] -= draws.offset_mm @ R_tp  # Tr(−R_tpᵀ δ) ΔP: the offset applied before ΔP (left of it)
    T = (inv[:, None] @ problem.T_cam_part[None] @ right[:, None]).reshape(S * L, 4, 4)
    v, w = problem.screws[None, :, :3], problem.screws[None, :, 3:]
    v2 = np.einsum("sij,slj->sli", Rt, v - np.cross(p[:, None, :], w))
    w2 = np.einsum("sij,slj->sli", Rt, np.broadcast_to(w, (S, L, 3)))
    screws = np.concatenate([v2, w2], axis=-1) * draws.time_scale[:, None, None]
    return T, screws.reshape(S * L, 6)


def _cell_chunk(problem: Problem, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                draws: Draws, depth_mm: np.ndarray | None = None) -> np.ndarray:
    """``cell_objectives`` (B, S, K) of one chunk of draws, as one stack of S·L poses."""
    S, L = draws.size, len(problem.screws)
    B = len(radii)
    stacked = copy.copy(problem)
    stacked.T_cam_part, stacked.screws = cell_poses(problem, draws)
    maps, glare = problem.occlusion, problem.glare
    if maps is not None or glare is not None:  # nominal maps, looked up where each pose's nominal camera sees a point
        to_nominal = np.tile(problem.T_cam_part, (S, 1, 1)) @ _inverse(stacked.T_cam_part)
        if maps is not None:
            stacked._depth_maps = maps.tile(S, to_nominal)  # pyright: ignore[reportPrivateUsage] (the problem's copy)
        if glare is not None:
            stacked._glare = glare.tile(S, to_nominal)  # pyright: ignore[reportPrivateUsage] (the problem's copy)
    noise = None
    if "pose" in problem.objective_config.measures and draws.noise_grey is not None:
        noise = np.repeat(draws.noise_grey, L)[:, None]
    arrays = stacked.pose_arrays(np.asarray(centres, float), np.asarray(axes, float), np.asarray(radii, float),
                                 noise, depth_mm)

    def per_draw(a: np.ndarray) -> np.ndarray:  # (B, S·L, …) → (B·S, L, …)
        return a.reshape((B * S, L) + a.shape[2:])
    arrays = {k: tuple(map(per_draw, v)) if isinstance(v, tuple) else per_draw(np.asarray(v))
              for k, v in arrays.items()}
    return problem.aggregate_arrays(arrays).reshape(B, S, -1)


def _inverse(T: np.ndarray) -> np.ndarray:
    """Inverses (…, 4, 4) of rigid transforms."""
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    out = np.zeros_like(T)
    out[..., :3, :3], out[..., 3, 3] = Rt, 1.0
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3])
    return out


def shop_features(centres: np.ndarray, axes: np.ndarray, radii: np.ndarray, changed: np.ndarray,
                  draws: Draws) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Features (B, S, N, 3), (B, S, N, 3), (B, S, N) of B designs (B, N, 3), (B, N, 3), (B, N) as the shop makes
    them in S draws: each ``changed`` hole (N,) displaced by ``draws.hole_shift_mm`` (S, N, 2) across its axis and
    its diameter changed by ``draws.diameter_mm`` (S, N) (radius by half of it, at least 0.05 mm)."""
    c, a, r = (np.asarray(v, float) for v in (centres, axes, radii))
    u, v = _across(a.reshape(-1, 3))
    u, v = u.reshape(a.shape), v.reshape(a.shape)
    m = np.asarray(changed, float)[None, :, None]
    d = draws.hole_shift_mm * m  # (S, N, 2)
    C = c[:, None] + d[None, ..., :1] * u[:, None] + d[None, ..., 1:] * v[:, None]
    R = np.maximum(r[:, None] + 0.5 * draws.diameter_mm[None] * m[..., 0], 0.05)
    return C, np.broadcast_to(a[:, None], C.shape), R


def shop_objectives(problem: Problem, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray, changed: np.ndarray,
                    draws: Draws, depth_mm: np.ndarray | None = None) -> np.ndarray:
    """Raw objectives (B, S, K) of B designs made by the shop in S draws (``shop_features``), as B·S designs of
    ONE batched evaluation (``Problem.batch_objectives``, chunked to the memory budget)."""
    C, A, R = shop_features(centres, axes, radii, changed, draws)
    B, S, N = R.shape
    depth = None if depth_mm is None else np.repeat(np.asarray(depth_mm, float), S, axis=0)  # (B·S, N)
    G = problem.batch_objectives(C.reshape(B * S, N, 3), A.reshape(B * S, N, 3), R.reshape(B * S, N),
                                 depth_mm=depth)
    return G.reshape(B, S, -1)


def robustness(problem: Problem, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray, changed: np.ndarray, *,
               position_tol_mm: float = 0.1, size_steps: int = 1, sizes: Sequence[float] = (),
               camera_position_mm: float | Sequence[float] = 2.0, camera_angle_deg: float | Sequence[float] = 1.0,
               samples: int = 200,
               combined_before: float | None = None, seed: int = 0) -> JsonDict:
    """The robustness block of results.json for the design with features (N,3), (N,3), (N,) (part frame, mm);
    ``changed`` (N,) bool: the holes the shop makes anew (moved or resized)."""
    rng = np.random.default_rng(seed)
    cam_mm, cam_deg = np.asarray(camera_position_mm, float), np.asarray(camera_angle_deg, float)  # one or per axis
    c, a, r = (np.asarray(v, float) for v in (centres, axes, radii))
    changed = np.asarray(changed, bool)
    names = list(problem.names)
    nominal = problem.features_objectives(c, a, r)
    pareto = problem.objective_config.combine == "pareto"
    comb: Callable[[np.ndarray], np.ndarray] | None = problem.combined_from if not pareto else None
    razor: list[str] = []
    out: JsonDict = {"position_tol_mm": position_tol_mm, "size_steps": size_steps,
                     "camera_position_mm": cam_mm.tolist(), "camera_angle_deg": cam_deg.tolist(),
                     "samples": samples, "names": names, "razor_edge": razor}
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
    dT[:, :3, :3] = rotvec_matrix(np.radians(rng.uniform(-cam_deg, cam_deg, (samples, 3))))
    dT[:, :3, 3] = rng.uniform(-cam_mm, cam_mm, (samples, 3))
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
                    razor.append(key)
        out[key] = block
    return out
