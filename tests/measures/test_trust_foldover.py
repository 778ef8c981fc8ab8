"""Lens fold-over: past the distortion polynomial's monotonic radius a point is outside the image everywhere."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from cadfeat import measures
from cadfeat.cad.features import Hole
from cadfeat.camera import Camera
from cadfeat.design.unseen import scored_measures
from cadfeat.render.camera_views import draw_hole_overlay

pytestmark = pytest.mark.numerics  # run again under another BLAS kernel (Makefile: test)

THESIS = Camera.preset("dalsa-cad1-128a")


def test_fold_radius_is_where_the_radial_distortion_stops_growing():
    r = THESIS.fold_radius
    k1, k2, _, _, k3 = THESIS.dist

    def rd(x):
        return x * (1 + k1 * x**2 + k2 * x**4 + k3 * x**6)
    h = 1e-7  # independent: numerical derivative of r_d changes sign at the fold
    assert (rd(r - 1e-4 + h) - rd(r - 1e-4)) > 0 > (rd(r + 1e-4 + h) - rd(r + 1e-4))
    assert THESIS.valid_field_deg == pytest.approx(23.03, abs=0.01)  # the issue: "about 23° off axis"
    assert Camera(fx=500, fy=500, cx=320, cy=240, width=640, height=480).fold_radius == np.inf
    assert THESIS.fold_inside_image  # the thesis calibration folds inside its own image corners: a warning
    assert not Camera(fx=500, fy=500, cx=320, cy=240, width=640, height=480, dist=(-0.1, 0, 0, 0, 0)).fold_inside_image


def test_point_35_degrees_off_axis_is_not_visible_not_in_jacobian_no_overlay():
    a = np.radians(35.0)
    z = 100.0
    centre = np.array([[np.tan(a) * z, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 5.0, 0.0], [5.0, 0.0, 0.0]])
    axes = np.tile([0.0, 0.0, -1.0], (4, 1))  # facing the camera (which looks along +z from z = −100)
    T = np.eye(4)[None].copy()
    T[0, 2, 3] = z  # part frame origin 100 mm in front of the camera
    raw = THESIS.project(centre[:1] + [0, 0, z])
    assert np.all((raw >= 0) & (raw <= [THESIS.width, THESIS.height]))  # the fold puts it inside the image
    m = measures.evaluate(THESIS, T, np.ones((1, 6)), centre, axes, np.full(4, 0.2))
    assert m.folded[0].tolist() == [True, False, False, False]
    # the measures are the thesis's (issue 32 item 7: the cone margin of a point 35° off axis, outside the
    # camera's 2 atan(64/fx) field); the objectives score the folded point unseen
    assert m.fov[0, 0] == pytest.approx(np.cos(a) - np.cos(THESIS.fov_rad / 2), abs=1e-12) and m.fov[0, 0] < 0
    s = scored_measures(m, THESIS, 5.0)
    assert not s.visible[0, 0] and s.visible[0, 1:].all()
    assert s.fov[0, 0] < 0 and s.fov_px[0, 0] < 0 and s.resolution_px[0, 0] <= 0 and s.focus[0, 0] <= 0
    # not in Λ: the same measures without the folded point
    rest = measures.evaluate(THESIS, T, np.ones((1, 6)), centre[1:], axes[1:], np.full(3, 0.2))
    np.testing.assert_allclose(m.sigma_min, rest.sigma_min, rtol=1e-12)
    np.testing.assert_allclose(m.resolvability, rest.resolvability, rtol=1e-12)
    # no overlay: drawing the folded hole alone leaves the image untouched
    hole = Hole(centre[0], axes[0], 0.2, 0.2, 1.0, True, "plain", 0, None, "F")
    image = np.zeros((THESIS.height, THESIS.width, 3), np.uint8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = draw_hole_overlay(image, THESIS, [hole], T[0])
    assert not out.any()
    seen = Hole(centre[1], axes[1], 0.2, 0.2, 1.0, True, "plain", 0, None, "S")
    assert draw_hole_overlay(image, THESIS, [seen], T[0]).any()
