"""g_POSE inside the optimisation problem (``design.pose_terms``, ``Problem``): equals an independent assembly of
``measures.pose_information`` + ``objectives.pose_objective`` on the same holes; batched = one by one; usable in
weighted and max-min combinations and as a constraint."""

from __future__ import annotations

import numpy as np
import pytest

from cadfeat.design.objectives import pose_objective
from cadfeat.design.pose_terms import pose_aggregate_batch
from cadfeat.measures import pose_information
from cadfeat.measures.pose_models import models_for
from cadfeat.poses import invert_T
from tests.optim_helpers import two_hole_problem


def _direct(problem, x, how):
    """Independent assembly: the camera poses from the trajectory, the holes from the model, no occlusion mesh,
    the models of the problem's cell (``pose_models.models_for``, with its gate and placement)."""
    c, a, r = problem.model.features(x)
    T = invert_T(np.asarray(problem.trajectory.T_task_cam)) @ np.eye(4)
    ell = problem.objective_config.pose_rotation_length_mm
    holes = problem.model.holes
    info = pose_information(problem.camera, T, c, a, r, rotation_length_mm=ell,
                            model=models_for(problem.cell).for_cell(problem.cell),
                            through=[h.through for h in holes],
                            depth_ratio=[h.depth_mm / (2 * ri) for h, ri in zip(holes, r, strict=True)])
    return pose_objective(info, how, ell), info


@pytest.mark.parametrize("how", ["rms", "worst", "logdet"])
def test_g_pose_equals_pose_information_and_pose_objective(how):
    problem = two_hole_problem(measures=("pose",), pose_rotation_length_mm=20.0, pose_aggregate=how,
                               normalisation="natural")
    x = problem.space.x0
    g = problem.features_objectives(*problem.model.features(x))
    expected, _ = _direct(problem, x, how)
    assert g[0] == pytest.approx(expected, rel=1e-9)
    assert expected < 0


def test_batched_g_pose_equals_one_by_one_and_mixes_with_the_thesis_measures():
    problem = two_hole_problem(measures=("resolution", "pose"), combine="maxmin", rotation_length_mm=50.0,
                               normalisation="natural")
    rng = np.random.default_rng(3)
    X = problem.space.lower + rng.random((4, problem.space.size)) * problem.space.span
    G, _ = problem.evaluate_batch(X)
    for b, x in enumerate(X):
        one = problem.features_objectives(*problem.model.features(x))
        np.testing.assert_allclose(G[b], one, rtol=1e-9)
        assert G[b, 1] == pytest.approx(_direct(problem, x, "rms")[0], rel=1e-9)
    assert np.all(np.isfinite(problem.combined_from(G)))
    weighted = two_hole_problem(measures=("resolution", "pose"), combine="weighted", rotation_length_mm=50.0,
                                normalisation="natural", weights={"pose": 1.0, "resolution": 0.5})
    assert np.all(np.isfinite(weighted.combined_from(weighted.evaluate_batch(X)[0])))


def test_g_pose_as_a_constraint_predicted_error_at_most():
    problem = two_hole_problem(measures=("resolution", "pose"), combine="constraint", rotation_length_mm=50.0,
                               thresholds={"pose": -0.05}, normalisation="natural")
    x = problem.space.x0
    G, C = problem.evaluate_batch(x[None])
    err = -_direct(problem, x, "rms")[0]
    # the last margin is (g − (−0.05)) / scale: positive exactly when the predicted error is ≤ 0.05 mm
    assert C[0, -1] * problem.scales[1] == pytest.approx(0.05 - err, rel=1e-9)


def test_batched_aggregate_matches_pose_objective():
    problem = two_hole_problem(measures=("pose",), rotation_length_mm=50.0)
    _, info = _direct(problem, problem.space.x0, "rms")
    for how in ("rms", "worst", "logdet"):
        g = pose_aggregate_batch(info.error_mm(50.0)[None], info.information[None], how, 50.0)
        assert g[0] == pytest.approx(pose_objective(info, how, 50.0), rel=1e-12)


def test_stacked_designs_with_depth_map_occlusion_equal_one_design_at_a_time(tmp_path):
    """The optimiser's one-call path (B·L stacked poses, every design's rims against each pose's depth map)
    equals ``pose_of_features`` design by design (holes (N, 3), its own rim test) on a study with occlusion."""
    from study_helpers import study

    from cadfeat.design.pose_terms import pose_of_features
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_study

    problem = setup_study(load_study(study(tmp_path, objective={"measures": ["pose"]}))).problem
    assert problem.occlusion is not None
    rng = np.random.default_rng(5)
    X = problem.space.lower + rng.random((3, problem.space.size)) * problem.space.span
    G, _ = problem.evaluate_batch(X)
    for b, x in enumerate(X):
        info = pose_of_features(problem, *problem.model.features(x))
        assert G[b, 0] == pytest.approx(pose_objective(info, "rms", problem.objective_config.pose_rotation_length_mm),
                                        rel=1e-9)


def test_fixed_holes_kept_between_calls_give_pose_informations_numbers(tmp_path):
    """``stacked_information`` evaluates the fixed holes once and keeps them between calls (the robust solve's
    speed-up); it gives ``measures.pose_information``'s numbers on all holes, design by design
    (``pose_of_features``: its own rim test and one pose_information call), bit for bit — also when a moving hole
    comes so close to a fixed hole's rim that the detection model's rim gap couples them."""
    import copy

    from study_helpers import study

    from cadfeat.design.pose_terms import pose_of_features, stacked_information
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_study

    problem = copy.copy(setup_study(load_study(study(tmp_path, objective={"measures": ["pose"]}))).problem)
    assert problem.occlusion is not None
    c0, a0, r0 = (np.asarray(v, float) for v in problem.model.features(problem.space.x0))
    N = len(r0)
    problem.fixed_mask = np.arange(N) > 0  # hole 0 moves, the others are fixed
    X = np.repeat(c0[None], 3, axis=0)
    X[1, 0, :2] += [2.0, -1.0]
    d = c0[1] - c0[0]
    X[2, 0] = c0[1] - d * (1.2 * r0[1] + r0[0] + 0.3) / np.linalg.norm(d)  # rims 0.2·r apart: the gap couples them
    A, R = np.repeat(a0[None], 3, axis=0), np.repeat(r0[None], 3, axis=0)
    ell = problem.objective_config.pose_rotation_length_mm
    for _ in range(2):  # the second call finds the fixed holes' terms kept
        got = stacked_information(problem, X, A, R)
        L = len(problem.T_cam_part)
        for b in range(3):
            ref = pose_of_features(problem, X[b], A[b], R[b])
            sl = slice(b * L, (b + 1) * L)
            assert np.array_equal(got.information[sl], ref.information)
            assert np.array_equal(got.error_mm(ell)[sl], ref.error_mm(ell))
    # the close moving hole changes the fixed neighbour's detection probability (the coupling is exercised)
    near, far = (pose_of_features(problem, X[b], A[b], R[b]) for b in (2, 0))
    assert np.abs(near.probability[:, 1] - far.probability[:, 1]).max() > 1e-3


def _glare(problem, grey):
    """Uniform glare maps at the problem's poses: a face of ``grey`` everywhere (measures.glare)."""
    from cadfeat.measures.glare import GlareMaps
    from cadfeat.render.glare import reduced

    small = reduced(problem.camera, 4)
    image = np.full((len(problem.T_cam_part), small.height, small.width), grey, np.float32)
    return GlareMaps(image, small, np.zeros((0, 3)), np.zeros(0))


def test_glare_takes_blind_rims_against_a_bright_face_away_and_both_paths_agree():
    """A face at full scale leaves a clipped bore no edge: with such maps the blind holes' detection rate and
    information vanish; a dark face (c ≫ 21.5 σ) changes nothing. The batched optimiser path and
    ``pose_of_features`` give the same numbers with the maps."""
    import dataclasses

    from cadfeat.design.pose_terms import pose_of_features, stacked_information

    problem = two_hole_problem(measures=("pose",), normalisation="natural")
    c, a, r = (np.asarray(v, float) for v in problem.model.features(problem.space.x0))
    through = pose_of_features(problem, c, a, r)
    problem.set_glare(_glare(problem, 255.0))       # the plate's through holes show the background: no change
    np.testing.assert_array_equal(pose_of_features(problem, c, a, r).information, through.information)
    problem.set_glare(None)
    problem.model.holes = [dataclasses.replace(h, through=False, depth_mm=3.0) for h in problem.model.holes]
    ref0 = pose_of_features(problem, c, a, r)
    assert ref0.probability.max() > 0.5
    problem.set_glare(_glare(problem, 60.0))
    np.testing.assert_allclose(pose_of_features(problem, c, a, r).information, ref0.information, rtol=1e-6)
    problem.set_glare(_glare(problem, 255.0))
    ref = pose_of_features(problem, c, a, r)
    assert ref.probability.max() < 0.01 * ref0.probability.max()   # s(−21.5/4) ≈ 0.005 of the rate
    got = stacked_information(problem, c[None], a[None], r[None])
    np.testing.assert_allclose(got.information, ref.information, rtol=1e-9, atol=1e-12)
