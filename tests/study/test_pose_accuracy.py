"""results.json ``pose_accuracy`` (``cadfeat.study.pose_accuracy``) on a plate with four holes seen along an
approach: the per-pose prediction equals a direct ``measures.pose_information`` call; "what would help most"
agrees in sign with actually moving / resizing the named hole; the filter bound lies under the single-frame one."""

from __future__ import annotations

import numpy as np
import pytest

from cadfeat.cad.features import Hole
from cadfeat.camera import Camera
from cadfeat.measures import pose_information
from cadfeat.poses import invert_T
from cadfeat.study.pose_accuracy import PHASES, design_pose_accuracy
from cadfeat.trajectory import straight_approach
from cadfeat.vision import FilterTuning

# (x, y, r, depth, through): a blind target hole B and three through holes
LAYOUT = {"A": (-30.0, 20.0, 2.0, 8.0, True), "B": (25.0, 15.0, 1.6, 3.0, False),
          "C": (-30.0, -20.0, 2.5, 8.0, True), "D": (30.0, -20.0, 1.5, 8.0, True)}


def _holes(shift_b=(0.0, 0.0), dr_b=0.0):
    out = []
    for name, (x, y, r, depth, through) in LAYOUT.items():
        if name == "B":
            x, y, r = x + shift_b[0], y + shift_b[1], r + dr_b
        out.append(Hole(np.array([x, y, 0.0]), np.array([0.0, 0.0, 1.0]), r, r, depth, through, "plain", 0, None,
                        name))
    return out


@pytest.fixture(scope="module")
def scene():
    camera = Camera.preset("basler-aca1300-200um-8mm")
    traj = straight_approach((-60.0, -40.0, 300.0), (60.0, 40.0, 240.0), (0.0, 0.0, 0.0), n=12, duration_s=2.0)
    T = invert_T(np.asarray(traj.T_task_cam))
    holes = _holes()
    block = design_pose_accuracy(camera, T, np.asarray(traj.times_s), holes, [h.name for h in holes], ["B"], None,
                                 FilterTuning(), 50.0)
    return camera, T, block


def _direct(camera, T, holes):
    c = np.array([h.centre for h in holes])
    a = np.array([h.axis for h in holes])
    r = np.array([h.radius_mm for h in holes])
    ratio = np.array([h.depth_mm / (2 * h.radius_mm) for h in holes])
    return pose_information(camera, T, c, a, r, through=[h.through for h in holes], depth_ratio=ratio,
                            rotation_length_mm=50.0)


def _rms(v):
    return float(np.sqrt(np.mean(np.square(v))))


def test_per_pose_prediction_equals_pose_information(scene):
    camera, T, block = scene
    info = _direct(camera, T, _holes())
    pp = block["per_pose"]
    np.testing.assert_allclose(pp["error_translation_mm"], info.error_translation_mm, rtol=1e-10)
    np.testing.assert_allclose(pp["error_rotation_deg"], info.error_rotation_deg, rtol=1e-10)
    np.testing.assert_allclose(pp["bias_translation_mm"], info.bias_translation_mm, rtol=1e-10)
    np.testing.assert_allclose(pp["noise_translation_mm"], info.sigma_translation_mm, rtol=1e-10)
    # the parts combine as √(bias² + noise²)
    np.testing.assert_allclose(np.hypot(pp["bias_rotation_deg"], pp["noise_rotation_deg"]), pp["error_rotation_deg"],
                               rtol=1e-10)
    assert block["rms"]["error_translation_mm"] == pytest.approx(_rms(info.error_translation_mm), rel=1e-10)
    assert sum(block["share"].values()) == pytest.approx(1.0, abs=1e-9)
    assert [p["phase"] for p in block["weakest"]] == list(PHASES)
    # the filter accumulates information over frames: its bound is under the single-frame noise bound
    assert np.all(np.array(pp["iekf_translation_mm"]) <= np.array(pp["noise_translation_mm"]) * (1 + 1e-9))


def test_help_most_agrees_with_moving_the_hole(scene):
    camera, T, block = scene
    hm = block["help_most"]
    assert set(hm["holes"]) == {"B"} and hm["best"]["hole"] == "B"
    e0 = _rms(_direct(camera, T, _holes()).error_translation_mm)
    d = hm["holes"]["B"]
    assert d["d_error_per_mm_move"] < 0
    step = 1.0
    moved = _rms(_direct(camera, T, _holes(shift_b=step * np.array(d["move_direction"][:2]))).error_translation_mm)
    assert moved < e0
    assert (moved - e0) / step == pytest.approx(d["d_error_per_mm_move"], rel=0.5)
    dr = d["d_error_per_mm_radius"]
    resized = _rms(_direct(camera, T, _holes(dr_b=0.3)).error_translation_mm)
    assert np.sign(resized - e0) == np.sign(dr)
    assert "B" in hm["best"]["sentence"]


def test_g_pose_of_a_study_equals_a_direct_assembly(tmp_path):
    """The study's reported g_POSE (``pipeline.score``: exact rim occlusion) equals pose_information on the
    study's holes with the rim test on a mesh of its part built here, aggregated by pose_objective."""
    from study_helpers import study

    from cadfeat.cad.export import mesh_from_shape
    from cadfeat.design.objectives import pose_objective
    from cadfeat.measures.rim_occlusion import rim_occlusion
    from cadfeat.study.pipeline import score
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_study

    config = load_study(study(tmp_path, objective={"measures": ["fov", "pose"], "pose_aggregate": "worst",
                                                   "pose_rotation_length_mm": 20.0}))
    setup = setup_study(config)
    values, _ = score(setup, setup.holes0)
    holes = setup.holes0
    c = np.array([h.centre for h in holes])
    a = np.array([h.axis for h in holes])
    r = np.array([h.radius_mm for h in holes])
    T = invert_T(np.asarray(setup.trajectory.T_task_cam)) @ setup.T_task_part
    through = np.array([h.through for h in holes])
    depth = np.array([h.depth_mm for h in holes])
    occ = rim_occlusion(mesh_from_shape(setup.shape0, tolerance=0.05), T, c, a, r, through=through, depth_mm=depth)
    info = pose_information(setup.camera, T, c, a, r, occlusion=occ, through=through, depth_ratio=depth / (2 * r),
                            rotation_length_mm=20.0)
    assert values["g_POSE"] == pytest.approx(pose_objective(info, "worst", 20.0), rel=1e-9)
