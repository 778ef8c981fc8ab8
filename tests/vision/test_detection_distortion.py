"""The detector's rim centre through a strongly distorting lens (the thesis camera, k1 = −1.45).

Reference, independent of cadfeat's ellipse code: dense rim points projected with ``cv2.projectPoints`` (with
the lens distortion) are drawn, anti-aliased, into a grey image; the expected measurement is the pinhole
ellipse's centre (``cv2.fitEllipse`` of the same rim projected *without* distortion), pushed through the
distortion by ``cv2.projectPoints`` of a point on its ray. The detector given the camera must find that centre;
fitting the ellipse in the distorted image (no camera) is off by the second-order distortion term."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from cadfeat.camera import Camera
from cadfeat.vision.detection import detect_holes

SUPER = 8


def _rim(centre_mm: np.ndarray, normal: np.ndarray, radius_mm: float, n: int = 2000) -> np.ndarray:
    u = np.cross(normal, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return centre_mm + radius_mm * (np.cos(t)[:, None] * u + np.sin(t)[:, None] * v)


def _project(cam: Camera, pts: np.ndarray, dist: np.ndarray) -> np.ndarray:
    z = np.zeros(3)
    return cv2.projectPoints(pts.reshape(-1, 1, 3), z, z, cam.K, dist)[0].reshape(-1, 2)


def _image(cam: Camera, rim_px: np.ndarray) -> np.ndarray:
    canvas = np.full((cam.height * SUPER, cam.width * SUPER), 200, np.uint8)
    poly = np.round((rim_px + 0.5) * SUPER - 0.5).astype(np.int32)     # pixel centres at integer coordinates
    cv2.fillPoly(canvas, [poly], 30)
    return cv2.resize(canvas, (cam.width, cam.height), interpolation=cv2.INTER_AREA)


@pytest.mark.parametrize("centre", [(-12.0, -9.0, 60.0), (10.0, 6.0, 55.0)])
def test_rim_centre_through_a_distorting_lens(centre: tuple[float, float, float]) -> None:
    cam = Camera.preset("dalsa-cad1-128a")
    c = np.array(centre)
    normal = np.array([0.15, -0.1, -1.0])
    normal /= np.linalg.norm(normal)
    rim = _rim(c, normal, 2.5)
    img = _image(cam, _project(cam, rim, cam.dist_coeffs))
    (x0, y0), _, _ = cv2.fitEllipse(_project(cam, rim, np.zeros(5)).astype(np.float32))
    ray = np.array([(x0 - cam.cx) / cam.fx, (y0 - cam.cy) / cam.fy, 1.0])
    expected = _project(cam, ray[None] * 50.0, cam.dist_coeffs)[0]

    fixed = detect_holes(img, camera=cam, smooth_sigma_px=0.0)
    plain = detect_holes(img, smooth_sigma_px=0.0)
    assert len(fixed.centre_px) == 1 and len(plain.centre_px) == 1
    err_fixed = np.linalg.norm(fixed.centre_px[0] - expected)
    err_plain = np.linalg.norm(plain.centre_px[0] - expected)
    assert err_fixed < 0.05, (err_fixed, err_plain)
    assert err_plain > 3 * err_fixed and err_plain > 0.1          # what the fix removes
    # a region of interest: the same centre in full-frame pixels
    u0, v0 = (int(v) - 20 for v in fixed.centre_px[0])
    roi = detect_holes(img[v0:, u0:], camera=cam, origin_px=(u0, v0), smooth_sigma_px=0.0)
    np.testing.assert_allclose(roi.centre_px[0] + (u0, v0), fixed.centre_px[0], atol=1e-6)
