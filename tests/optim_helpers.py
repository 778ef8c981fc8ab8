"""Synthetic problems for the optimiser tests: the ``Problem`` interface the solvers use, on analytic
functions (no camera, no CAD)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cadfeat.design_space import DesignSpace, Variable
from cadfeat.objectives import MEASURES, ObjectiveConfig
from cadfeat.problem import Problem


class AnalyticProblem:
    """Objectives G(X) (B, K) "larger is better" and margins C(X) (B, M) given as vectorised functions."""

    def __init__(self, space: DesignSpace, objectives: Callable, constraints: Callable | None = None,
                 combine: str = "weighted", weights: dict | None = None):
        self.space = space
        self._g = objectives
        self._c = constraints
        k = objectives(space.x0[None]).shape[1]
        measures = tuple(list(MEASURES)[:k])
        self.objective_config = ObjectiveConfig(measures=measures, combine=combine, weights=weights or {})
        self.names = self.objective_config.names
        self.scales = np.ones(k)
        self.n_evals = 0

    def evaluate_batch(self, X):
        X = np.atleast_2d(X)
        self.n_evals += len(X)
        G = self._g(X)
        C = self._c(X) if self._c is not None else np.zeros((len(X), 0))
        return G, C

    combined_from = Problem.combined_from
    _thr_idx = np.zeros(0, dtype=int)
    _thr = np.zeros(0)


def box(*bounds, x0=None, sizes=None):
    variables = [Variable(f"x{i}", lo, hi, "mm", "position" if not (sizes and i in sizes) else "diameter",
                          sizes.get(i) if sizes else None) for i, (lo, hi) in enumerate(bounds)]
    x0 = np.array([(lo + hi) / 2 for lo, hi in bounds]) if x0 is None else np.asarray(x0, float)
    return DesignSpace(variables, x0)
