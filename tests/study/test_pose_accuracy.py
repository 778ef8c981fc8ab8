"""results.json ``pose_accuracy`` (``cadfeat.study.pose_accuracy``) on a plate with four holes seen along an
approach: the per-pose prediction equals a direct ``measures.pose_information`` call; "what would help most"
agrees in sign with actually moving / resizing the named hole; the filter bound lies under the single-frame one."""

from __future__ import annotations

import numpy as np
import pytest

from cadfeat.cad.features import Hole
from cadfeat.camera import Camera
from cadfeat.cell import Cell
from cadfeat.design.pose_terms import cell_models
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
    """``pose_information`` with the default cell's models (``design.pose_terms.cell_models``: its calibration)."""
    c = np.array([h.centre for h in holes])
    a = np.array([h.axis for h in holes])
    r = np.array([h.radius_mm for h in holes])
    ratio = np.array([h.depth_mm / (2 * h.radius_mm) for h in holes])
    return pose_information(camera, T, c, a, r, through=[h.through for h in holes], depth_ratio=ratio,
                            rotation_length_mm=50.0, model=cell_models(Cell()))


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
                            rotation_length_mm=20.0, model=cell_models(setup.problem.cell))
    assert values["g_POSE"] == pytest.approx(pose_objective(info, "worst", 20.0), rel=1e-9)


# A plate with a low wall (x ∈ [−12, −6] mm, 5 mm high) and a camera looking along +x from above: the wall's
# shadow ends near x = +2.5 mm, so hole H (x = −3) is hidden at every pose and 8 mm along +x it is in view.
WALL_LO, WALL_HI = np.array([-12.0, -40.0, 0.0]), np.array([-6.0, 40.0, 5.0])


def _wall_scene():
    trimesh = pytest.importorskip("trimesh")
    from cadfeat.poses import look_at

    plate = trimesh.creation.box(extents=(120, 100, 5))
    plate.apply_translation((0, 0, -2.5))
    mesh = trimesh.util.concatenate([plate, trimesh.creation.box(bounds=np.stack([WALL_LO, WALL_HI]))])
    eyes = [(-250.0 + 10 * k, 10.0 * k - 30.0, 150.0) for k in range(6)]
    T = np.stack([invert_T(look_at(np.array(e), np.array([10.0, 0.0, 0.0]), up=(0, 0, 1))) for e in eyes])
    spec = {"P": (30.0, -20.0, 3.0), "Q": (35.0, 25.0, 3.0), "R": (55.0, 0.0, 2.5), "S": (10.0, 30.0, 2.0),
            "H": (-3.0, 5.0, 1.5)}
    holes = [Hole(np.array([x, y, 0.0]), np.array([0.0, 0.0, 1.0]), r, r, 3.0, False, "plain", 0, None, name)
             for name, (x, y, r) in spec.items()]
    return mesh, T, holes


def _rim_hidden_by_slab(centre, radius, T, samples=16):
    """Independent: fraction of rim points whose segment to the camera crosses the wall box (slab test)."""
    eyes = invert_T(T)[:, :3, 3]
    ang = np.linspace(0, 2 * np.pi, samples, endpoint=False)
    rim = centre + radius * np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], axis=1)
    d = eyes[:, None, :] - rim[None]                                          # (L, S, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (WALL_LO - rim[None]) / d, (WALL_HI - rim[None]) / d
    enter, leave = np.minimum(t1, t2).max(axis=-1), np.maximum(t1, t2).min(axis=-1)
    return ((enter < leave) & (leave > 1e-6) & (enter < 1 - 1e-6)).mean(axis=1)


def test_help_most_says_move_a_hidden_hole_out_of_hiding():
    """The hidden hole's gradient is zero (its hidden fraction is held), so only the probe can help; it must name
    the hole, a move that the independent slab test confirms brings the rim into view, and an error drop that a
    direct pose_information with the slab test's occlusion confirms."""
    from cadfeat.measures.rim_occlusion import rim_occlusion
    from cadfeat.study.pose_accuracy import help_most

    mesh, T, holes = _wall_scene()
    names = [h.name for h in holes]
    c = np.array([h.centre for h in holes])
    a = np.array([h.axis for h in holes])
    r = np.array([h.radius_mm for h in holes])
    assert np.all(_rim_hidden_by_slab(c[-1], r[-1], T) > 0.5)                   # H hidden at every pose
    occ = rim_occlusion(mesh, T, c, a, r, samples=16)
    held = help_most(CAMERA_PRESET, T, holes, names, ["H"], occ, 50.0)        # no mesh: the old answer
    assert held["holes"]["H"]["d_error_per_mm_move"] == 0.0 and "out_of_hiding" not in held["holes"]["H"]
    hm = help_most(CAMERA_PRESET, T, holes, names, ["H"], occ, 50.0, mesh)
    assert hm["best"]["hole"] == "H" and hm["best"]["change"] == "reveal"
    assert "out of hiding" in hm["best"]["sentence"] and "rotation" in hm["best"]["sentence"]
    probe = hm["holes"]["H"]["out_of_hiding"]
    moved = c[-1] + probe["distance_mm"] * np.array(probe["direction"])
    slab = _rim_hidden_by_slab(moved, r[-1], T)
    assert np.mean(slab <= 0.03) >= probe["detected_fraction"] - 1e-9 and probe["detected_fraction"] > 0.5
    occ2 = occ.copy()
    occ2[:, -1] = slab
    c2 = c.copy()
    c2[-1] = moved
    ratio = 3.0 / (2 * r)                                                     # depth / diameter
    before = pose_information(CAMERA_PRESET, T, c, a, r, occlusion=occ, through=[False] * 5, depth_ratio=ratio,
                              rotation_length_mm=50.0, model=cell_models(Cell()))
    after = pose_information(CAMERA_PRESET, T, c2, a, r, occlusion=occ2, through=[False] * 5, depth_ratio=ratio,
                             rotation_length_mm=50.0, model=cell_models(Cell()))
    drop = _rms(after.error_translation_mm) - _rms(before.error_translation_mm)
    assert drop < 0 and drop == pytest.approx(probe["d_error_mm"], rel=0.2)
    assert probe["d_rotation_deg"] == pytest.approx(_rms(after.error_rotation_deg) - _rms(before.error_rotation_deg),
                                                    rel=0.2, abs=1e-6)


CAMERA_PRESET = Camera.preset("basler-aca1300-200um-8mm")
