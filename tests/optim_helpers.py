"""Synthetic problems for the optimiser tests: the ``Problem`` interface the solvers use, on analytic
functions (no camera, no CAD)."""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np

from cadfeat.design.design_space import DesignSpace, Variable
from cadfeat.design.objectives import MEASURES, Normaliser, ObjectiveConfig, combined_indices
from cadfeat.design.problem import Problem


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
        self.offsets = np.zeros(k)
        self.normaliser = Normaliser("none", dict.fromkeys(self.names, 1.0), dict.fromkeys(self.names, "none"))
        self.combined_idx = np.array(combined_indices(self.objective_config, self.names), dtype=int)
        self.n_evals = 0

    def evaluate_batch(self, X):
        X = np.atleast_2d(X)
        self.n_evals += len(X)
        G = self._g(X)
        C = self._c(X) if self._c is not None else np.zeros((len(X), 0))
        return G, C

    combined_from = Problem.combined_from
    normalised = Problem.normalised
    leximin_key = Problem.leximin_key
    _thr_idx = np.zeros(0, dtype=int)
    _thr = np.zeros(0)


def box(*bounds, x0=None, sizes=None):
    variables = [Variable(f"x{i}", lo, hi, "mm", "position" if not (sizes and i in sizes) else "diameter",
                          sizes.get(i) if sizes else None) for i, (lo, hi) in enumerate(bounds)]
    x0 = np.array([(lo + hi) / 2 for lo, hi in bounds]) if x0 is None else np.asarray(x0, float)
    return DesignSpace(variables, x0)


# ------------------------------------------------------------------------------- a small CAD problem
PLATE = (80.0, 60.0, 5.0)


def plate_with_holes(centres_xy, radii):
    """A CadQuery plate 80 × 60 × 5 mm (top face z = 0) with through holes at ``centres_xy`` (mm)."""
    import cadquery as cq

    sx, sy, sz = PLATE
    solid = cq.Solid.makeBox(sx, sy, sz, cq.Vector(-sx / 2, -sy / 2, -sz))
    cuts = [cq.Solid.makeCylinder(float(r), sz + 2, cq.Vector(float(x), float(y), -sz - 1))
            for (x, y), r in zip(centres_xy, radii, strict=True)]
    return solid.cut(*cuts)


def two_hole_rebuild(x):
    """x = (x1, y1, x2, y2, d): two holes of diameter d on the plate; returns the extracted holes."""
    from cadfeat.cad.features import extract_holes

    x = np.asarray(x, float)
    return extract_holes(plate_with_holes([(x[0], x[1]), (x[2], x[3])], [x[4] / 2] * 2),
                         prefer_direction=(0, 0, 1))


@functools.lru_cache(maxsize=8)
def _two_hole_model(x0: tuple, span: tuple):
    from cadfeat.design.design_space import LinearFeatureModel

    return LinearFeatureModel.from_rebuild(two_hole_rebuild, np.array(x0), 1e-3 * np.array(span),
                                           names=["x1", "y1", "x2", "y2", "d"])


def two_hole_problem(measures=("resolution",), combine="weighted", aggregate="sum", n=12, x0=(-20, 10, 20, -10, 4),
                     feature_reduce="min", edge=2.0, ligament=2.0, d_bounds=(2.0, 8.0), heights=(320.0, 260.0),
                     **objective):
    """Two holes on a plate seen by a camera moving above it: a real ``Problem`` (CAD → linear map)."""
    from cadfeat.camera import Camera
    from cadfeat.design.constraints import ConstraintConfig
    from cadfeat.trajectory import straight_approach

    variables = [Variable("x1", -35, 35), Variable("y1", -25, 25), Variable("x2", -35, 35), Variable("y2", -25, 25),
                 Variable("d", *d_bounds, "mm", "diameter")]
    space = DesignSpace(variables, np.asarray(x0, float))
    model = _two_hole_model(tuple(x0), tuple(space.span))
    camera = Camera.preset("basler-aca1300-200um-8mm")
    traj = straight_approach((-40, -30, heights[0]), (40, 30, heights[1]), (0, 0, 0), n=n)
    cfg = ObjectiveConfig(measures=tuple(measures), combine=combine, aggregate=aggregate,
                          feature_reduce=feature_reduce, **objective)
    return Problem(space, model, camera, traj, np.eye(4), cfg,
                   ConstraintConfig(edge_distance_mm=edge, ligament_mm=ligament), [False, False])
