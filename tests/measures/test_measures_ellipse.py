"""hole_ellipse / sphere ellipse / resolution against cv2.fitEllipse of densely projected rim points
(cv2.projectPoints), with and without lens distortion, tilts 0–70°."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cadfeat import measures
from cadfeat.camera import Camera

pytestmark = pytest.mark.numerics  # run again under another BLAS kernel (Makefile: test)

RNG = np.random.default_rng(1905)
CAM = Camera(fx=812.3, fy=809.1, cx=331.0, cy=247.5, width=640, height=480)
DIST = (-0.21, 0.08, 0.0013, -0.0021, -0.012)


def _rim_points(centre, normal, radius, n=2000):
    normal = normal / np.linalg.norm(normal)
    u = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return centre + radius * (np.cos(t)[:, None] * u + np.sin(t)[:, None] * v)


def _fit(camera, pts):
    uv, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), camera.K, camera.dist_coeffs)
    (cu, cv_), (w, h), ang = cv2.fitEllipse(uv.reshape(-1, 2).astype(np.float32))
    major_angle = np.deg2rad(ang if w >= h else ang + 90.0)
    return np.array([cu, cv_]), np.array([max(w, h), min(w, h)]), major_angle


def _angle_diff(a, b):
    d = np.mod(a - b + np.pi / 2, np.pi) - np.pi / 2
    return abs(d)


def _case(tilt_deg):
    """A hole somewhere in view, its normal tilted by tilt_deg from the direction to the camera."""
    centre = np.array([RNG.uniform(-60, 60), RNG.uniform(-40, 40), RNG.uniform(250, 450)])
    to_cam = -centre / np.linalg.norm(centre)
    axis = np.cross(to_cam, RNG.normal(size=3))
    axis /= np.linalg.norm(axis)
    normal = Rotation.from_rotvec(np.deg2rad(tilt_deg) * axis).apply(to_cam)
    return centre, normal, RNG.uniform(4.0, 12.0)


@pytest.mark.parametrize("tilt", [0.0, 15.0, 30.0, 45.0, 60.0, 70.0])
def test_hole_ellipse_matches_fitEllipse_without_distortion(tilt):
    for _ in range(3):
        centre, normal, radius = _case(tilt)
        e = measures.hole_ellipse(CAM, centre, normal, radius)
        c_ref, axes_ref, ang_ref = _fit(CAM, _rim_points(centre, normal, radius))
        assert e.valid
        np.testing.assert_allclose(e.axes_px, axes_ref, atol=0.05)
        np.testing.assert_allclose(e.centre_px, c_ref, atol=0.05)
        if axes_ref[0] - axes_ref[1] > 0.5:
            assert _angle_diff(e.angle_rad, ang_ref) < 1e-3


@pytest.mark.parametrize("tilt", [0.0, 35.0, 70.0])
def test_hole_ellipse_with_distortion_local_affine(tilt):
    """Distorted rims are not ellipses; the local-affine map stays within 1 % / 0.3 px of the fitted ellipse."""
    cam = CAM.replace(dist=DIST)
    for _ in range(3):
        centre, normal, radius = _case(tilt)
        e = measures.hole_ellipse(cam, centre, normal, radius)
        c_ref, axes_ref, ang_ref = _fit(cam, _rim_points(centre, normal, radius))
        np.testing.assert_allclose(e.axes_px, axes_ref, rtol=0.01, atol=0.05)
        np.testing.assert_allclose(e.centre_px, c_ref, atol=0.3)


def test_batched_shapes_and_rotation_about_own_axis():
    centres = np.stack([_case(40.0)[0] for _ in range(6)]).reshape(2, 3, 3)
    normals = RNG.normal(size=(2, 3, 3)) - centres / np.linalg.norm(centres, axis=-1, keepdims=True) * 3
    e = measures.hole_ellipse(CAM, centres, normals, 5.0)
    assert e.centre_px.shape == (2, 3, 2) and e.axes_px.shape == (2, 3, 2) and e.angle_rad.shape == (2, 3)
    assert np.all(e.axes_px[..., 0] >= e.axes_px[..., 1])


def test_behind_camera_is_invalid_and_finite():
    c = np.array([[0.0, 0.0, -100.0], [0.0, 0.0, 2.0], [10.0, 0.0, 300.0]])
    n = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    e = measures.hole_ellipse(CAM, c, n, 5.0)  # 2nd: rim crosses the camera plane
    assert e.valid.tolist() == [False, False, True]
    assert np.all(np.isfinite(e.centre_px)) and np.all(e.axes_px[:2] == 0)
    m = measures.resolution_margin_px(CAM, c, n, 5.0, min_axis_px=5.0)
    assert m[0] < -100 and m[1] < -100 and m[2] > 0


def test_sphere_ellipse_matches_fitted_outline():
    """The thesis's sphere (eq. 3.13–3.17): its outline is the projection of the tangent circle."""
    for _ in range(4):
        c = np.array([RNG.uniform(-80, 80), RNG.uniform(-60, 60), RNG.uniform(200, 400)])
        R = RNG.uniform(5, 15)
        d = np.linalg.norm(c)
        # tangent circle: centre c (1 − R²/d²), radius R √(1 − R²/d²), normal along c
        circle_c = c * (1 - R**2 / d**2)
        circle_r = R * np.sqrt(1 - R**2 / d**2)
        e = measures.sphere_ellipse(CAM, c, R)
        c_ref, axes_ref, _ = _fit(CAM, _rim_points(circle_c, c, circle_r))
        np.testing.assert_allclose(e.axes_px, axes_ref, atol=0.05)
        np.testing.assert_allclose(e.centre_px, c_ref, atol=0.05)
        assert measures.resolution_margin_sphere(CAM, c, None, R, 3.0) == pytest.approx(e.axes_px[1] - 3.0)


def test_thesis_sphere_eigenvalues_eq_3_18():
    """eq. 3.18 coefficients: x² term (Y²+Z²−R²)/f², xy term −2XY/f² → C_T = [[Y²+Z²−R², −XY], [−XY, X²+Z²−R²]]/f²."""
    cam = Camera(fx=500.0, fy=500.0, cx=320.0, cy=240.0, width=640, height=480)
    X, Y, Z, R = 10.0, -20.0, 300.0, 4.0
    CT = np.array([[Y**2 + Z**2 - R**2, -X * Y], [-X * Y, X**2 + Z**2 - R**2]]) / 500.0**2
    got = measures.resolution_margin_sphere(cam, np.array([X, Y, Z]), None, R, 0.0, thesis_eigenvalues=True)
    assert got == pytest.approx(np.linalg.eigvalsh(CT)[0])


def test_line_segment_eq_3_7_is_image_length():
    cam = Camera(fx=700.0, fy=700.0, cx=320.0, cy=240.0, width=640, height=480)
    A = np.array([[10.0, 5.0, 300.0], [-40.0, 20.0, 250.0]])
    B = np.array([[30.0, -5.0, 320.0], [-40.0, 60.0, 400.0]])
    length = np.linalg.norm(cam.project(A) - cam.project(B), axis=-1)
    np.testing.assert_allclose(measures.line_segment_margin_px(cam, A, B, 4.0), length - 4.0, rtol=1e-10)
