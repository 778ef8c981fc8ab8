"""Area-integrating renders (``CameraViewRenderer(..., supersample=k)``) against the exact pixel coverage.

Independent reference: a flat regular 48-gon (its exact vertices, no CAD tessellation) seen square-on, its
vertices projected by ``Camera.project``: its exact image area and centroid (shoelace formulas), and each
pixel's covered fraction from ``cv2.fillPoly`` on a 32× finer grid (box-averaged back, ``cv2.resize``
INTER_AREA; within ~0.01 px of the exact edge), independent of VTK. The
render's coverage is its grey level over the lit face's (the background is black). A sensor integrates over
each pixel: the supersampled render must give each edge pixel its covered fraction, keep the polygon's area
(no edge bias, unlike MSAA's resolve) and its centroid; the point-sampled render (k = 1) must not (so the test
tells the two apart).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

pv = pytest.importorskip("pyvista")

from cadfeat.camera import Camera  # noqa: E402
from cadfeat.poses import invert_T, look_at  # noqa: E402
from cadfeat.render.camera_views import CameraViewRenderer, supersampled  # noqa: E402
from cadfeat.render.scene import RenderError  # noqa: E402
from cadfeat.vision.images import grey  # noqa: E402

CAMERA = Camera(fx=600.0, fy=600.0, cx=47.37, cy=39.81, width=96, height=80, focus_distance_mm=100.0)
SIDES = 48
RADIUS_MM = 2.5          # 15 px at 100 mm
REF = 32                 # reference sub-pixels per pixel side


def _polygon(offset_mm: tuple[float, float]) -> np.ndarray:
    phi = np.linspace(0.0, 2.0 * np.pi, SIDES, endpoint=False) + 0.1
    return np.stack([RADIUS_MM * np.cos(phi) + offset_mm[0], RADIUS_MM * np.sin(phi) + offset_mm[1],
                     np.zeros(SIDES)], axis=-1)


def _mesh(vertices: np.ndarray):
    centre = vertices.mean(axis=0)
    pts = np.vstack([centre, vertices])
    tri = [(3, 0, 1 + i, 1 + (i + 1) % SIDES) for i in range(SIDES)]   # a fan, facing +z (towards the camera)
    return pv.PolyData(pts, np.array(tri).ravel())


def _pose() -> np.ndarray:
    return invert_T(look_at(np.array([0.0, 0.0, 100.0]), np.zeros(3), up=(0.0, 1.0, 0.0)))


def _image_polygon(vertices: np.ndarray, T: np.ndarray) -> np.ndarray:
    return CAMERA.project(vertices @ T[:3, :3].T + T[:3, 3])


def _exact_coverage(vertices: np.ndarray, T: np.ndarray) -> np.ndarray:
    px = _image_polygon(vertices, T)
    shift = 4
    fine = np.round((REF * (px + 0.5) - 0.5) * (1 << shift)).astype(np.int32)   # sub-pixel centres at integers
    mask = np.zeros((CAMERA.height * REF, CAMERA.width * REF), np.float32)
    cv2.fillPoly(mask, [fine], 1.0, lineType=cv2.LINE_8, shift=shift)
    return cv2.resize(mask, (CAMERA.width, CAMERA.height), interpolation=cv2.INTER_AREA)


def _coverage(k: int, vertices: np.ndarray, T: np.ndarray) -> np.ndarray:
    with CameraViewRenderer(None, [], CAMERA, mesh=_mesh(vertices), supersample=k) as renderer:
        image = grey(renderer.render(T))
    face = np.median(image[image > 0.5 * image.max()])
    return image / face


def _area_centroid(px: np.ndarray) -> tuple[float, np.ndarray]:
    """Exact area (px²) and centroid (px) of the image polygon (shoelace formulas)."""
    x, y = px[:, 0], px[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    area = 0.5 * cross.sum()
    return abs(area), np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6.0 * area)


def _stats(cov: np.ndarray, exact: np.ndarray, px: np.ndarray) -> tuple[float, float, float]:
    """RMS coverage error over the edge pixels, the area error as a mean edge shift (px, + outwards) and the
    centroid's error (px)."""
    edge = (exact > 0.0) & (exact < 1.0)
    rms = float(np.sqrt(np.mean((cov - exact)[edge] ** 2)))
    area, centre = _area_centroid(px)
    perimeter = float(np.sum(np.linalg.norm(px - np.roll(px, -1, axis=0), axis=-1)))
    v, u = np.mgrid[0:CAMERA.height, 0:CAMERA.width]
    centroid = np.array([(cov * u).sum(), (cov * v).sum()]) / cov.sum()
    return rms, float((cov.sum() - area) / perimeter), float(np.linalg.norm(centroid - centre))


@pytest.mark.parametrize("offset_mm", [(0.0, 0.0), (0.137, -0.061)])
def test_supersampled_render_integrates_each_pixel(offset_mm):
    vertices = _polygon(offset_mm)
    T = _pose()
    exact, px = _exact_coverage(vertices, T), _image_polygon(vertices, T)
    assert exact.sum() > 600.0                                      # the 15 px disc is in the image
    rms1, shift1, _ = _stats(_coverage(1, vertices, T), exact, px)
    rms2, shift2, cen2 = _stats(_coverage(2, vertices, T), exact, px)
    rms4, shift4, cen4 = _stats(_coverage(4, vertices, T), exact, px)
    # point sampling: each edge pixel is 0 or 1 (RMS error ≈ 0.25 of full coverage); the box mean of k² samples
    # gives the covered fraction to ~1/k² (measured: k = 1 0.24–0.26, k = 2 0.09, k = 4 0.03)
    assert rms1 > 0.2
    assert rms2 < 0.13 and rms4 < 0.05 and rms4 < rms1 / 5
    # no edge bias (MSAA's resolve moved edges ~¼ px; measured |shift| ≤ 0.006 px at k = 2, 0.002 at k = 4) and
    # the centroid kept (a principal point off by half a sub-pixel would move it by 1/(2k) px; measured 0.017–0.023
    # px at k = 2, 0.002–0.004 at k = 4, 0.04–0.07 point-sampled)
    assert abs(shift2) < 0.015 and abs(shift4) < 0.005
    assert cen2 < 0.04 and cen4 < 0.01


def test_supersampled_camera_maps_pixel_blocks():
    """Pixel u's k sub-pixel centres u − ½ + (i + ½)/k map to the integers k·u + i (x' = k(x + ½) − ½)."""
    for k in (2, 3):
        cam = supersampled(CAMERA, k)
        u = 7.0 - 0.5 + (np.arange(k) + 0.5) / k
        X = np.stack([(u - CAMERA.cx) / CAMERA.fx, np.full(k, (3.0 - CAMERA.cy) / CAMERA.fy), np.ones(k)], -1)
        np.testing.assert_allclose(cam.project(X)[:, 0], 7 * k + np.arange(k), atol=1e-9)
        np.testing.assert_allclose(cam.project(X)[:, 1], 3 * k + (k - 1) / 2, atol=1e-9)


@pytest.mark.parametrize("bad", [0, 9, 1.5, True])
def test_supersample_must_be_a_small_integer(bad):
    with pytest.raises(RenderError, match="supersample"):
        CameraViewRenderer(None, [], CAMERA, mesh=_mesh(_polygon((0.0, 0.0))), supersample=bad)
