"""Synthetic camera images against OpenCV: dark holes found in the render sit where the camera model says.

Independent references: ``cv2.projectPoints`` of densely sampled rim points (whose ``cv2.fitEllipse``
is the exact image conic for a pinhole camera), ``Camera.project`` of the hole centres, and
``cadfeat.measures.hole_ellipse`` (the contract's predicted ellipse).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

cq = pytest.importorskip("cadquery")

from cadfeat.cad.features import extract_holes, holes_to_arrays  # noqa: E402
from cadfeat.camera import Camera  # noqa: E402
from cadfeat.measures import hole_ellipse  # noqa: E402
from cadfeat.poses import invert_T, look_at  # noqa: E402
from cadfeat.render.camera_views import CameraViewRenderer, render_camera_views  # noqa: E402

UPSAMPLE = 8  # sub-pixel contours: bilinear ×8 up-sampling, threshold, findContours (≈ marching squares)


@pytest.fixture(scope="module")
def plate():
    """A plate with a through hole, a blind hole and a counterbored hole (rim radius 5 mm or 6 mm)."""
    wp = cq.Workplane("XY").box(80, 60, 5).faces(">Z").workplane().pushPoints([(-20, -10)]).hole(10)
    wp = wp.faces(">Z").workplane().pushPoints([(15, 12)]).hole(10, 3)
    wp = wp.faces(">Z").workplane().pushPoints([(22, -15)]).cboreHole(6, 12, 2)
    holes = extract_holes(wp)
    assert sorted(h.kind for h in holes) == ["counterbore", "plain", "plain"]
    assert sorted(h.through for h in holes) == [False, True, True]
    return wp.val(), holes


def _pose(eye, target=(0.0, 0.0, 2.5)) -> np.ndarray:
    return invert_T(look_at(np.asarray(eye, float), np.asarray(target, float), up=(0.0, 1.0, 0.0)))


def _rim_points(holes, n=4000) -> np.ndarray:
    centres, axes, radii = holes_to_arrays(holes)
    assert np.allclose(axes, [0, 0, 1])
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)], -1)
    return centres[:, None, :] + radii[:, None, None] * ring[None]


def _expected(camera: Camera, holes, T: np.ndarray):
    """Per hole: (centre, sorted full axes) of cv2.fitEllipse of cv2.projectPoints rim points, and the same
    of ``measures.hole_ellipse`` (exact conic; first-order distortion)."""
    rvec, _ = cv2.Rodrigues(T[:3, :3])
    fitted = []
    for rim in _rim_points(holes):
        px, _ = cv2.projectPoints(rim, rvec, T[:3, 3], camera.K, camera.dist_coeffs)
        (cx, cy), axes, _ = cv2.fitEllipse(px.reshape(-1, 2).astype(np.float32))
        fitted.append((np.array([cx, cy]), np.sort(axes)))
    centres, axes_, radii = holes_to_arrays(holes)
    e = hole_ellipse(camera, centres @ T[:3, :3].T + T[:3, 3], axes_ @ T[:3, :3].T, radii)
    assert np.all(e.valid)
    predicted = [(np.asarray(e.centre_px)[j], np.sort(np.asarray(e.axes_px)[j])) for j in range(len(holes))]
    return fitted, predicted


def _dark_blobs(image: np.ndarray):
    """Hole blobs not touching the border: (region centroid px, sub-pixel fitEllipse centre, sorted axes)."""
    grey = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY).astype(np.float32)
    part_level = np.percentile(grey[grey > 40], 50)
    threshold = 0.5 * (part_level + np.percentile(grey, 1))  # midway between the grey part and the dark holes
    h, w = grey.shape
    big = cv2.resize(grey, (w * UPSAMPLE, h * UPSAMPLE), interpolation=cv2.INTER_LINEAR)
    contours, hierarchy = cv2.findContours((big < threshold).astype(np.uint8), cv2.RETR_CCOMP,
                                           cv2.CHAIN_APPROX_NONE)
    blobs = []
    for c, (_, _, _, parent) in zip(contours, hierarchy[0], strict=True):
        if parent != -1:
            continue  # an inner boundary of a dark region (the part's outline inside the background)
        pts = (c[:, 0, :].astype(np.float64) + 0.5) / UPSAMPLE - 0.5  # up-sampled pixel centre → image px
        if len(pts) < 20 or pts.min() < 2 or pts[:, 0].max() > w - 3 or pts[:, 1].max() > h - 3:
            continue  # the background around the part, or a speck
        (ex, ey), axes, _ = cv2.fitEllipse(pts.astype(np.float32))
        mask = np.zeros((h, w), np.uint8)
        cv2.fillPoly(mask, [np.round(pts).astype(np.int32)], 1)
        m = cv2.moments(((grey < threshold) & (mask > 0)).astype(np.uint8), binaryImage=True)
        blobs.append((np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]]), np.array([ex, ey]), np.sort(axes)))
    return blobs


def _check_image(image, camera, holes, T, centre_tol_px=1.0, axes_tol_px=1.0):
    centres, _, _ = holes_to_arrays(holes)
    projected = camera.project(centres @ T[:3, :3].T + T[:3, 3])
    fitted, predicted = _expected(camera, holes, T)
    blobs = _dark_blobs(image)
    assert len(blobs) == len(holes)
    for centroid, e_centre, e_axes in blobs:
        j = int(np.argmin(np.linalg.norm(projected - centroid, axis=1)))
        assert np.linalg.norm(centroid - projected[j]) < centre_tol_px
        for centre, axes in (fitted[j], predicted[j]):
            assert np.linalg.norm(e_centre - centre) < 0.5
            np.testing.assert_allclose(e_axes, axes, atol=axes_tol_px)


def test_dark_holes_match_projection_pinhole(plate):
    shape, holes = plate
    camera = Camera(fx=700.0, fy=650.0, cx=330.3, cy=236.8, width=640, height=480)  # fx ≠ fy, off-centre
    T = _pose([30.0, -40.0, 160.0])
    with CameraViewRenderer(shape, holes, camera) as renderer:
        image = renderer.render(T)
        assert image.shape == (480, 640, 3)
        _check_image(image, camera, holes, T)
        T2 = _pose([-60.0, 10.0, 140.0], target=(5.0, 0.0, 0.0))  # the same plotter, a second pose
        _check_image(renderer.render(T2), camera, holes, T2)


def test_dark_holes_match_projection_with_distortion(plate):
    shape, holes = plate
    camera = Camera(fx=650.0, fy=650.0, cx=318.0, cy=243.0, width=640, height=480, dist=(-0.12, 0.05, 0.0, 0.0, 0.0))
    T = _pose([20.0, -30.0, 150.0])
    with CameraViewRenderer(shape, holes, camera) as renderer:
        _check_image(renderer.render(T), camera, holes, T)


def test_a_barrel_lens_sees_the_part_up_to_its_valid_field():
    """A plate far larger than the view, seen through the thesis camera's strong barrel lens (k₁ = −1.45): every
    pixel inside the lens model's valid field (``Camera.fold_radius``, the image of the fold circle) shows the
    part, none the black background — the pinhole render must cover the wider field a barrel lens images. A hole
    placed where it images 8 px inside the image's edge is found where ``cv2.projectPoints`` puts its rim."""
    camera = Camera(fx=231.41, fy=231.25, cx=64.2, cy=61.5, width=128, height=128,
                    dist=(-1.45, -1.32, 0.0, 0.0, 0.0))
    T = _pose([0.0, 0.0, 60.0], target=(0.0, 0.0, 0.0))
    # the hole: the plate point that images at (64.2, 11) px (undistortPoints: the exact inverse, independent)
    xy = cv2.undistortPoints(np.array([[[64.2, 11.0]]]), camera.K, camera.dist_coeffs).reshape(2)
    point = invert_T(T) @ np.array([*(xy * 62.5), 62.5, 1.0])        # on the plate's top face z = 2.5
    wp = cq.Workplane("XY").box(400, 400, 5).faces(">Z").workplane().pushPoints([tuple(point[:2])]).hole(3.0)
    holes = extract_holes(wp)
    with CameraViewRenderer(wp.val(), holes, camera) as renderer:
        image = renderer.render(T)
    grey = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    edge = camera.distort_normalized(np.array([camera.fold_radius, 0.0]))   # (the lens has no tangential terms)
    rd = (float(edge[0]) - camera.cx) / camera.fx
    u, v = np.meshgrid(np.arange(128.0), np.arange(128.0))
    valid = np.hypot((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy) < 0.97 * rd
    rim = _rim_points(holes)[0]
    rvec, _ = cv2.Rodrigues(T[:3, :3])
    px, _ = cv2.projectPoints(rim, rvec, T[:3, 3], camera.K, camera.dist_coeffs)
    px = px.reshape(-1, 2)
    near_hole = np.min(np.hypot(u[..., None] - px[:, 0], v[..., None] - px[:, 1]), axis=-1) < 3.0
    interior = np.array([[cv2.pointPolygonTest(px.astype(np.float32), (float(a), float(b)), False) >= 0
                          for a in range(128)] for b in range(128)])
    part = valid & ~near_hole & ~interior
    assert part.sum() > 0.5 * 128 * 128
    assert np.all(grey[part] > 60), f"{int(np.sum(grey[part] <= 60))} pixels of the valid field show background"
    (cx, cy), _, _ = cv2.fitEllipse(px.astype(np.float32))
    ys, xs = np.nonzero(interior & (grey < 60))
    assert len(xs) > 0.8 * interior.sum(), "the hole near the image's edge is dark"
    assert abs(xs.mean() - cx) < 0.5 and abs(ys.mean() - cy) < 0.5


def test_render_camera_views_writes_pngs_with_overlay(plate, tmp_path):
    shape, holes = plate
    camera = Camera(fx=500.0, fy=500.0, cx=160.0, cy=120.0, width=320, height=240)
    T = np.stack([_pose([0.0, 0.0, 200.0]), _pose([40.0, -30.0, 180.0])])
    plain = render_camera_views(shape, holes, camera, T, tmp_path, "plain", overlay=False)
    drawn = render_camera_views(shape, holes, camera, T, tmp_path, "drawn", overlay=True)
    assert [p.name for p in drawn] == ["drawn_000.png", "drawn_001.png"]
    for a, b in zip(plain, drawn, strict=True):
        img_a, img_b = cv2.imread(str(a)), cv2.imread(str(b))
        assert img_a.shape == img_b.shape == (240, 320, 3)
        assert img_a.std() > 20  # not blank: grey part, dark holes, black background
        changed = np.any(img_a != img_b, axis=-1)
        assert changed.sum() > 100  # ellipses and centre markers were drawn


def test_cadquery_and_pyvista_render_in_one_process():
    """cadquery-ocp ships its own VTK: both must import and render off-screen (EGL) in one process."""
    import pyvista as pv

    from cadfeat.render.scene import EGL_WINDOW, new_plotter, screenshot, shape_polydata

    box = cq.Workplane("XY").box(10, 10, 10).val()
    plotter = new_plotter((120, 90))
    try:
        assert plotter.ren_win.GetClassName() == EGL_WINDOW
        plotter.add_mesh(shape_polydata(box), color="red")
        image = screenshot(plotter)
    finally:
        plotter.close()
    assert isinstance(pv.__version__, str)
    assert image.shape == (90, 120, 3)
    reddish = (image[..., 0] > 150) & (image[..., 1] < 100)
    assert reddish.sum() > 500
