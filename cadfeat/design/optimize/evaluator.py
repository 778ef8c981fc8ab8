"""Evaluation bookkeeping shared by every solver: unit coordinates, cache, finite differences, best-so-far.

Solvers work in unit coordinates u ∈ [0, 1] of the *free* variables (x = lower + u·span), so a
finite-difference step ``h`` is relative to each variable's range. Every evaluated design (including
finite-difference points) updates the best feasible design so far, which is what an interrupted run
returns.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, NotRequired, Protocol, TypedDict

import numpy as np

from cadfeat.design.objectives import leximin_better

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.design.design_space import DesignSpace, FeatureModel

FEAS_TOL = 1e-6
"""A design is feasible when every constraint margin is ≥ −FEAS_TOL (mm, or normalised units)."""
LEXIMIN_TOL = 1e-8
"""Normalised objectives within this of each other count as tied (max-min then compares the next-worst)."""


class Best(TypedDict):
    """A design an evaluator has seen (its best so far, ``Evaluator.best``): the design ``x`` (P,), its combined
    objective, raw objectives G (K,) and margins C (M,), whether it is feasible and its largest violation."""

    x: np.ndarray
    combined: float
    G: np.ndarray
    C: np.ndarray
    feasible: bool
    violation: float


class HistoryEntry(TypedDict):
    """One solver iteration (``OptimResult.history``, results.json ``history``): the iteration, phase and start,
    the solver's own iteration count, the minimised f = −combined, feasibility and largest violation, the best
    combined objective so far, evaluations and seconds so far; ``front_size`` for NSGA-II."""

    iteration: int
    phase: str
    start: int
    local_iteration: int
    f: float
    combined: float
    feasible: bool
    max_violation: float
    best_combined: float | None
    n_evals: int
    time_s: float
    front_size: NotRequired[int]


class StartSummary(TypedDict):
    """One start's local solve (``OptimResult.starts``): where it started and ended, its combined objective (None:
    a robust start that found no design) and largest violation there (the robust solves give neither end nor
    violation)."""

    start: int
    x_start: list[float]
    x_end: NotRequired[list[float]]
    combined: float | None
    max_violation: NotRequired[float]


class ParetoFront(TypedDict):
    """The NSGA-II front (``OptimResult.pareto``, results.json ``pareto``): objective names, raw and normalised
    values per point, the designs, feasibility, the chosen point and why."""

    names: list[str]
    points: list[list[float]]
    normalised: list[list[float]]
    x: list[list[float]]
    feasible: list[bool]
    chosen: int
    chosen_by: str


class CadRound(TypedDict):
    """One round of ``solve_with_cad``'s trust-region loop (``OptimResult.cad_rounds``): the model's optimum ``x`` in
    the region (``radius``, None: the whole box) and its predicted combined objective; the rebuild's ``status``
    (agree, differ, rebuild failed) with its error, or its largest prediction error, true combined objective and
    feasibility; where the map was refreshed (or why not)."""

    round: int
    x: list[float]
    predicted_combined: float
    radius: list[float] | None
    status: NotRequired[str]
    error: NotRequired[str]
    max_error_mm: NotRequired[float]
    true_combined: NotRequired[float]
    feasible: NotRequired[bool]
    refresh_failed: NotRequired[str]
    refreshed_at: NotRequired[list[float]]


def best_of(x: np.ndarray, combined: float, G: np.ndarray, C: np.ndarray) -> Best:
    """The ``Best`` record of a design evaluated to ``G`` and ``C`` (feasible when its violation is within
    ``FEAS_TOL``)."""
    violation = float(max(0.0, -C.min(initial=0.0)))
    return {"x": x, "combined": combined, "G": G, "C": C, "feasible": violation <= FEAS_TOL, "violation": violation}


class Combination(Protocol):
    """What the optimisers read of an objective configuration: how the objectives combine ("weighted", "maxmin",
    "constraint", "pareto")."""

    @property
    def combine(self) -> str: ...


class OptimProblem(Protocol):
    """What the optimisers read of a problem: ``design.problem.Problem`` and ``design.robust.RobustProblem`` are
    such problems (a protocol: ``problem`` imports the optimisers)."""

    @property
    def space(self) -> DesignSpace: ...
    @property
    def names(self) -> Sequence[str]: ...
    @property
    def objective_config(self) -> Combination: ...
    @property
    def scales(self) -> np.ndarray: ...
    @property
    def combined_idx(self) -> np.ndarray: ...
    @property
    def n_evals(self) -> int: ...

    def evaluate_batch(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Raw objectives G (B, K) and constraint margins C (B, M) of designs X (B, P)."""
        ...

    def combined_from(self, G: np.ndarray) -> np.ndarray:
        """The scalar to maximise (...,) from raw objectives G (..., K)."""
        ...

    def normalised(self, G: np.ndarray) -> np.ndarray:
        """Normalised objectives (..., K)."""
        ...


class CadProblem(OptimProblem, Protocol):
    """What the CAD trust-region loop (``optimize.cad``) reads besides: the feature model, objectives and margins
    of CAD-extracted features, and the same problem on a refreshed model (``design.problem.Problem``)."""

    @property
    def model(self) -> FeatureModel: ...

    def with_model(self, model: FeatureModel) -> CadProblem:
        """The same problem on another feature model."""
        ...

    def features_objectives(self, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                            exact_occlusion: bool = False, depth_mm: Sequence[float] | np.ndarray | None = None
                            ) -> np.ndarray:
        """Raw aggregated objectives (K,) of hole features."""
        ...

    def features_constraints(self, centres: np.ndarray, radii: np.ndarray, g: np.ndarray,
                             X: np.ndarray | None = None) -> np.ndarray:
        """Constraint margins (..., M) of features and raw objectives."""
        ...


class Evaluator:
    """Batched, cached evaluation of a ``Problem`` on the free variables ``free`` (others at ``x_base``)."""

    def __init__(self, problem: OptimProblem, x_base: np.ndarray, free: np.ndarray | None = None,
                 progress: Callable[[HistoryEntry], None] | None = None, t0: float | None = None,
                 history: list[HistoryEntry] | None = None, bounds: tuple[np.ndarray, np.ndarray] | None = None):
        self.problem = problem
        space = problem.space
        lower, upper = (space.lower, space.upper) if bounds is None else bounds
        self.bounds = (np.maximum(space.lower, lower), np.minimum(space.upper, upper))
        self.free = np.arange(space.size) if free is None else np.asarray(free, dtype=int)
        self.x_base = np.asarray(x_base, dtype=float).copy()  # fixed entries kept as given (snapped sizes)
        self.x_base[self.free] = np.clip(self.x_base[self.free], self.bounds[0][self.free], self.bounds[1][self.free])
        self.lower = self.bounds[0][self.free]
        self.span = np.maximum(self.bounds[1][self.free] - self.lower, 1e-300)
        self.progress = progress
        self.t0 = time.perf_counter() if t0 is None else t0
        self.history = [] if history is None else history
        self._cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
        self.best: Best | None = None
        self.phase = "local"
        self.start = 0

    # ---------------------------------------------------------------------------------- coordinates
    def to_x(self, U: np.ndarray) -> np.ndarray:
        """Unit coordinates of the free variables (B, p) → full designs (B, P)."""
        U = np.atleast_2d(U)
        X = np.repeat(self.x_base[None], len(U), axis=0)
        X[:, self.free] = self.lower + np.clip(U, 0.0, 1.0) * self.span
        return X

    def to_u(self, x: np.ndarray) -> np.ndarray:
        return np.clip((np.asarray(x, dtype=float)[self.free] - self.lower) / self.span, 0.0, 1.0)

    def sub(self, x_base: np.ndarray, free: np.ndarray) -> Evaluator:
        """An evaluator on a subset of the variables (others at ``x_base``), sharing history and bounds."""
        return Evaluator(self.problem, x_base, free, self.progress, self.t0, self.history, self.bounds)

    # ----------------------------------------------------------------------------------- evaluation
    def batch(self, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Raw objectives G (B, K) and margins C (B, M) at unit points U (B, p); cached per point."""
        U = np.clip(np.atleast_2d(np.asarray(U, dtype=float)), 0.0, 1.0)
        keys = [u.tobytes() for u in U]
        todo = [i for i, k in enumerate(keys) if k not in self._cache]
        if todo:
            X = self.to_x(U[todo])
            G, C = self.problem.evaluate_batch(X)
            for j, i in enumerate(todo):
                self._cache[keys[i]] = (G[j], C[j])
                self._consider(X[j], G[j], C[j])
        G = np.stack([self._cache[k][0] for k in keys])
        C = np.stack([self._cache[k][1] for k in keys])
        return G, C

    def _consider(self, x: np.ndarray, g: np.ndarray, c: np.ndarray) -> None:
        violation = float(max(0.0, -c.min(initial=0.0)))
        feasible = violation <= FEAS_TOL
        combined = float(self.problem.combined_from(g))
        b = self.best
        better = (b is None or (feasible and not b["feasible"]) or (feasible and b["feasible"] and self.improves(g, b))
                  or (not feasible and not b["feasible"] and violation < b["violation"]))
        if better:
            self.best = {"x": x.copy(), "combined": combined, "G": g.copy(), "C": c.copy(), "feasible": feasible,
                         "violation": violation}

    def improves(self, g: np.ndarray, best: Best) -> bool:
        """Whether feasible objectives ``g`` beat the feasible best: by the combined value; for max-min, ties
        (within ``LEXIMIN_TOL``) broken by the next-worst normalised objective, and so on (leximin)."""
        problem = self.problem
        key = getattr(problem, "leximin_key", None)  # (``Problem`` has it; the robust problem's one value has none)
        if problem.objective_config.combine != "maxmin" or key is None:
            return float(problem.combined_from(g)) > best["combined"]

        return leximin_better(key(g), key(best["G"]), LEXIMIN_TOL)

    def combined(self, U: np.ndarray) -> np.ndarray:
        G, _ = self.batch(U)
        return np.asarray(self.problem.combined_from(G))

    def gradients(self, u: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Central finite differences at u (p,) with unit step ``h`` (one-sided at the bounds), from one batch
        of 2p designs: value G (K,), C (M,) and Jacobians dG (K, p), dC (M, p) per unit coordinate."""
        u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
        p = u.size
        E = np.eye(p)
        up = np.clip(u + h * E, 0.0, 1.0)
        dn = np.clip(u - h * E, 0.0, 1.0)
        G, C = self.batch(np.vstack([u[None], up, dn]))
        du = (up - dn)[np.arange(p), np.arange(p)]
        dG = ((G[1:p + 1] - G[p + 1:]) / du[:, None]).T
        dC = ((C[1:p + 1] - C[p + 1:]) / du[:, None]).T
        return G[0], C[0], dG, dC

    # -------------------------------------------------------------------------------------- history
    def record(self, iteration: int, G: np.ndarray, C: np.ndarray, front_size: int | None = None) -> HistoryEntry:
        """Append a history entry (and report it to ``progress``, which may raise KeyboardInterrupt)."""
        violation = float(max(0.0, -np.min(C, initial=0.0)))
        entry: HistoryEntry = {
            "iteration": len(self.history), "phase": self.phase, "start": self.start, "local_iteration": iteration,
            "f": float(-self.problem.combined_from(G)), "combined": float(self.problem.combined_from(G)),
            "feasible": violation <= FEAS_TOL, "max_violation": violation,
            "best_combined": None if self.best is None else self.best["combined"],
            "n_evals": int(self.problem.n_evals), "time_s": time.perf_counter() - self.t0}
        if front_size is not None:
            entry["front_size"] = front_size
        self.history.append(entry)
        if self.progress is not None:
            self.progress(entry)
        return entry
