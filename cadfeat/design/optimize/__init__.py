"""Optimisers for feature design (thesis §4.1, §7.3: local minima — multi-start is the default).

``optimise(problem, config, progress=None) -> OptimResult`` with ``config.method``:

- ``"multistart"`` (default): SLSQP (or trust-constr) from ``starts`` points of a scrambled Sobol design
  (``scipy.stats.qmc``, seeded), then from the initial design (one extra start, last: it never decides a tie);
- ``"local"``: one local solve from the initial design;
- ``"global"``: ``scipy.optimize.differential_evolution`` (seeded, constraints as ``NonlinearConstraint``)
  followed by a local polish;
- ``"pareto"``: NSGA-II (pymoo, seeded): the front, and its max-min point as the chosen design.

Discrete diameters (variables with standard sizes, ``snap_standard_sizes``): the continuous optimum is
snapped to the nearest sizes (both neighbours of each tried when few) and the positions re-solved with
the sizes fixed (for Pareto: the chosen point, re-solved by max-min, so ``x_best`` may then differ from
the front's continuous point). Max-min is solved in epigraph form (smooth). Gradients are central finite differences
with a step relative to each variable's range, all 2P points evaluated in one batch.

Determinism: same problem + same seed → identical result. Ctrl-C (``KeyboardInterrupt``, also raised by a
``progress`` callback) stops the run and returns the best feasible design so far with ``interrupted=True``.

``solve_with_cad`` (``cadfeat.design.optimize.cad``) wraps these in the trust-region loop with CAD rebuilds.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar, cast

import numpy as np
from pydantic import Field, ValidationInfo, model_validator

from cadfeat.design.optimize.evaluator import (
    FEAS_TOL,
    Best,
    CadRound,
    Evaluator,
    HistoryEntry,
    ParetoFront,
    StartSummary,
    best_of,
)
from cadfeat.design.optimize.solvers import (
    global_solve,
    leximin_refine,
    local_solve,
    multistart,
    pareto_solve,
    snap_candidates,
)
from cadfeat.settings import Settings, boolean, choice, context_of, integer, number, reject, seed_from_context

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cad.features import Hole

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.design.optimize.evaluator import OptimProblem

__all__ = ["FEAS_TOL", "METHODS", "OptimResult", "OptimizerConfig", "optimise", "solve_with_cad"]

METHODS = ("multistart", "local", "global", "pareto")
LOCAL_SOLVERS = ("SLSQP", "trust-constr")


class OptimizerConfig(Settings):
    """Solver settings — and the study file's ``[optimizer]`` (one declaration:
    ``cadfeat.study.settings.OptimizerSettings`` is this class); ``seed`` defaults to the study's (validation
    context ``seed``), ``starts``/``maxiter`` are bounded by the study's size limits (context ``limits``).
    Solver tuning, not study keys: ``fd_step``: finite-difference step as a fraction of each variable's range;
    ``eager_gradients``: evaluate the finite-difference stencil in the same batch as every value request
    (fewer, larger batches: faster on feature models, more evaluations);
    ``ftol``: local solver tolerance; ``de_*``: differential evolution; ``pop_size``/``n_gen``: NSGA-II."""

    section: ClassVar[str] = "optimizer"

    method: str = choice("multistart", METHODS)
    starts: int = Field(default=8, description="multistart: number of local starts",
                        json_schema_extra={"minimum": 1, "x-allowed": "an integer ≥ 1 (≤ the study's size limit)"})
    maxiter: int = Field(default=100, description="iterations of each local solve",
                         json_schema_extra={"minimum": 1, "x-allowed": "an integer ≥ 1 (≤ the study's size limit)"})
    seed: int = integer(0, 0, 2**32 - 1)
    local_solver: str = choice("SLSQP", LOCAL_SOLVERS)
    snap_standard_sizes: bool = boolean(True)
    fd_step: float = number(1e-5, 0.0, 0.1, lo_open=True, hi_open=True, internal=True)
    eager_gradients: bool = boolean(False, internal=True)
    ftol: float = number(1e-9, 0.0, lo_open=True, internal=True)
    de_maxiter: int = integer(60, 1, internal=True)
    de_popsize: int = integer(12, 1, internal=True)
    pop_size: int = integer(40, 1, internal=True)
    n_gen: int = integer(40, 1, internal=True)

    @model_validator(mode="before")
    @classmethod
    def _study_seed(cls, data: object, info: ValidationInfo) -> object:
        return seed_from_context(data, info)

    @model_validator(mode="after")
    def _limits(self, info: ValidationInfo) -> OptimizerConfig:
        """``starts``, ``maxiter`` ≥ 1 and within the study's size limits (context ``limits``), when given."""
        limits = cast("dict[str, int]", context_of(info).get("limits", {}))
        for key, limit in (("starts", "optimizer_starts"), ("maxiter", "optimizer_maxiter")):
            value = cast(int, getattr(self, key))
            hi = limits.get(limit)
            if value < 1 or (hi is not None and value > hi):
                allowed = "an integer ≥ 1" if hi is None else f"an integer in [1, {hi}]"
                raise reject(key, f"{value} is not allowed", allowed)
        return self


@dataclass
class OptimResult:
    """The outcome of ``optimise`` / ``solve_with_cad``.

    ``x_best`` (P,) design values, ``f_best`` = −combined (minimised), ``combined_best``, ``objectives_best``
    (raw g values), ``feasible``, ``max_violation``; ``history``: one dict per solver iteration (iteration,
    phase, start, f, combined, feasible, max_violation, n_evals, time_s); ``pareto``: None or the front
    (names, points, normalised, x, feasible, chosen); ``starts``: per-start summaries; ``cad_rounds``:
    trust-region rounds of ``solve_with_cad``; ``holes``: the holes extracted from the final CAD rebuild."""

    x_best: np.ndarray
    f_best: float
    history: list[HistoryEntry]
    interrupted: bool
    pareto: ParetoFront | None
    n_evals: int
    time_s: float
    combined_best: float = float("nan")
    objectives_best: dict[str, float] = field(default_factory=dict[str, float])
    feasible: bool = False
    max_violation: float = 0.0
    message: str = ""
    starts: list[StartSummary] = field(default_factory=list[StartSummary])
    cad_rounds: list[CadRound] = field(default_factory=list[CadRound])
    holes: list[Hole] | None = None


def _result(ev: Evaluator, problem: OptimProblem, t0: float, interrupted: bool, n0: int,
            pareto: ParetoFront | None = None, starts: list[StartSummary] | None = None,
            message: str = "") -> OptimResult:
    best = ev.best
    if best is None:  # interrupted before any evaluation
        x = problem.space.x0.copy()
        G, C = problem.evaluate_batch(x[None])
        best = best_of(x, float(problem.combined_from(G[0])), G[0], C[0])
    if not message:
        message = ("interrupted: best design so far" if interrupted else
                   "feasible optimum" if best["feasible"] else "no feasible design found: least violation")
    return OptimResult(np.asarray(best["x"], dtype=float), -float(best["combined"]), ev.history, interrupted, pareto,
                       problem.n_evals - n0, time.perf_counter() - t0, float(best["combined"]),
                       dict(zip(problem.names, map(float, best["G"]), strict=True)), bool(best["feasible"]),
                       float(best["violation"]), message, starts or [])


def optimise(problem: OptimProblem, config: OptimizerConfig | None = None,
             progress: Callable[[HistoryEntry], None] | None = None, *, x_start: np.ndarray | None = None,
             bounds: tuple[np.ndarray, np.ndarray] | None = None) -> OptimResult:
    """Optimise ``problem`` (module docstring). ``x_start`` replaces the initial design; ``bounds`` (lower,
    upper) restricts the search box (the trust region of ``solve_with_cad``)."""
    config = config or OptimizerConfig()
    t0 = time.perf_counter()
    n0 = problem.n_evals
    x_start = problem.space.x0 if x_start is None else np.asarray(x_start, dtype=float)
    ev = Evaluator(problem, x_start, progress=progress, t0=t0, bounds=bounds)
    pareto: ParetoFront | None = None
    starts: list[StartSummary] = []
    interrupted = False
    try:
        if config.method == "pareto":
            pareto = pareto_solve(ev, config)
            x = np.asarray(pareto["x"][pareto["chosen"]])
            G, C = ev.batch(ev.to_u(x)[None])
            ev.best = best_of(x, float(problem.combined_from(G[0])), G[0], C[0])
        elif config.method == "global":
            global_solve(ev, config)
        elif config.method == "local":
            local_solve(ev, ev.to_u(x_start), config)
        else:
            starts = multistart(ev, config)
        if config.method != "pareto":
            leximin_refine(ev, config)
        if config.snap_standard_sizes and problem.space.discrete.any():
            _snap(ev, problem, config)
    except KeyboardInterrupt:
        interrupted = True
    return _result(ev, problem, t0, interrupted, n0, pareto, starts)


def _snap(ev: Evaluator, problem: OptimProblem, config: OptimizerConfig) -> None:
    """Snap standard-size variables of the best design and re-solve the others with them fixed."""
    space = problem.space
    assert ev.best is not None  # (called after the solves: they evaluated designs)
    x_cont = ev.best["x"].copy()
    free = np.flatnonzero(~space.discrete)
    candidates = snap_candidates(space, x_cont)
    results: list[Best] = []
    for k, x in enumerate(candidates):
        sub = ev.sub(x, free)
        sub.phase, sub.start = "snap", k
        if free.size:
            local_solve(sub, sub.to_u(x), config)
        else:
            sub.batch(np.zeros((1, 0)))
        assert sub.best is not None  # (the sub-evaluator evaluated its designs)
        results.append(sub.best)
    feasible = [r for r in results if r["feasible"]]
    pool = feasible or sorted(results, key=lambda r: r["violation"])[:1]
    best = pool[0]
    for r in pool[1:]:
        if r["feasible"] and best["feasible"] and ev.improves(r["G"], best) or not best["feasible"] and \
                r["violation"] < best["violation"]:
            best = r
    ev.best = best


if TYPE_CHECKING:  # the checker sees the function itself
    from cadfeat.design.optimize.cad import solve_with_cad
else:
    def solve_with_cad(*args, **kwargs):
        """The trust-region loop with CAD rebuilds: see ``cadfeat.design.optimize.cad.solve_with_cad``."""
        # lazy: import cycle (cadfeat.design.optimize.cad imports cadfeat.design.optimize)
        from cadfeat.design.optimize.cad import solve_with_cad as _solve

        return _solve(*args, **kwargs)
