"""Images, detection and the closed loop, against independent references and a scene with a known answer.

- the thin-lens blur equals the camera's acceptable blur circle exactly at its near and far planes
  (``Camera.depth_of_field_mm``, eq. 3.4–3.5);
- sensor images are deterministic per seed and differ between seeds;
- detection on clean renders recovers the exact rim-ellipse centres (``measures.hole_ellipse``) within 0.3 px;
- association never matches a hole to another hole's detection (missing → NaN);
- end to end: spreading four target holes over the plate lowers the pose error, with a significant paired
  (Wilcoxon) difference.
"""

from __future__ import annotations

import numpy as np
import pytest

cq = pytest.importorskip("cadquery")

from cadfeat.cad.features import extract_holes, holes_to_arrays  # noqa: E402
from cadfeat.camera import Camera  # noqa: E402
from cadfeat.cell import Cell  # noqa: E402
from cadfeat.measures import hole_ellipse  # noqa: E402
from cadfeat.measures.focus import defocus_diameter_px  # noqa: E402
from cadfeat.poses import invert_T, look_at  # noqa: E402
from cadfeat.trajectory import orbit_arc  # noqa: E402
from cadfeat.vision.closed_loop import TrackingConfig, compare, design_json, observe, track_design  # noqa: E402
from cadfeat.vision.detection import Detections, associate, detect_holes  # noqa: E402
from cadfeat.vision.images import render_sequence, sensor_images  # noqa: E402

CAMERA = Camera(fx=420.0, fy=420.0, cx=160.0, cy=120.0, width=320, height=240, dist=(-0.12, 0.02, 0.0, 0.0, 0.0),
                focus_distance_mm=300.0)


def _plate(points):
    return cq.Workplane("XY").box(100, 80, 5).faces(">Z").workplane().pushPoints(points).hole(8)


def test_defocus_blur_is_the_blur_circle_at_the_depth_of_field_limits():
    near, far = CAMERA.depth_of_field_mm
    c_px = CAMERA.blur_circle_mm / CAMERA.pixel_pitch_mm
    np.testing.assert_allclose(defocus_diameter_px(CAMERA, np.array([near, far])), [c_px, c_px], rtol=1e-9)
    assert defocus_diameter_px(CAMERA, CAMERA.focus_distance_mm) == 0.0


def test_sensor_noise_is_deterministic_per_seed():
    optical = np.full((2, 30, 40), 100.0, dtype=np.float32)
    a, b, c = (sensor_images(optical, 3.0, s) for s in (5, 5, 6))
    assert a.dtype == np.uint8 and np.array_equal(a, b) and not np.array_equal(a, c)
    assert abs(float(a.std()) - 3.0) < 0.3 and not np.array_equal(a[0], a[1])


def test_detection_recovers_rim_ellipse_centres_on_clean_renders():
    wp = _plate([(-30, -20), (25, -15), (-10, 22), (30, 25)])
    wp = wp.faces(">Z").workplane().pushPoints([(0, 0)]).cboreHole(6, 12, 2)
    holes = extract_holes(wp)
    eyes = [(0, 0, 300), (60, -80, 260), (-90, 50, 250), (110, 40, 240)]
    T = np.stack([invert_T(look_at(np.array(e, float), np.array([0.0, 0.0, 2.5]), up=(0, 1, 0))) for e in eyes])
    images = render_sequence(wp.val(), holes, CAMERA, T)
    centres, axes, radii = holes_to_arrays(holes)
    worst = 0.0
    for k in range(len(T)):
        e = hole_ellipse(CAMERA, centres @ T[k, :3, :3].T + T[k, :3, 3], axes @ T[k, :3, :3].T, radii)
        got = associate(e, detect_holes(np.rint(images[k]).astype(np.uint8)))
        assert np.all(np.isfinite(got)), k
        worst = max(worst, float(np.linalg.norm(got - e.centre_px, axis=1).max()))
    assert worst < 0.3, worst


def test_association_never_matches_a_wrong_hole():
    pred = hole_ellipse(CAMERA, np.array([[-20.0, 0, 300], [-12.0, 0, 300], [30.0, 0, 300]]),
                        np.tile([0.0, 0, -1], (3, 1)), np.array([3.0, 3.0, 3.0]))
    pc = pred.centre_px
    # hole 0 missed; hole 1 found 0.4 px off; a detection between 0 and 1 (merged blob) and one far away
    det_centres = np.array([pc[1] + [0.4, 0.0], 0.5 * (pc[0] + pc[1]), pc[2] + [30.0, 0.0]])
    det = Detections(det_centres, np.tile(pred.axes_px[0], (3, 1)), np.zeros(3), np.zeros(3))
    got = associate(pred, det, gate_px=10.0)
    assert np.isnan(got[0]).all() and np.isnan(got[2]).all()
    np.testing.assert_allclose(got[1], pc[1] + [0.4, 0.0])
    # a detection of the wrong size is not taken either
    small = Detections(pc[:1].copy(), pred.axes_px[:1] / 3.0, np.zeros(1), np.zeros(1))
    assert np.isnan(associate(pred, small)).all()


def test_spread_holes_track_better_end_to_end():
    """Known answer: four holes clustered in a 16 × 12 mm square vs spread over 76 × 56 mm; same camera,
    trajectory, noise seeds and initial errors. The spread layout must give lower pose errors (paired test)."""
    before = _plate([(-8, -6), (8, -6), (8, 6), (-8, 6)])
    after = _plate([(-38, -28), (38, -28), (38, 28), (-38, 28)])
    traj = orbit_arc(centre=[0, 0, 2.5], radius_mm=300, elevation_deg=70, azimuth_start_deg=-110,
                     azimuth_end_deg=-70, n=12, duration_s=1.2)
    T = invert_T(traj.T_task_cam)
    config = TrackingConfig(runs=8, exposure_s=0.005, settle_frames=3, r_px2=0.05, q_rate_mm2_s2=10.0,
                            q_omega_rad2_s2=1e-4, initial_error_mm=5.0, initial_error_deg=1.0, sigma0_mm=20.0,
                            sigma0_rad=0.1, cell=Cell(noise_sigma_grey=4.0))
    results = {}
    for name, wp in (("before", before), ("after", after)):
        obs = observe(wp.val(), extract_holes(wp), CAMERA, T, config.sensor, traj.velocity_screws())
        results[name] = track_design(CAMERA, obs, T, traj.times_s, config)
        assert np.all(results[name].detection_rate == 1.0)
    verdicts = compare(results["before"], results["after"])
    for method in config.estimators:
        assert verdicts[method]["verdict"] == "better", (method, verdicts[method])
        assert verdicts[method]["translation"]["p_value"] < 0.01
        b = design_json(results["before"])["estimators"][method]["trans_mm_rms"]
        a = design_json(results["after"])["estimators"][method]["trans_mm_rms"]
        assert a["ci_high"] < b["ci_low"]


def test_paired_verdict_needs_significance_and_a_change_that_matters():
    from scipy.stats import wilcoxon

    from cadfeat.vision.metrics import paired_verdict

    before = 1.0 + 0.1 * np.random.default_rng(0).random(12)
    small = paired_verdict(before, 0.98 * before, min_change=0.05)      # consistent, significant, but 2 %
    assert small["p_value"] == pytest.approx(wilcoxon(before, 0.98 * before).pvalue) and small["p_value"] < 0.01
    assert small["verdict"] == "no significant difference"
    assert paired_verdict(before, 0.98 * before)["verdict"] == "better"
    assert paired_verdict(before, 0.8 * before, min_change=0.05)["verdict"] == "better"
    assert paired_verdict(before, 1.3 * before, min_change=0.05)["verdict"] == "worse"
    noisy = before + 0.05 * np.random.default_rng(1).standard_normal(12)
    assert paired_verdict(before, noisy)["verdict"] == "no significant difference"
