"""A memory budget for batched evaluations: chunk to it, and refuse at set-up what cannot fit.

Every batched evaluation of the optimiser and of the robustness analysis holds arrays of (designs or draws) ×
poses × features (the measures, the stacked Jacobians) and, for the camera-mount draws, a copy of the depth
maps per draw (poses × grid² cells). A 1,500-pose trajectory with 200 draws asked numpy for 36.6 GiB at once
(issue 16). Here:

- ``MEMORY_BUDGET_BYTES`` (1 GiB) is the most one batch may hold; override it with the environment variable
  ``CADFEAT_MEMORY_BUDGET_BYTES`` or by setting this module's constant;
- ``chunked(fn, n, bytes_per_item, what)`` evaluates ``fn`` on consecutive slices of ``n`` items, each slice
  within the budget, and concatenates the results (the same numbers as one call: items are independent);
- ``check_fits`` estimates, before any work, what the smallest unit of a study needs (the depth maps of every
  pose; one design over every pose) and raises ``MemoryBudgetError`` (one line: what, how much, the budget,
  what to change) when it cannot fit.

Estimates are upper bounds per element (``BYTES_PER_FEATURE_POSE``), not measurements.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any, cast

import numpy as np

from cadfeat.errors import CadfeatError

__all__ = ["BYTES_PER_FEATURE_POSE", "DEPTH_GRID", "MEMORY_BUDGET_BYTES", "MemoryBudgetError", "budget_bytes",
           "check_fits", "chunk_size", "chunked", "depth_map_bytes", "design_bytes"]

MEMORY_BUDGET_BYTES = 1 << 30
"""Most bytes one batched evaluation may hold (1 GiB); env ``CADFEAT_MEMORY_BUDGET_BYTES`` overrides it."""
BYTES_PER_FEATURE_POSE = 512
"""Upper bound of the bytes one (design, pose, feature) needs in a batched evaluation: the measures' (L, N)
arrays (about 16 float64), the stacked Jacobian rows (2 × 6 float64), the aggregation's temporaries."""
DEPTH_GRID = 128
"""Cells per side of the optimiser's depth maps (``Problem.occlusion``)."""


class MemoryBudgetError(CadfeatError):
    """A study's smallest batch cannot fit in the memory budget (raised at set-up, before any work)."""


def budget_bytes() -> int:
    """The memory budget (bytes): ``CADFEAT_MEMORY_BUDGET_BYTES`` if set, else ``MEMORY_BUDGET_BYTES``."""
    raw = os.environ.get("CADFEAT_MEMORY_BUDGET_BYTES")
    if raw is None:
        return int(MEMORY_BUDGET_BYTES)
    try:
        value = int(float(raw))
    except ValueError:
        value = 0
    if value <= 0:
        raise CadfeatError(f"CADFEAT_MEMORY_BUDGET_BYTES={raw!r}: allowed: a positive number of bytes")
    return value


def _gib(n: float) -> str:
    return f"{n / 2**30:.3g} GiB"


def depth_map_bytes(n_poses: int, grid: int = DEPTH_GRID) -> int:
    """Bytes of the depth maps of ``n_poses`` poses (float64, grid² cells each)."""
    return int(n_poses) * int(grid) ** 2 * 8


def design_bytes(n_poses: int, n_holes: int, *, depth_maps: bool = False, grid: int = DEPTH_GRID) -> int:
    """Upper bound of the bytes one design (or one camera draw) needs over ``n_poses`` poses with ``n_holes``
    holes; ``depth_maps``: plus its own copy of the depth maps (a displaced camera's draw)."""
    per = int(n_poses) * max(int(n_holes), 1) * BYTES_PER_FEATURE_POSE
    return per + (depth_map_bytes(n_poses, grid) if depth_maps else 0)


def chunk_size(bytes_per_item: int, what: str) -> int:
    """How many items of ``bytes_per_item`` fit in the budget together (≥ 1); ``MemoryBudgetError`` when not
    even one does."""
    budget = budget_bytes()
    if bytes_per_item > budget:
        raise MemoryBudgetError(f"{what}: one item needs about {_gib(bytes_per_item)}, more than the memory budget "
                                f"of {_gib(budget)} (CADFEAT_MEMORY_BUDGET_BYTES); allowed: fewer trajectory "
                                "samples or holes, objective.occlusion = false, or a larger budget")
    return max(1, budget // max(int(bytes_per_item), 1))


def chunked(fn: Callable[[slice], Any], n: int, bytes_per_item: int, what: str) -> Any:
    """``fn(slice)`` over consecutive slices of ``range(n)`` within the budget, results concatenated along
    axis 0 (a tuple of arrays: each one). One call when everything fits."""
    step = chunk_size(bytes_per_item, what)
    if n <= step:
        return fn(slice(0, n))
    parts: list[Any] = [fn(slice(i, min(i + step, n))) for i in range(0, n, step)]
    if isinstance(parts[0], tuple):
        tuples = cast("list[tuple[np.ndarray, ...]]", parts)
        return tuple(np.concatenate([p[k] for p in tuples], axis=0) for k in range(len(tuples[0])))
    return np.concatenate(parts, axis=0)


def check_fits(n_poses: int, n_holes: int = 1, *, occlusion: bool = True, robustness_samples: int = 0,
               what: str = "study") -> None:
    """Refuse, before any work, a study whose smallest batch cannot fit in the budget: the depth maps of
    every pose (``occlusion``), one design over every pose, one camera-mount draw (``robustness_samples``
    > 0, with its copy of the depth maps). ``MemoryBudgetError`` (one line) otherwise."""
    budget = budget_bytes()
    needs = [("one design over every pose", design_bytes(n_poses, n_holes))]
    if occlusion:
        needs.append(("the occlusion depth maps", depth_map_bytes(n_poses)))
        if robustness_samples > 0:
            needs.append(("one camera-mount draw of the robustness analysis",
                          design_bytes(n_poses, n_holes, depth_maps=True)))
    for label, need in needs:
        if need > budget:
            most = _max_poses(budget, n_holes, occlusion, robustness_samples)
            raise MemoryBudgetError(
                f"{what}: {label} needs about {_gib(need)} for {n_poses:,} trajectory samples, more than the memory "
                f"budget of {_gib(budget)}; allowed: at most {most:,} samples ([trajectory] n), "
                "objective.occlusion = false, or a larger CADFEAT_MEMORY_BUDGET_BYTES")


def _max_poses(budget: int, n_holes: int, occlusion: bool, robustness_samples: int) -> int:
    per_pose = max(n_holes, 1) * BYTES_PER_FEATURE_POSE
    if occlusion:
        per_pose = max(per_pose, DEPTH_GRID ** 2 * 8)
        if robustness_samples > 0:
            per_pose = max(per_pose, max(n_holes, 1) * BYTES_PER_FEATURE_POSE + DEPTH_GRID ** 2 * 8)
    return int(budget // per_pose)
