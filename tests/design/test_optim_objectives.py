"""Objectives: aggregation (closed forms, scipy's logsumexp), normalisation (never raw units, the Λ(x0)=0
case), combination, bad input; the axiomatic classification on hand-made matrices and on a problem."""

from __future__ import annotations

import numpy as np
import pytest
from optim_helpers import two_hole_problem
from scipy.special import logsumexp

from cadfeat.design.axiomatic import classify, design_matrix
from cadfeat.design.objectives import Normaliser, ObjectiveConfig, aggregate, combine, natural_units, objective_values
from cadfeat.errors import CadfeatError

pytestmark = pytest.mark.numerics  # run again under another BLAS kernel (Makefile: test)


def test_aggregates_closed_forms_and_smooth_min_bounds():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(3, 25))
    np.testing.assert_allclose(aggregate(v, "sum"), v.sum(1))
    np.testing.assert_allclose(aggregate(v, "mean"), v.mean(1))
    np.testing.assert_allclose(aggregate(v, "min"), v.min(1))
    beta, unit = 7.0, 0.5
    expected = -(unit / beta) * (logsumexp(-beta * v / unit, axis=1) - np.log(v.shape[1]))
    s = aggregate(v, "smoothmin", beta, unit)
    np.testing.assert_allclose(s, expected, rtol=1e-12)
    assert np.all(s >= v.min(1)) and np.all(s <= v.mean(1))
    sharp = aggregate(v, "smoothmin", 1e4, 1.0)
    assert np.all(sharp - v.min(1) <= np.log(25) / 1e4 + 1e-12)
    huge = aggregate(np.array([1e3, 1e3 + 1]), "smoothmin", 50.0)  # no overflow
    assert np.isfinite(huge) and 1e3 <= huge <= 1e3 + 0.5


class _M:  # per-pose/per-feature arrays shaped like measures.Measures
    def __init__(self, L=4, N=3):
        rng = np.random.default_rng(1)
        self.fov = rng.normal(size=(L, N))
        self.fov_px = rng.normal(size=(L, N)) * 10
        self.focus = rng.normal(size=(L, N))
        self.resolution_px = rng.normal(size=(L, N)) * 3
        self.resolvability = rng.uniform(1, 2, size=L)


def test_objective_values_feature_reduction_and_mask():
    m = _M()
    cfg = ObjectiveConfig(aggregate="sum", feature_reduce="min")
    g = objective_values(m, cfg)
    assert g["g_FOV"] == pytest.approx(m.fov.min(1).sum())
    assert g["g_RES"] == pytest.approx(m.resolution_px.min(1).sum())
    assert g["g_DIR"] == pytest.approx(m.resolvability.sum())
    mask = np.array([False, True, True])
    g = objective_values(m, ObjectiveConfig(aggregate="min", feature_reduce="mean", fov_measure="image"),
                         feature_mask=mask)
    assert g["g_FOV"] == pytest.approx(m.fov_px[:, 1:].mean(1).min())
    assert g["g_FOC"] == pytest.approx(m.focus[:, 1:].mean(1).min())


def test_normaliser_never_uses_raw_units_for_tiny_initial_values():
    # the initial Λ is exactly 0 (e.g. an image singularity at x0): its scale must be the natural unit
    natural = {"g_FOV": 0.2, "g_DIR": 150.0, "g_RES": 5.0}
    norm = Normaliser.build("initial", {"g_FOV": -0.05, "g_DIR": 0.0, "g_RES": 1e-5}, natural)
    assert norm.reference == {"g_FOV": 0.05, "g_DIR": 150.0, "g_RES": 5.0}
    assert norm.sources == {"g_FOV": "initial", "g_DIR": "natural", "g_RES": "natural"}
    d = norm.to_dict()
    assert d["method"] == "initial" and "natural unit" in d["note"]
    assert Normaliser.build("natural", {"g_FOV": 3.0}, natural).reference == {"g_FOV": 0.2}


def test_natural_units_resolvability_is_pixels_per_mm_of_motion():
    from cadfeat.camera import Camera

    cam = Camera.preset("basler-aca1300-200um-8mm")
    u = natural_units(ObjectiveConfig(aggregate="mean"), cam, 10, 4, 250.0)
    # 4 points at 250 mm translating parallel to the image plane: each moves fx/250 px per mm
    assert u["resolvability"] == pytest.approx(np.sqrt(4) * cam.fx / 250.0)
    assert u["fov"] == pytest.approx(1 - np.cos(cam.fov_rad / 2))
    assert natural_units(ObjectiveConfig(aggregate="sum"), cam, 10, 4, 250.0)["focus"] == 10.0


def test_combine_weighted_maxmin_constraint():
    names = ["g_FOV", "g_RES", "g_DIR"]
    G = np.array([[0.5, 2.0, 1.0], [1.0, 1.0, 1.0]])
    w = ObjectiveConfig(measures=("fov", "resolution", "resolvability"), combine="weighted",
                        weights={"g_RES": 2.0})
    np.testing.assert_allclose(combine(G, w, names), [5.5, 4.0])
    mm = ObjectiveConfig(measures=("fov", "resolution", "resolvability"), combine="maxmin")
    np.testing.assert_allclose(combine(G, mm, names), [0.5, 1.0])
    c = ObjectiveConfig(measures=("fov", "resolution", "resolvability"), combine="constraint",
                        thresholds={"fov": 0.0})
    np.testing.assert_allclose(combine(G, c, names), [3.0, 2.0])


@pytest.mark.parametrize("kwargs, match", [
    ({"measures": ("fov", "colour")}, "measures"),
    ({"aggregate": "median"}, "aggregate"),
    ({"combine": "lexicographic"}, "combine"),
    ({"combine": "constraint"}, "thresholds"),
    ({"weights": {"g_XYZ": 1.0}}, "weights"),
    ({"smoothmin_beta": 0.0}, "smoothmin_beta"),
    ({"feature_reduce": "max"}, "feature_reduce"),
])
def test_objective_config_bad_input(kwargs, match):
    with pytest.raises(CadfeatError, match=match):
        ObjectiveConfig(**kwargs)


@pytest.mark.parametrize("matrix, verdict", [
    (np.eye(3), "uncoupled"),
    ([[1, 0, 0], [0, 0, 1], [0, 1, 0]], "uncoupled"),
    ([[1, 0, 0], [1, 1, 0], [1, 1, 1]], "decoupled"),
    ([[1, 1, 1], [0, 1, 0], [0, 1, 1]], "decoupled"),  # triangular after permuting rows and columns
    (np.ones((3, 3)), "coupled"),
    ([[1, 1], [1, 1]], "coupled"),
    ([[1, 0], [1, 0], [0, 1]], "coupled"),  # Theorem 1: more requirements than parameters
    ([[1, 0], [0, 0]], "uncoupled"),  # a requirement no parameter affects is left out
])
def test_classify_hand_made_matrices(matrix, verdict):
    assert classify(np.asarray(matrix, bool))[0] == verdict


def test_design_matrix_of_a_problem_positions_vs_diameter():
    # FOV (cone, centres only) depends on positions, resolution on the diameter (and slightly positions)
    problem = two_hole_problem(measures=("fov", "resolution"), n=8)
    dm = design_matrix(problem, problem.space.x0, rows="objectives", threshold_rel=0.05)
    assert dm.rows == ["g_FOV", "g_RES"] and dm.cols == ["position", "diameter"]
    assert dm.matrix[0, 1] == 0.0 and dm.matrix[1, 1] > 0
    assert dm.binary[0].tolist() == [True, False]
    assert dm.verdict in ("uncoupled", "decoupled")
    full = design_matrix(problem, problem.space.x0)
    assert full.rows[2:] == ["edge", "ligament"] and full.verdict == "coupled"
    per_var = design_matrix(problem, problem.space.x0, columns="variables", rows="objectives")
    assert per_var.cols == problem.space.names and per_var.to_dict()["verdict"] == per_var.verdict
