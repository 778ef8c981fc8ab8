"""SE(3) helpers against independent references: scipy.linalg.expm/logm of the 4x4 twist matrix, scipy
Rotation, numpy matrix inverse, cv2.projectPoints with the extrinsics, finite differences."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm, logm
from scipy.spatial.transform import Rotation

from cadfeat.camera import Camera
from cadfeat.errors import CadfeatError
from cadfeat.poses import (
    hat,
    invert_T,
    look_at,
    look_at_screws,
    make_T,
    points_in_frames,
    rotate_vectors,
    se3_exp,
    se3_log,
    transform_points,
    twist_between,
)

pytestmark = pytest.mark.numerics  # run again under another BLAS kernel (Makefile: test)

RNG = np.random.default_rng(7)


def _random_T(n: int) -> np.ndarray:
    return make_T(Rotation.random(n, rng=RNG).as_matrix(), RNG.uniform(-500, 500, (n, 3)))


def _twist_matrix(xi: np.ndarray) -> np.ndarray:
    """The se(3) matrix [[ω]×, v; 0, 0] — built by hand, for expm/logm."""
    M = np.zeros((4, 4))
    M[:3, :3] = hat(xi[3:])
    M[:3, 3] = xi[:3]
    return M


finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
vec3 = st.tuples(finite, finite, finite).map(np.array)
unit = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).map(np.array).filter(
    lambda a: np.linalg.norm(a) > 1e-3).map(lambda a: a / np.linalg.norm(a))
angle = st.one_of(
    st.floats(0.0, 1e-12),                        # zero and far below cv2.Rodrigues's cut-off
    st.floats(1e-12, 1e-4),                       # tiny: Taylor branch
    st.floats(1e-4, np.pi - 1e-3),                # general
    st.floats(1e-9, 1e-3).map(lambda e: np.pi - e),  # near π
)


# ---------------------------------------------------------------------- homogeneous transforms
def test_make_invert_transform_points_against_numpy():
    T = _random_T(20)
    np.testing.assert_allclose(invert_T(T), np.linalg.inv(T), atol=1e-10)
    np.testing.assert_allclose(T @ invert_T(T), np.broadcast_to(np.eye(4), T.shape), atol=1e-12)
    p = RNG.uniform(-100, 100, (20, 3))
    homogeneous = np.einsum("lij,lj->li", T, np.concatenate([p, np.ones((20, 1))], axis=1))[:, :3]
    np.testing.assert_allclose(transform_points(T, p), homogeneous, atol=1e-10)
    np.testing.assert_allclose(rotate_vectors(T, p), np.einsum("lij,lj->li", T[:, :3, :3], p), atol=1e-12)
    np.testing.assert_allclose(rotate_vectors(T[:, :3, :3], p), rotate_vectors(T, p))


def test_points_in_frames_shapes_and_values():
    T = _random_T(5)
    p = RNG.uniform(-50, 50, (7, 3))
    out = points_in_frames(T, p)
    assert out.shape == (5, 7, 3)
    for k in (0, 4):
        for j in (0, 6):
            np.testing.assert_allclose(out[k, j], (T[k] @ np.append(p[j], 1.0))[:3], atol=1e-10)
    assert points_in_frames(T.reshape(5, 1, 4, 4), p.reshape(7, 1, 3)).shape == (5, 1, 7, 1, 3)
    assert points_in_frames(T[0], p).shape == (7, 3)


def test_points_in_camera_frames_project_like_cv2_with_extrinsics():
    """Project task points through T_cam_task = invert_T(T_task_cam) and Camera.project; OpenCV gets the
    same extrinsics as (rvec, tvec)."""
    cam = Camera.preset("dalsa-cad1-128a")
    eyes = RNG.uniform(-30, 30, (6, 3)) + [0, 0, 45]
    T_task_cam = look_at(eyes, RNG.uniform(-3, 3, (6, 3)))
    pts = RNG.uniform(-4, 4, (9, 3))
    uv = cam.project(points_in_frames(invert_T(T_task_cam), pts))
    for k in range(6):
        T_cam_task = np.linalg.inv(T_task_cam[k])
        rvec = Rotation.from_matrix(T_cam_task[:3, :3]).as_rotvec()
        ref, _ = cv2.projectPoints(pts, rvec, T_cam_task[:3, 3], cam.K, cam.dist_coeffs)
        np.testing.assert_allclose(uv[k], ref[:, 0], atol=1e-8)


# ---------------------------------------------------------------------- exponential / logarithm
@settings(max_examples=150, deadline=None)
@given(v=vec3, axis=unit, theta=angle)
def test_exp_matches_expm_and_log_inverts_it(v, axis, theta):
    xi = np.concatenate([v, axis * theta])
    T = se3_exp(xi)
    np.testing.assert_allclose(T, expm(_twist_matrix(xi)), rtol=0, atol=1e-9 * (1 + np.linalg.norm(v)))
    np.testing.assert_allclose(T[:3, :3], Rotation.from_rotvec(axis * theta).as_matrix(), atol=1e-14)
    back = se3_log(T)
    np.testing.assert_allclose(back, xi, rtol=0, atol=1e-8 * (1 + np.linalg.norm(v)))


@settings(max_examples=100, deadline=None)
@given(v=vec3, axis=unit, theta=angle)
def test_log_then_exp_is_identity_on_transforms(v, axis, theta):
    T = make_T(Rotation.from_rotvec(axis * theta).as_matrix(), v)
    np.testing.assert_allclose(se3_exp(se3_log(T)), T, rtol=0, atol=1e-9 * (1 + np.linalg.norm(v)))


def test_log_matches_logm_and_is_batched():
    xi = np.concatenate([RNG.uniform(-100, 100, (30, 3)), Rotation.random(30, rng=RNG).as_rotvec() * 0.9], 1)
    T = se3_exp(xi)
    ref = np.array([logm(t).real for t in T])
    ref_xi = np.concatenate([ref[:, :3, 3], ref[:, [2, 0, 1], [1, 2, 0]]], axis=1)
    np.testing.assert_allclose(se3_log(T), ref_xi, atol=1e-8)
    assert se3_exp(xi.reshape(5, 6, 6)).shape == (5, 6, 4, 4)
    assert se3_log(T.reshape(3, 10, 4, 4)).shape == (3, 10, 6)


def test_tiny_rotations_are_not_zeroed():
    """cv2.Rodrigues drops rotations below ~1e-5 rad (docs/design.md "Known pitfalls"); the exponential keeps them."""
    xi = np.array([0.3, -0.2, 0.1, 3e-9, -1e-8, 2e-9])
    T = se3_exp(xi)
    np.testing.assert_allclose(T, expm(_twist_matrix(xi)), atol=1e-15)
    np.testing.assert_allclose(se3_log(T)[3:], xi[3:], rtol=1e-6)


def test_bad_shapes():
    with pytest.raises(CadfeatError, match="shape"):
        se3_exp(np.zeros(5))
    with pytest.raises(CadfeatError, match="shape"):
        se3_log(np.eye(3))


def test_twist_between():
    Ta, Tb = _random_T(10), _random_T(10)
    xi = twist_between(Ta, Tb)
    np.testing.assert_allclose(Ta @ se3_exp(xi), Tb, atol=1e-9)
    # body twist: a motion expressed in frame a (moving 5 mm along a's own x axis)
    step = make_T(np.eye(3), [5.0, 0.0, 0.0])
    np.testing.assert_allclose(twist_between(Ta, Ta @ step), np.tile([5.0, 0, 0, 0, 0, 0], (10, 1)), atol=1e-10)


# ---------------------------------------------------------------------- look-at
@settings(max_examples=100, deadline=None)
@given(eye=vec3, offset=vec3, up=vec3)
def test_look_at_aims_at_target_with_up_upwards(eye, offset, up):
    if np.linalg.norm(offset) < 1.0 or np.linalg.norm(up) < 1e-3:
        return
    target = eye + offset
    cam = Camera.preset("basler-aca1300-200um-8mm")
    T = look_at(eye, target, up)
    R = T[:3, :3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    T_cam_task = invert_T(T)
    np.testing.assert_allclose(cam.project(transform_points(T_cam_task, target)), [cam.cx, cam.cy], atol=1e-6)
    # world up is image up: a point displaced along the part of `up` across the view goes to smaller v
    z = offset / np.linalg.norm(offset)
    up_perp = up - z * (z @ up)
    if np.linalg.norm(up_perp) > 1e-3 * np.linalg.norm(up):
        probe = target + 0.01 * np.linalg.norm(offset) * up_perp / np.linalg.norm(up_perp)
        u, v = cam.project(transform_points(T_cam_task, probe))
        assert u == pytest.approx(cam.cx, abs=1e-6 * cam.fx)
        assert v < cam.cy - 1.0


def test_look_at_batched_and_fallback_when_up_is_parallel():
    eyes = np.array([[0.0, 0.0, 200.0], [0.0, 0.0, -200.0], [0.0, 150.0, 0.0]])
    T = look_at(eyes, [0.0, 0.0, 0.0], up=[[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
    for k in range(3):
        R = T[k, :3, :3]
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(R[:, 2], -eyes[k] / np.linalg.norm(eyes[k]), atol=1e-12)
    # looking straight down with up = +z: task +y becomes image up (camera y = task −y)
    np.testing.assert_allclose(T[0, :3, 1], [0.0, -1.0, 0.0], atol=1e-12)
    # looking along −y with up = +y: +y is parallel too, so task +x is image up
    np.testing.assert_allclose(T[2, :3, 1], [-1.0, 0.0, 0.0], atol=1e-12)


def test_look_at_errors():
    with pytest.raises(CadfeatError, match="eye and target"):
        look_at([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])
    with pytest.raises(CadfeatError, match="up"):
        look_at([0.0, 0.0, 1.0], [1.0, 0.0, 0.0], up=[0.0, 0.0, 0.0])


def test_look_at_screws_match_finite_differences():
    """Analytic look-at screws vs central differences of look_at poses (twist_between / 2h)."""
    t = np.linspace(0.0, 2.0, 15)
    eye = lambda s: np.stack([300 * np.cos(s), 200 * np.sin(1.3 * s), 150 + 40 * s], -1)  # noqa: E731
    eye_dot = lambda s: np.stack([-300 * np.sin(s), 260 * np.cos(1.3 * s), 40 + 0 * s], -1)  # noqa: E731
    target = lambda s: np.stack([10 * s, -5 * s * s, 0 * s], -1)  # noqa: E731
    target_dot = lambda s: np.stack([10 + 0 * s, -10 * s, 0 * s], -1)  # noqa: E731
    up = np.array([0.1, 0.2, 1.0])
    h = 1e-5
    fd = twist_between(look_at(eye(t - h), target(t - h), up), look_at(eye(t + h), target(t + h), up)) / (2 * h)
    # log(T(t−h)⁻¹ T(t+h)) / 2h is the body twist at t up to O(h²) (Magnus expansion)
    screws = look_at_screws(eye(t), target(t), eye_dot(t), target_dot(t), up)
    np.testing.assert_allclose(screws, fd, rtol=1e-5, atol=1e-4)


def test_cam_from_part_is_the_camera_frame_of_the_part_and_is_the_only_one():
    """``poses.cam_from_part`` maps part points into the camera frame (against ``np.linalg.inv``), and no module
    of the package writes ``inv(T_task_cam) @ T_task_part`` again (docs/design.md "Conventions": the cell's frames
    declared once)."""
    import re
    from pathlib import Path

    from cadfeat.poses import cam_from_part, look_at

    T_task_cam = np.stack([look_at([100.0, -50.0, 300.0 + k], [0.0, 0.0, 0.0]) for k in range(3)])
    T_task_part = look_at([5.0, 2.0, -3.0], [10.0, 0.0, 50.0])
    p = np.array([3.0, -4.0, 5.0, 1.0])
    expected = np.linalg.inv(T_task_cam) @ (T_task_part @ p)
    np.testing.assert_allclose(cam_from_part(T_task_cam, T_task_part) @ p, expected, atol=1e-9)
    root = Path(__file__).resolve().parent.parent / "cadfeat"
    again = [str(f) for f in root.rglob("*.py") if f.name != "poses.py"
             and re.search(r"(inv|invert_T)\([^()]*T_task_cam[^()]*\)\)? @ [\w.]*T_task_part", f.read_text())]
    assert not again, f"inv(T_task_cam) @ T_task_part written again in {again}: use poses.cam_from_part"
