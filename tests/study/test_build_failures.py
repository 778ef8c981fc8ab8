"""A CAD build that fails after set-up is an infeasible point, never the end of a run (issue 16 item 4); Ctrl-C
keeps the best design evaluated so far.

References: the part script's own failing region (tests/data/failing_region_plate.py: the delivered design must
lie outside it and be rebuilt for real), and, for the interrupt, a record of every design the optimiser
evaluated (the delivered one must be the best feasible one of them)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from optim_helpers import two_hole_problem, two_hole_rebuild
from study_helpers import DATA

from cadfeat.design.optimize import FEAS_TOL, OptimizerConfig, optimise, solve_with_cad
from cadfeat.errors import CadfeatError

FAILING = DATA / "failing_region_plate.py"
STUDY = {
    "study": {"name": "failing_plate", "part": str(FAILING), "seed": 7},
    "camera": {"preset": "realsense-d435-rgb", "focus_distance_mm": 200.0},
    "trajectory": {"kind": "straight_approach", "start": [-60.0, -80.0, 260.0], "end": [40.0, -40.0, 180.0],
                   "target": [0.0, 0.0, 6.0], "n": 12, "duration_s": 2.0},
    "design": {"parameters": {"x0": {"lower": -18.0, "upper": -4.0}, "y0": {"lower": -8.0, "upper": 12.0}}},
    "constraints": {"edge_distance_mm": 3.0, "ligament_mm": 2.5},
    "objective": {"measures": ["fov", "resolution", "resolvability"], "aggregate": "sum", "combine": "maxmin",
                  "rotation_length_mm": 50.0},
    "optimizer": {"method": "multistart", "starts": 2, "maxiter": 25},
    "robustness": {"samples": 0, "robust": False},
}


def test_a_build_failing_around_the_optimum_gives_a_buildable_design(tmp_path, monkeypatch):
    """The feature model's optimum (x0 ≈ -14.65) lies in the failing region: the run searches again with CAD in
    the loop and delivers a design outside the region, rebuilt and verified (rc 0, no traceback)."""
    from cadfeat.study import run as study_mod

    monkeypatch.setattr(study_mod, "_report", lambda *a, **k: None)
    result = study_mod.run_study(copy.deepcopy(STUDY), tmp_path / "out", quiet=True)
    res = result.results
    x0 = {v["name"]: v["after"] for v in res["variables"]}["x0"]
    assert not -16.0 < x0 < -13.0, x0
    assert "kernel failure in this region" in res["optimizer"]["rebuild_failed_at_model_optimum"]
    assert all(c["ok"] for c in res["constraints"])
    assert (tmp_path / "out" / "optimised.step").exists()


def test_a_failing_map_refresh_is_an_infeasible_point():
    """The trust-region loop's map refresh builds near the candidate; when that build fails the loop goes on
    (smaller region) instead of raising."""
    problem = two_hole_problem(measures=("resolution",), n=6)
    calls = []

    def refresh(x, holes):
        calls.append(np.asarray(x, float))
        raise CadfeatError("kernel failure near the candidate")

    def nonlinear_rebuild(x):  # hole 2 a little off the linear prediction: the loop has to refresh
        x = np.asarray(x, float).copy()
        x[2] += 1e-3 * (x[0] + 35.0)
        return two_hole_rebuild(x)

    res = solve_with_cad(problem, nonlinear_rebuild, OptimizerConfig(method="local"), refresh=refresh, max_rounds=2)
    assert calls and all("refresh_failed" in r for r in res.cad_rounds if r["status"] != "rebuild failed")
    assert res.holes is not None  # a design that was rebuilt for real


def test_when_nothing_else_builds_the_anchor_is_the_answer():
    """Every rebuild of the loop fails: the answer is the map's anchor, the one design the set-up built (its holes
    are the model's reference holes, extracted from CAD)."""
    problem = two_hole_problem(measures=("resolution",), n=6)

    def broken(x):
        raise RuntimeError("kernel failure everywhere")

    res = solve_with_cad(problem, broken, OptimizerConfig(method="local"), max_rounds=2)
    assert all(r["status"] == "rebuild failed" for r in res.cad_rounds)
    np.testing.assert_allclose(res.x_best, problem.model.x0, atol=0)
    assert res.holes == problem.model.holes


def test_no_buildable_design_is_one_clear_error():
    """Without a CAD-built anchor (a feature model that names no anchor design) and no rebuild that works: one
    clear error."""

    class NoAnchor:  # the same features, but no ``x0`` at which its holes were built
        def __init__(self, model):
            self.holes, self._model = model.holes, model

        def features(self, x):
            return self._model.features(x)

        def features_batch(self, X):
            return self._model.features_batch(X)

    problem = two_hole_problem(measures=("resolution",), n=6)
    problem = problem.with_model(NoAnchor(problem.model))

    def broken(x):
        raise RuntimeError("kernel failure everywhere")

    with pytest.raises(CadfeatError, match="no buildable design"):
        solve_with_cad(problem, broken, OptimizerConfig(method="local"), max_rounds=2)


def test_interrupt_from_the_objective_keeps_the_best_design_so_far(monkeypatch):
    """Ctrl-C raised inside an objective evaluation, mid-optimisation: the result is marked interrupted and its
    design is the best feasible design among all those evaluated before (recorded independently)."""
    problem = two_hole_problem(measures=("fov", "resolution"), combine="maxmin", n=6)
    real = problem.evaluate_batch
    seen: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def evaluate_batch(X):
        if len(seen) >= 40:
            raise KeyboardInterrupt
        G, C = real(X)
        seen.append((np.atleast_2d(X).copy(), G, C))
        return G, C

    monkeypatch.setattr(problem, "evaluate_batch", evaluate_batch)
    res = optimise(problem, OptimizerConfig(starts=4, maxiter=50))
    assert res.interrupted and res.feasible
    X = np.vstack([s[0] for s in seen])
    G = np.vstack([s[1] for s in seen])
    C = np.vstack([s[2] for s in seen])
    ok = C.min(axis=1, initial=0.0) >= -FEAS_TOL
    combined = np.where(ok, problem.combined_from(G), -np.inf)
    assert res.combined_best == pytest.approx(combined.max(), abs=1e-8)  # max-min ties go by leximin (1e-8)
    best = np.flatnonzero(combined >= combined.max() - 1e-8)
    assert np.min(np.abs(X[best] - res.x_best).max(axis=1)) <= 1e-12  # one of the evaluated best designs
    assert len(seen) == 40  # stopped mid-optimisation
