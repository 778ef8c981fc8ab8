"""The filters' measurement model against independent references.

- the ellipse centre of a rim equals ``cv2.fitEllipse`` of densely ``cv2.projectPoints``-projected rim points
  (pinhole: the exact image conic) and ``measures.hole_ellipse`` (a different conic formulation);
- it is NOT the projected centre (the offset the model exists for);
- its analytic Jacobian equals central finite differences, and becomes ``image_jacobian`` as R → 0;
- the pose Jacobian of ``measure`` equals finite differences of the left pose perturbation.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from cadfeat.camera import Camera
from cadfeat.measures import hole_ellipse, image_jacobian
from cadfeat.measures.rim_centre import measure, rim_centre_jacobian, rim_centre_px
from cadfeat.poses import make_T, se3_exp
from cadfeat.vision.motion import so3_exp

pytestmark = pytest.mark.numerics  # run again under another BLAS kernel (Makefile: test)

PINHOLE = Camera(fx=800.0, fy=780.0, cx=320.0, cy=240.0, width=640, height=480)
DISTORTED = PINHOLE.replace(dist=(-0.21, 0.08, 0.001, -0.002, 0.01))


def _holes(n=6, seed=0):
    rng = np.random.default_rng(seed)
    c = rng.normal(size=(n, 3)) * [40.0, 30.0, 10.0] + [0.0, 0.0, 250.0]
    nrm = rng.normal(size=(n, 3)) * 0.6
    nrm[:, 2] = -1.0
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return c, nrm, rng.uniform(3.0, 12.0, n)


def test_rim_centre_matches_fitted_projected_rim_and_hole_ellipse():
    c, n, R = _holes()
    got = rim_centre_px(PINHOLE, c, n, R)
    for j in range(len(c)):
        u = np.cross(n[j], [1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(n[j], u)
        phi = np.linspace(0, 2 * np.pi, 20000, endpoint=False)
        rim = c[j] + R[j] * (np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * v)
        px, _ = cv2.projectPoints(rim, np.zeros(3), np.zeros(3), PINHOLE.K, PINHOLE.dist_coeffs)
        (cx, cy), _, _ = cv2.fitEllipse(px.reshape(-1, 2).astype(np.float32))
        assert np.hypot(cx - got[j, 0], cy - got[j, 1]) < 2e-3
    for cam in (PINHOLE, DISTORTED):
        np.testing.assert_allclose(rim_centre_px(cam, c, n, R), hole_ellipse(cam, c, n, R).centre_px, atol=1e-9)
    offset = np.linalg.norm(got - PINHOLE.project(c), axis=1)
    assert offset.max() > 0.05  # the ellipse centre is not the image of the centre


@pytest.mark.parametrize("camera", [PINHOLE, DISTORTED], ids=["pinhole", "distorted"])
def test_rim_centre_jacobian_matches_finite_differences(camera):
    c, n, R = _holes(seed=1)
    J = rim_centre_jacobian(camera, c, n, R)
    h = 1e-6
    Jn = np.zeros_like(J)
    for j in range(6):
        moved = []
        for sign in (1.0, -1.0):
            g = np.zeros(6)
            g[j] = sign * h
            T = np.linalg.inv(se3_exp(g))  # the camera moves by the screw g: part points map by its inverse
            moved.append(rim_centre_px(camera, c @ T[:3, :3].T + T[:3, 3], n @ T[:3, :3].T, R))
        Jn[..., j] = (moved[0] - moved[1]) / (2 * h)
    np.testing.assert_allclose(J, Jn, rtol=1e-5, atol=1e-4 * np.abs(J).max())


def test_rim_centre_jacobian_tends_to_point_jacobian():
    c, n, _ = _holes(seed=2)
    for cam in (PINHOLE, DISTORTED):
        np.testing.assert_allclose(rim_centre_jacobian(cam, c, n, 1e-4), image_jacobian(cam, c), rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(rim_centre_jacobian(cam, c, n, 0.0), image_jacobian(cam, c))


def test_measure_pose_jacobian_matches_left_perturbation():
    c, n, R = _holes(seed=3)
    T = make_T(so3_exp(np.array([2.5, -0.4, 0.7])), [10.0, -20.0, 260.0])  # a large attitude: no gimbal issues
    X = (c - T[:3, 3]) @ T[:3, :3]
    N = n @ T[:3, :3]
    _, H = measure(DISTORTED, T, X, N, R)
    h = 1e-6
    for j in range(6):
        zs = []
        for sign in (1.0, -1.0):
            d = np.zeros(6)
            d[j] = sign * h
            Tp = make_T(so3_exp(d[3:]) @ T[:3, :3], T[:3, 3] + d[:3])
            zs.append(measure(DISTORTED, Tp, X, N, R, jacobian=False)[0])
        np.testing.assert_allclose(H[..., j], (zs[0] - zs[1]) / (2 * h), rtol=1e-5, atol=1e-3)
