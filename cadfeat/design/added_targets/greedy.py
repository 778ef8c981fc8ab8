"""Choosing where to add k target holes: lazy greedy over the candidate sites, and the exhaustive search that
checks it on small cases (issue 31).

The gain of a site — how much it raises g_POSE given the holes already chosen — shrinks as holes are added
(more holes, more information; the objective is close to submodular), so a site's last computed gain is an
upper bound of its next one. The lazy greedy (Minoux's accelerated greedy) keeps these bounds and, at each step,
evaluates only the sites whose bound could still beat the best fresh gain — ``batch`` at a time in one batched
prediction — instead of every site. The objective is not exactly submodular (the detection model couples
nearby rims, and the bias part of the error is not monotone), so the choice is checked against an exhaustive
search on small cases (tests, within 2 %).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

__all__ = ["GreedyResult", "exhaustive", "lazy_greedy"]

Evaluate = Callable[[np.ndarray], np.ndarray]
"""g (B,) of B site sets (B, k) of site indices; larger is better."""


@dataclass
class GreedyResult:
    """The sites in the order chosen (k,), g after each step (k + 1,: g[0] with none added), and how many
    designs were evaluated at each step."""

    order: list[int]
    values: list[float]
    evaluations: list[int] = field(default_factory=list[int])


def _feasible(conflicts: np.ndarray, chosen: list[int]) -> np.ndarray:
    """(M,) bool: sites compatible with every chosen one (not in conflict)."""
    if not chosen:
        return np.ones(len(conflicts), bool)
    return ~np.any(conflicts[chosen], axis=0)


def lazy_greedy(evaluate: Evaluate, conflicts: np.ndarray, k_max: int, batch: int = 24,
                stop: Callable[[list[float]], bool] | None = None) -> GreedyResult:
    """Add up to ``k_max`` sites one at a time, each the feasible site of largest g (module docstring).

    ``conflicts`` (M, M) bool: site pairs that cannot both be chosen (``sites.conflicts``); ``batch``: sites
    evaluated per batched call once the bounds are known (the first step evaluates every site); ``stop(values)``:
    True ends the search early (e.g. the stopping rule of ``[add_targets]``)."""
    M = len(conflicts)
    chosen: list[int] = []
    values = [float(evaluate(np.zeros((1, 0), int))[0])]
    bounds = np.full(M, np.inf)
    counts: list[int] = []
    for _ in range(k_max):
        ok = _feasible(conflicts, chosen)
        if not ok.any():
            break
        gain, n = _best(evaluate, chosen, values[-1], bounds, ok, batch)
        counts.append(n)
        chosen.append(gain)
        values.append(values[-1] + float(bounds[gain]))
        if stop is not None and stop(values):
            break
    return GreedyResult(chosen, values, counts)


def _best(evaluate: Evaluate, chosen: list[int], g: float, bounds: np.ndarray, ok: np.ndarray,
          batch: int) -> tuple[int, int]:
    """The feasible site of largest fresh gain (``bounds`` updated in place to the fresh gains evaluated), and
    how many sites were evaluated: stale sites are evaluated ``batch`` at a time, highest bound first, until
    the best fresh gain is at least every stale bound."""
    fresh = np.zeros(len(bounds), bool)
    n = 0
    while True:
        stale = np.flatnonzero(ok & ~fresh)
        best = np.flatnonzero(ok & fresh)
        top = best[np.argmax(bounds[best])] if best.size else -1
        if stale.size == 0 or (top >= 0 and bounds[top] >= np.max(bounds[stale])):
            return int(top), n
        size = stale.size if np.isinf(bounds[stale]).any() else batch
        pick = stale[np.argsort(-bounds[stale], kind="stable")[:size]]
        held = np.broadcast_to(np.asarray(chosen, int), (len(pick), len(chosen)))
        sets = np.concatenate([held, pick[:, None]], axis=1)
        bounds[pick] = evaluate(sets) - g
        fresh[pick] = True
        n += len(pick)


def exhaustive(evaluate: Evaluate, conflicts: np.ndarray, k: int, chunk: int = 2048) -> tuple[list[int], float]:
    """The best set of ``k`` mutually compatible sites by evaluating every one (the reference of the greedy
    choice: C(M, k) designs, for small M); returns (sites, g)."""
    M = len(conflicts)
    best: tuple[list[int], float] = ([], -np.inf)
    combos = itertools.combinations(range(M), k)
    while True:
        block = np.array(list(itertools.islice(combos, chunk)), int).reshape(-1, k)
        if not len(block):
            return best
        pairs = np.array([conflicts[block[:, i], block[:, j]] for i in range(k) for j in range(i + 1, k)])
        keep = ~pairs.any(axis=0) if pairs.size else np.ones(len(block), bool)
        block = block[keep]
        if len(block):
            g = evaluate(block)
            i = int(np.argmax(g))
            if g[i] > best[1]:
                best = (block[i].tolist(), float(g[i]))
