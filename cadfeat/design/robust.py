"""Robust objectives: optimise a statistic of the combined objective over a fixed set of draws of the cell.

``RobustProblem(problem, objective, draws)`` is the same design problem seen through the uncertainty of
``cadfeat.design.uncertainty``: its ``evaluate_batch(X)`` evaluates the B designs

- nominally (``Problem.batch_objectives``: the kept requirements and thresholds use the nominal values),
- in the S drawn cells (``robustness.cell_objectives``: camera mount, part placement, path offset, time scaling
  and pixel noise together; one stack of S·L poses per memory chunk),
- as the shop makes them in S draws (``robustness.shop_objectives``: the holes the study designs displaced and
  resized within the shop's tolerances; B·S designs in one batch),

(and the camera mounting error alone: ``BLOCKS``), and returns ONE objective, the statistic of the combined value
(``Problem.combined_from``, the nominal normalisation) — the smallest over the sources, so a design must hold up
under each:

- ``"percentile"`` (default): the q-th percentile (q = 10; linear interpolation between the order statistics);
- ``"mean"``: the mean;
- ``"chance"``: the nominal combined value, with the chance constraint "measure g_k ≥ bound in a share p of the
  cells" as one more margin: (the (1 − p) quantile of g_k − bound) / scale_k ≥ 0.

With ``floor_x`` (the original design), each source's combined 5th percentile may not fall below the original's
(one margin per source): the rule "a design more fragile than the original is never recommended", in sample.
The draws are fixed (common random numbers), so the optimisers see a deterministic function of the design and
the same seed gives the same robust optimum bit for bit. Works with every measure, g_POSE included (its pixel
noise draws enter through the σ model). ``robust_optimise`` runs local solves of the robust problem from given
starts (the nominal optimum, the best end-points of the nominal multi-start, the initial design); among the designs
they evaluate whose statistic is within its resolution of the best (``TIE_TOL``), it delivers the one with the most
margin to the original's floors (``tie_break``), so that round-off in a solver's path does not pick the more
fragile of two equally good designs.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, cast

import numpy as np

from cadfeat.design.objectives import ObjectiveConfig
from cadfeat.design.optimize import _result  # pyright: ignore[reportPrivateUsage] (the optimisers' result)
from cadfeat.design.optimize.evaluator import FEAS_TOL, Best, Evaluator, HistoryEntry, StartSummary
from cadfeat.design.robustness import cell_objectives, shop_objectives
from cadfeat.design.uncertainty import Draws
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from numpy.typing import ArrayLike

    from cadfeat.design.optimize import OptimizerConfig, OptimResult
    from cadfeat.design.optimize.evaluator import HistoryEntry, OptimProblem
    from cadfeat.design.problem import Problem

__all__ = ["BLOCKS", "FLOOR_PERCENTILE", "STATISTICS", "TIE_TOL", "RobustObjective", "RobustProblem",
           "robust_optimise", "statistic", "tie_break"]

STATISTICS = ("percentile", "mean", "chance")


class RobustSpec(Protocol):
    """The robust objective's settings (the study's ``[robustness]``, ``study.settings.RobustnessSettings``)."""

    @property
    def statistic(self) -> str: ...
    @property
    def percentile(self) -> float: ...
    @property
    def chance_measure(self) -> str | None: ...
    @property
    def chance_min(self) -> float | None: ...
    @property
    def chance_probability(self) -> float: ...


@dataclass(frozen=True)
class RobustObjective:
    """What the robust optimiser maximises (module docstring); ``chance_min`` in the measure's raw units."""

    statistic: str = "percentile"
    percentile: float = 10.0
    chance_measure: str | None = None
    chance_min: float | None = None
    chance_probability: float = 0.95

    @staticmethod
    def from_settings(spec: RobustSpec) -> RobustObjective:
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


BLOCKS = ("cell", "camera", "manufacturing")
"""The sources the robust problem evaluates, each on the same draws: the cell with all its errors together (the
cell that will be built), the camera mounting error alone (the largest by default, and the one a design must not
be more fragile to than the original), the shop's hole tolerances."""
FLOOR_PERCENTILE = 5.0
"""The "never worse than the original" rule's percentile of the combined value (per source)."""


class RobustProblem:
    """``problem`` seen through a statistic over fixed ``draws`` (module docstring). ``changed`` (N,) bool: the
    holes the shop makes (default: the movable ones, all when none moves). ``floor_x`` (P,): a design (the
    original) whose combined 5th percentile under each source of ``BLOCKS`` is a constraint (margin ≥ 0): the
    robust optimum is never more fragile than it, in sample."""

    def __init__(self, problem: Problem, objective: RobustObjective, draws: Draws, changed: ArrayLike | None = None,
                 floor_x: ArrayLike | None = None):
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
        self.floor: np.ndarray | None = None
        if floor_x is not None:
            comb = self.block_combined(np.asarray(floor_x, float)[None])
            self.floor = np.array([np.percentile(comb[b][0], FLOOR_PERCENTILE) for b in BLOCKS])

    # the solvers' view of one objective, maximised as it is
    def normalised(self, G: np.ndarray) -> np.ndarray:
        return np.asarray(G, float)

    def combined_from(self, G: np.ndarray) -> np.ndarray:
        return np.asarray(G, float)[..., 0]

    def constraint_labels(self) -> list[tuple[str, list[str]]]:
        extra: list[tuple[str, list[str]]] = \
            [(f"chance:{self.objective.chance_measure}", [])] if self._chance is not None else []
        if self.floor is not None:
            extra += [(f"p05 not below the original's: {b}", []) for b in BLOCKS]
        return self.inner.constraint_labels() + extra

    def constraints(self, x: np.ndarray) -> np.ndarray:
        return self.evaluate_batch(np.asarray(x, float)[None])[1][0]

    def block_objectives(self, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                         depth_mm: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Raw objectives of B designs' features (B, N, 3), (B, N, 3), (B, N): ``"nominal"`` (B, K) and per source
        of ``BLOCKS`` (B, S, K) on the draws with only that source (all cell sources for "cell")."""
        p = self.inner
        a = np.broadcast_to(axes, np.shape(centres))
        out = {"nominal": p.batch_objectives(centres, a, radii, depth_mm=depth_mm)}
        for b in BLOCKS:
            d = self.draws.only(b)
            if b == "manufacturing":
                shop = np.any(d.hole_shift_mm) or np.any(d.diameter_mm)
                out[b] = shop_objectives(p, centres, a, radii, self.changed, d, depth_mm) if shop else \
                    np.repeat(out["nominal"][:, None], d.size, axis=1)
            else:
                out[b] = cell_objectives(p, centres, a, radii, d, depth_mm)
        return out

    def block_combined(self, X: np.ndarray) -> dict[str, np.ndarray]:
        """The combined value of designs X (B, P): "nominal" (B,) and per source (B, S)."""
        c, a, r = self.inner.model.features_batch(np.atleast_2d(np.asarray(X, float)))
        G = self.block_objectives(c, a, r, self.inner.hole_depths(X))
        return {k: np.asarray(self.inner.combined_from(v), float) for k, v in G.items()}

    def value_and_margins(self, G: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """The robust objective (B,) and the extra margins (B, M') (chance constraint, the original's floors) of
        ``block_objectives``."""
        p = self.inner
        comb = {k: np.asarray(p.combined_from(v), float) for k, v in G.items()}
        margins: list[np.ndarray] = []
        if self.objective.statistic == "chance":
            value = comb["nominal"]
            k, q = self._chance, 100.0 * (1.0 - self.objective.chance_probability)
            low = np.min([np.percentile(G[b][..., k], q, axis=1) for b in BLOCKS], axis=0)
            margins.append((low - float(cast(float, self.objective.chance_min))) / float(p.scales[k]))
        else:
            value = np.min([statistic(comb[b], self.objective) for b in BLOCKS], axis=0)
        if self.floor is not None:
            margins += [np.percentile(comb[b], FLOOR_PERCENTILE, axis=1) - f for b, f in zip(BLOCKS, self.floor,
                                                                                              strict=True)]
        return value, np.stack(margins, axis=1) if margins else np.zeros((len(value), 0))

    def evaluate_batch(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The robust objective (B, 1) and the margins (B, M) (the nominal kept requirements, then the chance
        constraint's and the original's floors) of designs X (B, P)."""
        X = np.atleast_2d(np.asarray(X, float))
        p = self.inner
        c, a, r = p.model.features_batch(X)
        G = self.block_objectives(c, a, r, self.inner.hole_depths(X))
        value, extra = self.value_and_margins(G)
        C = np.concatenate([p.features_constraints(c, r, G["nominal"], X), extra], axis=1)
        self.n_evals += len(X)
        return value[:, None], C

    @property
    def n_robust_margins(self) -> int:
        """How many of ``evaluate_batch``'s margins are the robust problem's own (the last ones: the chance
        constraint's, then the original's floors, one per source of ``BLOCKS``)."""
        return int(self._chance is not None) + (len(BLOCKS) if self.floor is not None else 0)

    def fragility_margin(self, C: np.ndarray) -> np.ndarray:
        """The smallest of the robust margins (``n_robust_margins``) of margins C (..., M): how far a design is from
        being more fragile than the original under its weakest source (or from breaking the chance constraint);
        +inf without such margins."""
        C = np.asarray(C, float)
        n = self.n_robust_margins
        return C[..., C.shape[-1] - n:].min(axis=-1) if n else np.full(C.shape[:-1], np.inf)


ROBUST_EVALS_PER_VARIABLE = 30
"""Evaluations of each robust local solve per free design variable (COBYLA's ``maxiter``)."""
ROBUST_STEP = 0.05
"""COBYLA's initial step, as a fraction of each variable's range."""
STALL_EVALS_PER_VARIABLE = 2
"""A robust local solve stops when its best feasible statistic has not risen by ``STALL_TOL`` in this many
evaluations per free variable plus one (after the initial simplex of n + 1 points, n + 1 more model steps), and
at least ``STALL_EVALS_MIN``."""
STALL_EVALS_MIN = 10
STALL_TOL = 1e-3
"""The rise (relative, at least 1e-3 absolute) that counts as progress: well below the statistic's sampling
error over the draws (benchmarks/RESULTS.md, bench_robust: the 10th percentile's bootstrap standard error over
64 draws), so a solve is not stopped while it still gains anything the draws can resolve."""


TIE_TOL = STALL_TOL
"""Feasible designs whose robust statistic is within this (relative, at least absolute) of the best one are equally
good: the rise the local solves count as progress (``STALL_TOL``), below the statistic's sampling error. Among them
``robust_optimise`` delivers the one with the largest ``RobustProblem.fragility_margin`` (``tie_break``)."""


class _Stalled(Exception):
    """Raised inside COBYLA's objective to end a local solve that has stopped improving."""


def _local(ev: Evaluator, u0: np.ndarray, maxiter: int) -> None:
    """One derivative-free local solve (COBYLA) of the evaluator's robust objective from u0 under its margins:
    the statistic over the draws is piecewise smooth with steps (a hole leaving the view in one draw), where
    finite-difference gradients mislead a gradient solver. The evaluator keeps the best feasible design. The
    solve ends early when its best feasible value has not risen by ``STALL_TOL`` in ``STALL_EVALS_PER_VARIABLE``
    · (n + 1) evaluations, at least ``STALL_EVALS_MIN`` (a solve that has found no feasible design runs on)."""
    from scipy.optimize import minimize  # pyright: ignore[reportMissingTypeStubs, reportUnknownVariableType]

    iteration = [0]
    best, count, last = [-np.inf], [0], [0]
    stall = max(STALL_EVALS_MIN, STALL_EVALS_PER_VARIABLE * (u0.size + 1))

    def fun(u: np.ndarray) -> float:
        G, C = ev.batch(np.clip(u, 0.0, 1.0)[None])
        value = float(np.asarray(ev.problem.combined_from(G))[0])
        count[0] += 1
        rise = value - best[0] if np.isfinite(best[0]) else np.inf
        if C[0].min(initial=0.0) >= -FEAS_TOL and rise > STALL_TOL * max(1.0, abs(value)):
            best[0], last[0] = value, count[0]
        if np.isfinite(best[0]) and count[0] - last[0] >= stall:
            raise _Stalled
        return -value

    def callback(*args: object) -> None:
        iteration[0] += 1
        if iteration[0] % 10 == 0:  # one history entry every ten iterations
            u = getattr(args[0], "x", args[0])  # (an OptimizeResult, or the point itself)
            G, C = ev.batch(np.clip(np.asarray(u), 0, 1)[None])
            ev.record(iteration[0], G[0], C[0])

    n_cons = ev.batch(u0[None])[1].shape[1]
    def margins(u: np.ndarray) -> np.ndarray:
        return ev.batch(np.clip(u, 0.0, 1.0)[None])[1][0]

    cons = [{"type": "ineq", "fun": margins}] if n_cons else []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            minimize(fun, u0, method="COBYLA", constraints=cons, bounds=[(0.0, 1.0)] * u0.size, callback=callback,
                     options={"maxiter": maxiter, "rhobeg": ROBUST_STEP})
        except _Stalled:
            pass


class _PoolEvaluator(Evaluator):
    """An ``Evaluator`` that also keeps every feasible design it evaluates (in ``pool``, shared with the evaluators
    of ``sub``): the candidates of ``tie_break``."""

    def __init__(self, problem: OptimProblem, x_base: np.ndarray, free: np.ndarray | None = None,
                 progress: Callable[[HistoryEntry], None] | None = None, t0: float | None = None,
                 history: list[HistoryEntry] | None = None, bounds: tuple[np.ndarray, np.ndarray] | None = None,
                 pool: list[Best] | None = None) -> None:
        super().__init__(problem, x_base, free, progress, t0, history, bounds)
        self.pool: list[Best] = [] if pool is None else pool

    def sub(self, x_base: np.ndarray, free: np.ndarray) -> _PoolEvaluator:
        return _PoolEvaluator(self.problem, x_base, free, self.progress, self.t0, self.history, self.bounds,
                              pool=self.pool)

    def _consider(self, x: np.ndarray, g: np.ndarray, c: np.ndarray) -> None:
        super()._consider(x, g, c)
        violation = float(max(0.0, -c.min(initial=0.0)))
        if violation <= FEAS_TOL:
            self.pool.append({"x": x.copy(), "combined": float(self.problem.combined_from(g)), "G": g.copy(),
                              "C": c.copy(), "feasible": True, "violation": violation})


def tie_break(problem: RobustProblem, best: Best | None, pool: Sequence[Best]) -> Best | None:
    """Among the feasible designs of ``pool`` whose statistic is within ``TIE_TOL`` of ``best``'s (equally good:
    the statistic cannot tell them apart), the one with the largest ``fragility_margin``; equal margins (to 1e-12)
    go to the higher statistic, then to the earlier design. ``best`` itself when it is not feasible or the problem
    has no robust margins.

    Why: the robust statistic is piecewise smooth with steps (a hole leaving the view in one draw), and its maximum
    often lies next to a step of another source's 5th percentile. Two designs a few hundredths of a millimetre apart,
    on either side of such a step, can then have statistics equal to 1e-4 while one has half the other's margin to
    the original's floor — and which one COBYLA's path ends on is decided by round-off (issue 32 item 8: the razor
    edge, under the Prescott BLAS kernels, ended past the step and was more fragile than the original on held-out
    draws). Preferring the margin makes the choice a property of the designs, not of the path."""
    if best is None or not best["feasible"] or not problem.n_robust_margins or not pool:
        return best
    top = float(best["combined"])
    tol = TIE_TOL * max(1.0, abs(top))
    ties = [d for d in pool if d["feasible"] and d["combined"] >= top - tol]
    if not ties:
        return best
    margins = [float(problem.fragility_margin(d["C"])) for d in ties]
    widest = max(margins)
    chosen = [d for d, m in zip(ties, margins, strict=True) if m >= widest - 1e-12]
    return max(chosen, key=lambda d: d["combined"])  # (max keeps the first of equal values: the earlier design)


def robust_optimise(problem: RobustProblem, config: OptimizerConfig, starts: Sequence[np.ndarray],
                    progress: Callable[[HistoryEntry], None] | None = None) -> OptimResult:
    """Local solves of ``problem`` (COBYLA, ``ROBUST_EVALS_PER_VARIABLE`` evaluations per free variable) from
    each of ``starts`` in turn, one evaluator keeping the best feasible design (ties: the earlier); standard-size
    variables (``snap_standard_sizes``) stay at each start's (snapped) sizes. The delivered design: among the
    evaluated feasible designs as good as the best to ``TIE_TOL``, the one with the most margin to the original's
    floors (``tie_break``). An ``optimize.OptimResult``."""
    if not len(starts):
        raise CadfeatError("robust optimisation: no start given")
    space = problem.space
    discrete = np.asarray(space.discrete, bool) if config.snap_standard_sizes else np.zeros(space.size, bool)
    free = np.flatnonzero(~discrete)
    t0, n0 = time.perf_counter(), problem.n_evals
    ev = _PoolEvaluator(problem, np.asarray(starts[0], float), free, progress=progress, t0=t0)
    ev.phase = "robust"
    interrupted = False
    summaries: list[StartSummary] = []
    try:
        for k, x in enumerate(starts):
            sub = ev.sub(np.asarray(x, float), free)
            sub.best, sub.phase, sub.start = ev.best, "robust", k
            if free.size:
                _local(sub, sub.to_u(np.asarray(x, float)), ROBUST_EVALS_PER_VARIABLE * free.size)
            else:
                sub.batch(np.zeros((1, 0)))
            ev.best = sub.best
            summaries.append({"start": k, "x_start": np.asarray(x, float).tolist(),
                              "combined": None if sub.best is None else float(sub.best["combined"])})
    except KeyboardInterrupt:
        interrupted = True
    ev.best = tie_break(problem, ev.best, ev.pool)
    return _result(ev, problem, t0, interrupted, n0, starts=summaries)
