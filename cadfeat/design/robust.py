"""Robust objectives: optimise a statistic of the combined objective over a fixed set of draws of the cell.

``RobustProblem(problem, objective, draws)`` is the same design problem seen through the uncertainty of
``cadfeat.design.uncertainty``: its ``evaluate_batch(X)`` evaluates the B designs

- nominally (``Problem.batch_objectives``: the kept requirements and thresholds use the nominal values),
- in the S drawn cells (``robustness.cell_objectives``: camera mount, part placement, path offset, time scaling
  and pixel noise together; one stack of S·L poses per memory chunk),
- as the shop makes them in S draws (``robustness.shop_objectives``: the holes the study designs displaced and
  resized within the shop's tolerances; B·S designs in one batch),

and returns ONE objective, the statistic of the combined value (``Problem.combined_from``, the nominal
normalisation) — the smaller over the two sources, so a design must hold up under each:

- ``"percentile"`` (default): the q-th percentile (q = 10; linear interpolation between the order statistics);
- ``"mean"``: the mean;
- ``"chance"``: the nominal combined value, with the chance constraint "measure g_k ≥ bound in a share p of the
  cells" as one more margin: (the (1 − p) quantile of g_k − bound) / scale_k ≥ 0.

The draws are fixed (common random numbers), so the optimisers see a deterministic function of the design and
the same seed gives the same robust optimum bit for bit. Works with every measure, g_POSE included (its pixel
noise draws enter through the σ model). ``robust_optimise`` runs local solves of the robust problem from given
starts (the nominal optimum, the best end-points of the nominal multi-start, the initial design).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from cadfeat.design.objectives import ObjectiveConfig
from cadfeat.design.uncertainty import Draws
from cadfeat.errors import CadfeatError

__all__ = ["STATISTICS", "RobustObjective", "RobustProblem", "robust_optimise", "statistic"]

STATISTICS = ("percentile", "mean", "chance")


@dataclass(frozen=True)
class RobustObjective:
    """What the robust optimiser maximises (module docstring); ``chance_min`` in the measure's raw units."""

    statistic: str = "percentile"
    percentile: float = 10.0
    chance_measure: str | None = None
    chance_min: float | None = None
    chance_probability: float = 0.95

    @staticmethod
    def from_settings(spec: Any) -> RobustObjective:
        return RobustObjective(spec.statistic, float(spec.percentile), spec.chance_measure,
                               None if spec.chance_min is None else float(spec.chance_min),
                               float(spec.chance_probability))

    @property
    def label(self) -> str:
        if self.statistic == "percentile":
            return f"p{self.percentile:g}"
        if self.statistic == "mean":
            return "mean"
        return f"nominal, P({self.chance_measure} ≥ {self.chance_min:g}) ≥ {self.chance_probability:g}"


def statistic(values: np.ndarray, objective: RobustObjective, axis: int = -1) -> np.ndarray:
    """The objective's statistic of ``values`` over the draws (``axis``): the percentile or the mean (for
    "chance": the percentile, as a report of the spread)."""
    v = np.asarray(values, float)
    if objective.statistic == "mean":
        return v.mean(axis=axis)
    return np.percentile(v, objective.percentile, axis=axis)


class _ScalarConfig:
    """The objective configuration the solvers see: one objective, maximised as it is."""

    combine = "weighted"
    measures = ("robust",)
    weights: dict[str, float] = {}
    thresholds: dict[str, float] = {}


class RobustProblem:
    """``problem`` seen through a statistic over fixed ``draws`` (module docstring). ``changed`` (N,) bool: the
    holes the shop makes (default: the movable ones, all when none moves)."""

    def __init__(self, problem: Any, objective: RobustObjective, draws: Draws, changed: Any = None):
        if problem.objective_config.combine == "pareto":
            raise CadfeatError("robustness.robust: a robust objective needs one combined value; allowed: "
                               "objective.combine = maxmin, weighted or constraint, or robustness.robust = false")
        if objective.statistic not in STATISTICS:
            raise CadfeatError(f"robustness.statistic: {objective.statistic!r}; allowed: {', '.join(STATISTICS)}")
        self.inner, self.objective, self.draws = problem, objective, draws
        self.space, self.model = problem.space, problem.model
        fixed = np.asarray(problem.fixed_mask, bool)
        self.changed = (~fixed if (~fixed).any() else np.ones_like(fixed)) if changed is None else \
            np.asarray(changed, bool)
        self.names = [f"robust {objective.label} of the combined objective"]
        self.objective_config = _ScalarConfig()
        self.scales, self.offsets, self.combined_idx = np.ones(1), np.zeros(1), np.array([0])
        self.n_evals = 0
        self._chance = None
        if objective.statistic == "chance":
            names = list(problem.names)
            key = ObjectiveConfig.key
            idx = [i for i, n in enumerate(names) if key(n) == objective.chance_measure]
            if not idx or objective.chance_min is None:
                raise CadfeatError(f"robustness.chance_measure: {objective.chance_measure!r} is not a measure of the "
                                   f"study; allowed: {', '.join(key(n) for n in names)} (and a chance_min)")
            self._chance = idx[0]

    # the solvers' view of one objective, maximised as it is
    def normalised(self, G: np.ndarray) -> np.ndarray:
        return np.asarray(G, float)

    def combined_from(self, G: np.ndarray) -> np.ndarray:
        return np.asarray(G, float)[..., 0]

    def constraint_labels(self) -> list[tuple[str, list[str]]]:
        extra = [(f"chance:{self.objective.chance_measure}", [])] if self._chance is not None else []
        return self.inner.constraint_labels() + extra

    def constraints(self, x: np.ndarray) -> np.ndarray:
        return self.evaluate_batch(np.asarray(x, float)[None])[1][0]

    def draw_objectives(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Raw objectives of designs X (B, P): nominal (B, K), in the drawn cells (B, S, K) and as the shop makes
        them (B, S, K; the nominal repeated when the shop's tolerances are zero)."""
        from cadfeat.design.robustness import cell_objectives, shop_objectives

        p = self.inner
        c, a, r = p.model.features_batch(np.atleast_2d(np.asarray(X, float)))
        a = np.broadcast_to(a, c.shape)
        G0 = p.batch_objectives(c, a, r)
        Gc = cell_objectives(p, c, a, r, self.draws)
        if np.any(self.draws.hole_shift_mm) or np.any(self.draws.diameter_mm):
            Gs = shop_objectives(p, c, a, r, self.changed, self.draws)
        else:
            Gs = np.repeat(G0[:, None], self.draws.size, axis=1)
        return G0, Gc, Gs

    def evaluate_batch(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The robust objective (B, 1) and the margins (B, M) (the nominal kept requirements, and the chance
        constraint's margin last) of designs X (B, P)."""
        X = np.atleast_2d(np.asarray(X, float))
        p = self.inner
        G0, Gc, Gs = self.draw_objectives(X)
        c, _, r = p.model.features_batch(X)
        C = p.features_constraints(c, r, G0, X)
        if self.objective.statistic == "chance":
            value = np.asarray(p.combined_from(G0), float)
            k, q = self._chance, 100.0 * (1.0 - self.objective.chance_probability)
            low = np.minimum(np.percentile(Gc[..., k], q, axis=1), np.percentile(Gs[..., k], q, axis=1))
            margin = (low - float(self.objective.chance_min)) / float(p.scales[k])
            C = np.concatenate([C, margin[:, None]], axis=1)
        else:
            value = np.minimum(statistic(p.combined_from(Gc), self.objective),
                               statistic(p.combined_from(Gs), self.objective))
        self.n_evals += len(X)
        return np.asarray(value, float)[:, None], C


def robust_optimise(problem: RobustProblem, config: Any, starts: Sequence[np.ndarray],
                    progress: Any = None) -> Any:
    """The best of local solves of ``problem`` from each of ``starts`` (feasible first, then the robust value;
    ties keep the earlier start): an ``optimize.OptimResult`` with ``starts`` summarising each solve."""
    from cadfeat.design.optimize import optimise

    local = dataclasses.replace(config, method="local")
    best, summaries = None, []
    for k, x in enumerate(starts):
        res = optimise(problem, local, progress, x_start=np.asarray(x, float))
        summaries.append({"start": k, "x_start": np.asarray(x, float).tolist(), "x_end": res.x_best.tolist(),
                          "combined": float(res.combined_best), "feasible": bool(res.feasible)})
        if best is None or (res.feasible, res.combined_best) > (best.feasible, best.combined_best):
            best = res
        if res.interrupted:
            break
    if best is None:
        raise CadfeatError("robust optimisation: no start given")
    best.starts = summaries
    return best
