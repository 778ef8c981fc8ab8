"""Part pictures: before/after comparison, single part view, camera frusta geometry."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

cq = pytest.importorskip("cadquery")

from cadfeat.cad.features import extract_holes  # noqa: E402
from cadfeat.camera import Camera  # noqa: E402
from cadfeat.errors import CadfeatError  # noqa: E402
from cadfeat.poses import invert_T, look_at  # noqa: E402
from cadfeat.render import render_comparison, render_part  # noqa: E402
from cadfeat.render.part_views import FIXED, MOVED_AFTER, MOVED_BEFORE  # noqa: E402
from cadfeat.render.view_geometry import frustum_lines  # noqa: E402

BEFORE_XY = [(-20.0, -10.0), (15.0, 12.0), (22.0, -15.0)]
AFTER_XY = [(-12.0, -4.0), (15.0, 12.0), (28.0, -20.0)]


def _plate(points):
    wp = cq.Workplane("XY").box(80, 60, 5).faces(">Z").workplane().pushPoints(points).hole(8)
    holes = extract_holes(wp)
    centres = np.array([h.centre[:2] for h in holes])
    order = [int(np.argmin(np.linalg.norm(centres - p, axis=1))) for p in points]  # holes in the listed order
    return wp.val(), [holes[i] for i in order]


def _count_colour(image_bgr: np.ndarray, rgb, tol=40) -> int:
    target = np.array(rgb[::-1]) * 255
    return int((np.abs(image_bgr.astype(float) - target).max(axis=-1) < tol).sum())


@pytest.fixture(scope="module")
def pair():
    return _plate(BEFORE_XY), _plate(AFTER_XY)


def test_render_comparison_two_images_same_view(pair, tmp_path):
    (shape_b, holes_b), (shape_a, holes_a) = pair
    eyes = np.stack([[-80.0 + 160.0 * s, -60.0, 120.0] for s in np.linspace(0, 1, 12)])
    T_task_cam = np.stack([look_at(e, [0.0, 0.0, 0.0], up=(0.0, 1.0, 0.0)) for e in eyes])
    camera = Camera(fx=600.0, fy=600.0, cx=320.0, cy=240.0, width=640, height=480)
    paths = render_comparison(shape_b, shape_a, holes_b, holes_a, [False, True, False], tmp_path,
                              trajectory=T_task_cam, camera=camera, n_frusta=4, size=(500, 380))
    assert set(paths) == {"before", "after"}
    before, after = cv2.imread(str(paths["before"])), cv2.imread(str(paths["after"]))
    assert before.shape == after.shape == (380, 500, 3)
    for img in (before, after):
        assert img.std() > 10 and (img < 245).any(axis=-1).mean() > 0.05  # not blank
        assert _count_colour(img, FIXED) > 20  # the fixed hole is marked
    assert _count_colour(before, MOVED_BEFORE) > 20
    assert _count_colour(after, MOVED_AFTER) > 20
    # same viewpoint: the fixed hole (and its label) lands on the same pixels in both pictures
    blue = [np.argwhere(np.abs(img.astype(float) - np.array(FIXED[::-1]) * 255).max(axis=-1) < 40).mean(axis=0)
            for img in (before, after)]
    assert np.linalg.norm(blue[0] - blue[1]) < 1.0
    assert (np.abs(before.astype(int) - after.astype(int)).max(axis=-1) < 30).mean() > 0.85


def test_render_comparison_rejects_mismatched_hole_lists(pair, tmp_path):
    (shape_b, holes_b), (shape_a, holes_a) = pair
    with pytest.raises(CadfeatError, match="same length"):
        render_comparison(shape_b, shape_a, holes_b, holes_a[:2], [False] * 3, tmp_path)


def test_render_part_not_blank(pair, tmp_path):
    (shape_b, _), _ = pair
    path = render_part(shape_b, tmp_path / "part.png", view_direction=(0.0, 0.0, 1.0), size=(320, 240))
    img = cv2.imread(str(path))
    assert img.shape == (240, 320, 3)
    grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    assert (grey < 250).mean() > 0.2  # the plate fills a good part of the picture
    with pytest.raises(CadfeatError, match="view_direction"):
        render_part(shape_b, tmp_path / "bad.png", view_direction=(0.0, 0.0, 0.0))


def test_frustum_corners_project_to_image_corners():
    camera = Camera(fx=800.0, fy=760.0, cx=300.0, cy=250.0, width=640, height=480)
    T_part_cam = look_at(np.array([[50.0, -20.0, 200.0], [0.0, 90.0, 150.0]]), np.zeros(3))
    pts, cells = frustum_lines(camera, T_part_cam, depth_mm=30.0)
    assert pts.shape == (10, 3) and cells.shape == (2 * 8 * 3,)
    for k in range(2):
        T = invert_T(T_part_cam[k])
        rvec, _ = cv2.Rodrigues(T[:3, :3])
        px, _ = cv2.projectPoints(pts[5 * k + 1:5 * k + 5], rvec, T[:3, 3], camera.K, None)
        np.testing.assert_allclose(px.reshape(-1, 2), [[0, 0], [640, 0], [640, 480], [0, 480]], atol=1e-6)
        np.testing.assert_allclose(pts[5 * k], T_part_cam[k, :3, 3])  # apex at the camera centre
        depth = (pts[5 * k + 1:5 * k + 5] - T_part_cam[k, :3, 3]) @ T_part_cam[k, :3, 2]
        np.testing.assert_allclose(depth, 30.0)


def test_trajectory_placed_in_part_frame():
    from scipy.spatial.transform import Rotation

    from cadfeat.poses import make_T
    from cadfeat.render.view_geometry import _trajectory_in_part
    from cadfeat.trajectory import Trajectory

    eyes = np.array([[100.0, 0.0, 300.0], [50.0, 20.0, 280.0], [0.0, 40.0, 260.0]])
    traj = Trajectory(look_at(eyes, np.zeros(3)), [0.0, 0.5, 1.0])
    T_task_part = make_T(Rotation.from_euler("zyx", [0.3, -0.2, 0.1]).as_matrix(), [10.0, -5.0, 40.0])
    np.testing.assert_allclose(_trajectory_in_part(traj, T_task_part), traj.in_part_frame(T_task_part).T_task_cam,
                               atol=1e-12)
    np.testing.assert_allclose(_trajectory_in_part(traj.T_task_cam, None), traj.T_task_cam)
    with pytest.raises(CadfeatError, match="trajectory"):
        _trajectory_in_part(np.eye(4), None)


def test_closeup_pair_fills_the_picture_and_shows_the_moves(pair, tmp_path):
    """The close-up is fitted to the part alone: much bigger than in the trajectory overview, same view in both
    images, moved holes with their arrow (red) and new place (green), the fixed hole marked (blue)."""
    from cadfeat.render.part_views import ARROW

    (shape_b, holes_b), (shape_a, holes_a) = pair
    eyes = np.stack([[-400.0 + 800.0 * s, -300.0, 500.0] for s in np.linspace(0, 1, 8)])  # far away: tiny part
    T_task_cam = np.stack([look_at(e, [0.0, 0.0, 0.0], up=(0.0, 1.0, 0.0)) for e in eyes])
    paths = render_comparison(shape_b, shape_a, holes_b, holes_a, [False, True, False], tmp_path,
                              trajectory=T_task_cam, n_frusta=3, size=(500, 380), closeup=True)
    assert set(paths) == {"before", "after", "before_closeup", "after_closeup"}
    imgs = {k: cv2.imread(str(p)) for k, p in paths.items()}
    before, after = imgs["before_closeup"], imgs["after_closeup"]
    assert before.shape == after.shape == (380, 500, 3)

    def filled(img):  # fraction of non-background (non-white) pixels
        return float((img < 245).any(axis=-1).mean())

    for img in (before, after):
        assert img.std() > 10  # not blank
        assert filled(img) > 0.25  # the part fills a substantial part of the close-up
        assert _count_colour(img, FIXED) > 50
    assert filled(after) > 3 * filled(imgs["after"])  # ... unlike the overview with the far trajectory
    assert _count_colour(before, MOVED_BEFORE) > 50
    assert _count_colour(after, MOVED_AFTER) > 50
    red_after, red_before = _count_colour(after, ARROW, tol=50), _count_colour(before, ARROW, tol=50)
    assert red_after > 100 and red_after > 10 * red_before  # the arrows are in the after picture (legend: both)
    # same viewpoint: the fixed hole's highlight lands on the same pixels in both close-ups
    blue = [np.argwhere(np.abs(img.astype(float) - np.array(FIXED[::-1]) * 255).max(axis=-1) < 40).mean(axis=0)
            for img in (before, after)]
    assert np.linalg.norm(blue[0] - blue[1]) < 2.0


def test_place_labels_avoids_overlaps():
    """Four labels around four nearby circles: every box inside the image, none overlapping another or a circle."""
    from cadfeat.render.view_geometry import _boxes_overlap, place_labels

    anchors = np.array([[100.0, 100.0], [130.0, 100.0], [100.0, 130.0], [130.0, 130.0]])
    radii = np.full(4, 8.0)
    sizes = np.array([[60.0, 20.0]] * 4)
    rims = np.c_[anchors - 8.0, anchors + 8.0]
    corners = place_labels(anchors, radii, sizes, rims, (300, 260))
    boxes = np.c_[corners, corners + sizes]
    assert (boxes[:, :2] >= 0).all() and (boxes[:, 2] <= 300).all() and (boxes[:, 3] <= 260).all()
    for i in range(4):
        assert _boxes_overlap(boxes[i], np.delete(boxes, i, axis=0)) == 0.0
        assert _boxes_overlap(boxes[i], rims) == 0.0
