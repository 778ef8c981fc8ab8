"""Camera: projection and distortion against OpenCV, thin-lens depth of field against the blur circle
computed another way, field of view, calibration files, presets and bad input."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from cadfeat.camera import PRESETS, Camera, CameraError, build_camera, write_opencv_calibration
from cadfeat.settings import StudyError, validate_section
from cadfeat.study.settings.camera import CameraSettings

pytestmark = pytest.mark.numerics  # run again under another BLAS kernel (Makefile: test)

DATA = __import__("pathlib").Path(__file__).parent / "data"
RNG = np.random.default_rng(20050301)


def _cv2_project(camera: Camera, points_cam: np.ndarray) -> np.ndarray:
    uv, _ = cv2.projectPoints(points_cam.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), camera.K, camera.dist_coeffs)
    return uv.reshape(points_cam.shape[:-1] + (2,))


def _points_in_view(camera: Camera, n: int, depth: tuple[float, float]) -> np.ndarray:
    """Random camera-frame points whose undistorted projection lies inside the image."""
    z = RNG.uniform(*depth, n)
    u, v = RNG.uniform(0, camera.width, n), RNG.uniform(0, camera.height, n)
    return np.stack([(u - camera.cx) / camera.fx * z, (v - camera.cy) / camera.fy * z, z], axis=-1)


# ---------------------------------------------------------------------- projection
@pytest.mark.parametrize("dist", [
    (0.0, 0.0, 0.0, 0.0, 0.0),
    (-0.21, 0.08, 0.0013, -0.0021, -0.012),
    (0.35, -0.5, -0.004, 0.003, 0.9),
])
def test_project_matches_cv2_projectPoints(dist):
    cam = Camera(fx=812.3, fy=809.1, cx=331.0, cy=247.5, width=640, height=480, dist=dist)
    pts = _points_in_view(cam, 500, (50.0, 2000.0))
    np.testing.assert_allclose(cam.project(pts), _cv2_project(cam, pts), rtol=0, atol=1e-9)


def test_project_dalsa_preset_matches_cv2_and_keeps_batch_shape():
    cam = Camera.preset("dalsa-cad1-128a")
    pts = _points_in_view(cam, 120, (28.0, 60.0)).reshape(4, 30, 3)
    uv = cam.project(pts)
    assert uv.shape == (4, 30, 2)
    np.testing.assert_allclose(uv, _cv2_project(cam, pts), rtol=0, atol=1e-9)


@pytest.mark.parametrize("name", ["dalsa-cad1-128a", "realsense-d435-rgb"])
def test_distortion_jacobian_matches_finite_differences(name):
    cam = Camera.preset(name)
    if not cam.has_distortion:
        cam = cam.replace(dist=(0.12, -0.3, 0.002, -0.001, 0.07))
    xy = RNG.uniform(-0.3, 0.3, (200, 2))
    h = 1e-6
    fd = np.stack([(cam.distort_normalized(xy + h * e) - cam.distort_normalized(xy - h * e)) / (2 * h)
                   for e in np.eye(2)], axis=-1)
    np.testing.assert_allclose(cam.distortion_jacobian(xy), fd, rtol=1e-6, atol=1e-5)


def test_distortion_jacobian_matches_opencv_translation_jacobian():
    """For points at Z = 1 with zero pose, ∂(u,v)/∂(tx,ty) from cv2.projectPoints is ∂(u,v)/∂(x,y)."""
    cam = Camera.preset("dalsa-cad1-128a")
    xy = RNG.uniform(-0.25, 0.25, (50, 2))
    pts = np.concatenate([xy, np.ones((50, 1))], axis=1)
    _, jac = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K, cam.dist_coeffs)
    d_dt = jac[:, 3:5].reshape(50, 2, 2)  # rows u0 v0 u1 v1 ...; columns tx, ty
    np.testing.assert_allclose(cam.distortion_jacobian(xy), d_dt, rtol=1e-9, atol=1e-9)


# ---------------------------------------------------------------------- optics (eq. 3.4-3.6)
def _blur_diameter_mm(cam: Camera, depth_mm: np.ndarray) -> np.ndarray:
    """Thin lens, computed independently: a point at D focuses at d_D = f D / (D − f); on the sensor at d
    its blur disc has diameter a |d_D − d| / d_D."""
    f, a = cam.focal_length_mm, cam.aperture_mm
    d = 1.0 / (1.0 / f - 1.0 / cam.focus_distance_mm)
    d_D = f * depth_mm / (depth_mm - f)
    return a * np.abs(d_D - d) / d_D


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_depth_of_field_planes_have_the_limiting_blur_circle(name):
    cam = Camera.preset(name)
    near, far = cam.depth_of_field_mm
    assert cam.focal_length_mm < near < cam.focus_distance_mm < far
    assert _blur_diameter_mm(cam, np.array([near]))[0] == pytest.approx(cam.blur_circle_mm, rel=1e-9)
    if np.isfinite(far):
        assert _blur_diameter_mm(cam, np.array([far]))[0] == pytest.approx(cam.blur_circle_mm, rel=1e-9)
    inside = np.linspace(near, min(far, 50 * cam.focus_distance_mm), 50)[1:-1]
    assert np.all(_blur_diameter_mm(cam, inside) < cam.blur_circle_mm)
    outside = np.array([0.5 * (near + cam.focal_length_mm), 0.99 * near])
    assert np.all(_blur_diameter_mm(cam, outside) > cam.blur_circle_mm)


@pytest.mark.parametrize("f_mm, n, focus_mm, c_mm", [(3.5, 5.6, 45.0, 0.016), (25.0, 2.8, 900.0, 0.01),
                                                     (12.0, 11.0, 300.0, 0.007)])
def test_depth_of_field_random_optics(f_mm, n, focus_mm, c_mm):
    cam = Camera(fx=1000, fy=1000, cx=500, cy=500, width=1000, height=1000, focal_length_mm=f_mm, f_number=n,
                 focus_distance_mm=focus_mm, blur_circle_mm=c_mm)
    near, far = cam.depth_of_field_mm
    assert _blur_diameter_mm(cam, np.array([near]))[0] == pytest.approx(c_mm, rel=1e-9)
    if np.isfinite(far):
        assert _blur_diameter_mm(cam, np.array([far]))[0] == pytest.approx(c_mm, rel=1e-9)


def test_hyperfocal_distance():
    cam = Camera.preset("basler-aca1300-200um-8mm")
    H = cam.hyperfocal_distance_mm
    # Focused at H, a point at infinity (image at d_∞ = f) has exactly the limiting blur a (d − f) / f = c.
    at_h = cam.replace(focus_distance_mm=H)
    blur_inf = at_h.aperture_mm * (at_h.image_distance_mm - at_h.focal_length_mm) / at_h.focal_length_mm
    assert blur_inf == pytest.approx(cam.blur_circle_mm, rel=1e-9)
    # ... the near plane is then H/2, and past H the far plane is at infinity.
    assert at_h.depth_of_field_mm[0] == pytest.approx(H / 2, rel=1e-9)
    assert cam.replace(focus_distance_mm=1.001 * H).depth_of_field_mm[1] == float("inf")
    assert np.isfinite(cam.replace(focus_distance_mm=0.999 * H).depth_of_field_mm[1])
    assert Camera.preset("realsense-d435-rgb").depth_of_field_mm[1] == float("inf")


def test_image_distance_is_thin_lens():
    cam = Camera.preset("flir-bfs-u3-51s5m-12mm")
    d = cam.image_distance_mm
    assert 1 / cam.focal_length_mm == pytest.approx(1 / d + 1 / cam.focus_distance_mm, rel=1e-12)


# ---------------------------------------------------------------------- field of view
@pytest.mark.parametrize("name", sorted(PRESETS))
def test_fov_cone_touches_the_nearest_image_border(name):
    """A ray at α/2 off the optical axis, towards the nearest border of the smaller dimension, projects
    (pinhole, via cv2) onto that border; every other border direction is farther."""
    cam = Camera.preset(name).without_distortion()
    half = cam.fov_rad / 2
    dirs = {"left": (-1, 0), "right": (1, 0), "up": (0, -1), "down": (0, 1)}
    border = {"left": 0.0, "right": cam.width, "up": 0.0, "down": cam.height}
    slack = {}
    for key, (dx, dy) in dirs.items():
        ray = np.array([[dx * np.sin(half), dy * np.sin(half), np.cos(half)]])
        uv = _cv2_project(cam, ray)[0]
        slack[key] = abs(uv[0] - border[key]) if dx else abs(uv[1] - border[key])
    assert min(slack.values()) == pytest.approx(0.0, abs=1e-6)


def test_fov_of_centred_camera_is_the_smaller_dimension():
    cam = Camera.preset("basler-aca1300-200um-8mm")
    assert cam.fov_rad == pytest.approx(2 * np.arctan(cam.height / 2 / cam.fy))


# ---------------------------------------------------------------------- calibration files
def _write_with_filestorage(path, K, dist, size):
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", size[0])
    fs.write("image_height", size[1])
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", dist)
    fs.release()


@pytest.mark.parametrize("ext", ["yaml", "json", "xml"])
def test_opencv_filestorage_round_trip(tmp_path, ext):
    K = np.array([[903.25, 0.0, 655.5], [0.0, 901.75, 371.25], [0.0, 0.0, 1.0]])
    dist = np.array([[-0.2875, 0.1125, 0.00075, -0.0005, -0.0375]])
    path = tmp_path / f"calib.{ext}"
    _write_with_filestorage(path, K, dist, (1280, 720))
    cam = Camera.from_opencv_file(path, focal_length_mm=6.0, f_number=2.8)
    np.testing.assert_array_equal(cam.K, K)
    np.testing.assert_array_equal(cam.dist_coeffs, dist.ravel())
    assert (cam.width, cam.height, cam.focal_length_mm, cam.f_number) == (1280, 720, 6.0, 2.8)
    # and back out through write_opencv_calibration, read by plain FileStorage
    out = tmp_path / f"out.{ext}"
    write_opencv_calibration(cam, out)
    fs = cv2.FileStorage(str(out), cv2.FILE_STORAGE_READ)
    np.testing.assert_array_equal(fs.getNode("camera_matrix").mat(), K)
    np.testing.assert_array_equal(fs.getNode("distortion_coefficients").mat().ravel(), dist.ravel())
    assert (int(fs.getNode("image_width").real()), int(fs.getNode("image_height").real())) == (1280, 720)
    fs.release()


def test_calibration_fixtures():
    dalsa = Camera.from_opencv_file(DATA / "dalsa_calib_opencv.yaml")
    ref = Camera.preset("dalsa-cad1-128a")
    np.testing.assert_array_equal(dalsa.K, ref.K)
    np.testing.assert_array_equal(dalsa.dist_coeffs, ref.dist_coeffs)
    ros = Camera.from_opencv_file(DATA / "ros_calib_camera_info.yaml")
    assert (ros.fx, ros.fy, ros.cx, ros.cy, ros.width, ros.height) == (615.2, 614.8, 321.5, 238.2, 640, 480)
    assert ros.dist == (0.101, -0.2, 0.001, -0.002, 0.05)
    plain = Camera.from_opencv_file(DATA / "plain_calib.json")
    assert (plain.fx, plain.cx, plain.cy, plain.width, plain.height) == (1666.67, 640.0, 512.0, 1280, 1024)
    assert plain.dist == (0.0,) * 5
    via_dict = build_camera({"focal_length_mm": 3.5, "focus_distance_mm": 45.0},
                            calibration=DATA / "dalsa_calib_opencv.yaml")
    assert via_dict.focal_length_mm == 3.5 and via_dict.fx == ref.fx


@pytest.mark.parametrize("content, suffix, fragment", [
    ('{"D": [0, 0, 0, 0], "image_size": [640, 480]}', "json", "needs a 3x3 camera matrix"),
    ('{"K": [[1, 0, 1], [0, 1]], "image_size": [4, 4]}', "json", "K: not a numeric matrix"),
    ('{"K": [[500, 0, 320], [0, 500, 240], [0, 0, 1]], "D": [1, 2, 3], "image_size": [640, 480]}', "json",
     "4 or 5 values"),
    ('{"K": [[500, 0, 320], [0, 500, 240], [0, 0, 1]]}', "json", "needs image_width and image_height"),
    ('{"K": [[500, 0, 320], [0, 500, 240], [0, 0, 1]], "image_size": [640, 480], "f_number": -2.8}', "json",
     "f_number: not a positive number"),
    ('{"K": [[500, 0, 320], [0, 500, 240], [0, 0, 1]], "image_size": [640, 480], "focus_distance_mm": "far"}',
     "json", "focus_distance_mm: not a positive number"),
    ("this is : not : yaml : [", "yaml", "not a readable OpenCV FileStorage file"),
])
def test_bad_calibration_files(tmp_path, content, suffix, fragment):
    path = tmp_path / f"bad.{suffix}"
    path.write_text(content)
    with pytest.raises(CameraError, match=fragment) as info:
        Camera.from_opencv_file(path)
    assert str(path) in str(info.value)


def test_missing_calibration_file(tmp_path):
    with pytest.raises(CameraError, match="calibration file not found"):
        Camera.from_opencv_file(tmp_path / "nope.yaml")


# ---------------------------------------------------------------------- presets, dict form, bad input
@pytest.mark.parametrize("name", sorted(PRESETS))
def test_presets_build_and_round_trip_through_dict(name):
    cam = Camera.preset(name)
    assert cam.name == name and cam.source
    assert cam.aperture_mm == pytest.approx(cam.focal_length_mm / cam.f_number)
    again = build_camera(json.loads(json.dumps(cam.to_dict())))
    assert again == cam
    assert build_camera({"focus_distance_mm": 123.0}, preset=name).focus_distance_mm == 123.0


@pytest.mark.parametrize("kwargs, fragment", [
    (dict(fx=-5.0), "fx must be a positive number"),
    (dict(fy=float("nan")), "fy must be a finite number"),
    (dict(fx="800"), "fx must be a finite number"),
    (dict(width=640.5), "width must be a positive integer"),
    (dict(height=True), "height must be a positive integer"),
    (dict(cx=700.0), r"principal point \(cx, cy\)"),
    (dict(dist=(0.1, 0.2, 0.3)), "dist must be 4 or 5 finite numbers"),
    (dict(dist=(0.1, "x", 0.0, 0.0)), "dist must be 4 or 5 finite numbers"),
    (dict(f_number=0.0), "f_number must be a positive number"),
    (dict(f_number=4.0, aperture_mm=1.0), "not both inconsistent"),
    (dict(blur_circle_mm=-0.01), "blur_circle_mm must be a positive number"),
    (dict(focus_distance_mm=5.0), "must exceed focal_length_mm"),
])
def test_bad_camera_fields(kwargs, fragment):
    base = dict(fx=800.0, fy=800.0, cx=320.0, cy=240.0, width=640, height=480, focal_length_mm=8.0)
    with pytest.raises(CameraError, match=fragment):
        Camera(**{**base, **kwargs})


def test_bad_camera_tables_name_key_and_allowed():
    """A ``[camera]`` table (``CameraSettings``): one line naming the dotted key and what is allowed; Camera's own
    checks keep their wording."""
    cases = [
        ({"preset": "dalsa-cad1-128a", "fxx": 1.0}, r"camera.fxx: unknown key; allowed: keys of \[camera\]: .*fx"),
        ({"preset": "nikon"}, "camera.preset: 'nikon' is not allowed; allowed: basler"),
        ({"preset": "dalsa-cad1-128a", "focal_length_mm": "3.5"}, "camera.focal_length_mm: '3.5' is not allowed"),
        ({"fx": 500.0}, "camera.fy: missing; allowed: .*fx, fy, cx, cy, width, height"),
        ({"preset": "dalsa-cad1-128a", "cx": 700.0}, r"camera.cx: camera 'dalsa-cad1-128a': principal point"),
    ]
    for table, fragment in cases:
        with pytest.raises(StudyError, match=fragment) as info:
            validate_section(CameraSettings, table, "camera", "study.toml")
        assert str(info.value).startswith("study.toml: camera.") and "\n" not in str(info.value)
