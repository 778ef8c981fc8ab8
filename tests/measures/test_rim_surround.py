"""A rim whose surround is off the part (``rim_occlusion.surround_off``) against a closed form and the detector.

References: (1) face-on, the surround ring is a circle of radius R + g/s mm (s = fx/Z px per mm) about the hole's
centre, and a straight face edge at e mm from the centre cuts the fraction arccos(e / (R + g/s)) / π of it off
the part — exact geometry, for the exact ray test (the optimiser's depth maps leave the surround out: their
cells are coarser than the ring's 3 px, which the test also pins); (2) the closed loop's detector on a
rendered image rejects a rim that comes within the surround gap of the plate's edge and accepts one further
away, as the prediction says.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

cq = pytest.importorskip("cadquery")

from cadfeat.cad.export import mesh_from_shape  # noqa: E402
from cadfeat.cad.features import extract_holes, holes_to_arrays  # noqa: E402
from cadfeat.camera import Camera  # noqa: E402
from cadfeat.measures.depth import DepthMaps  # noqa: E402
from cadfeat.measures.rim_occlusion import SURROUND_GAP_PX, rim_occlusion, surround_off  # noqa: E402
from cadfeat.poses import invert_T, look_at  # noqa: E402

CAMERA = Camera(fx=800.0, fy=800.0, cx=320.0, cy=240.0, width=640, height=480)
Z_MM = 200.0          # camera height above the plate's top face: 4 px per mm
RADIUS_MM = 3.0
SAMPLES = 64


def _plate(edge_gap_px: float):
    """A 5 mm plate whose +x edge lies ``edge_gap_px`` image pixels (face-on) beyond the rim of a Ø6 through
    hole at the origin, and the camera straight above the hole."""
    e = RADIUS_MM + edge_gap_px * Z_MM / CAMERA.fx            # edge's distance from the hole's centre, mm
    wp = cq.Workplane("XY").box(e + 40.0, 80.0, 5.0, centered=(False, True, False)).translate((-40.0, 0, -5.0))
    wp = wp.faces(">Z").workplane(origin=(0, 0, 0)).hole(2 * RADIUS_MM)
    holes = extract_holes(wp)
    T = invert_T(look_at(np.array([0.0, 0.0, Z_MM]), np.zeros(3), up=(0.0, 1.0, 0.0)))[None]
    return wp.val(), holes, T, e


@pytest.mark.parametrize("edge_gap_px", [0.8, 1.6, 2.4, 6.0])
def test_surround_off_fraction_is_the_circle_cut_by_the_edge(edge_gap_px):
    shape, holes, T, e = _plate(edge_gap_px)
    c, n, r = holes_to_arrays(holes)
    ring = RADIUS_MM + SURROUND_GAP_PX * Z_MM / CAMERA.fx
    expected = np.arccos(min(e / ring, 1.0)) / np.pi
    mesh = mesh_from_shape(shape, tolerance=0.05)
    exact = surround_off(mesh, CAMERA, T, c, n, r, samples=SAMPLES)[0, 0]
    assert exact == pytest.approx(expected, abs=1.5 / SAMPLES)
    hidden = rim_occlusion(mesh, T, c, n, r, samples=SAMPLES, camera=CAMERA)[0, 0]
    assert hidden == pytest.approx(exact)                          # the rim itself is in full view
    maps = rim_occlusion(DepthMaps(mesh, CAMERA, T), T, c, n, r, samples=SAMPLES, camera=CAMERA)[0, 0]
    assert maps == 0.0


@pytest.mark.parametrize(("edge_gap_px", "accepted"), [(1.5, False), (7.0, True)])
def test_the_detector_agrees_with_the_predicted_surround(edge_gap_px, accepted):
    from cadfeat.render.camera_views import CameraViewRenderer
    from cadfeat.vision.detection import detect_holes

    shape, holes, T, _ = _plate(edge_gap_px)
    with CameraViewRenderer(shape, holes, CAMERA) as renderer:
        image = cv2.cvtColor(renderer.render(T[0]), cv2.COLOR_RGB2GRAY)
    found = detect_holes(image)
    near = np.linalg.norm(found.centre_px - [CAMERA.cx, CAMERA.cy], axis=1) < 3.0 if len(found.centre_px) else []
    assert bool(np.any(near)) is accepted
    c, n, r = holes_to_arrays(holes)
    off = surround_off(mesh_from_shape(shape, tolerance=0.05), CAMERA, T, c, n, r)[0, 0]
    assert bool(off <= 0.03) is accepted   # the closed loop's RIM_HIDDEN_MAX
