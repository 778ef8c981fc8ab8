"""The offset model's interior-contrast term (``measures.pose_models.interior_contrast``) against the renderer and
cadfeat's own detector.

- The shading law the term assumes (``SHADE_AMBIENT``, ``HOLE_ALBEDO``: Lambert under the camera's headlight)
  against the grey levels the renderer draws for the part's face, a bore's wall and a blind hole's floor
  (within 1.5 grey levels, i.e. < 1 % of the face's level).
- Held-out render conditions (a view angle, radius, depth and distance not in the calibration grid of
  ``tools/calibrate_detection.py``): the mean detected centre offset along the image direction of the hole's
  axis over 6 placements, against the model's systematic offset. A blind hole (its lit floor shows past the rim)
  and a counterbore (its step's floor: a rule, not fitted) are offset against the axis direction, a through hole
  (black background past the rim) along it; each within 3 × the uncertainty of the measured mean (its pixel-grid
  scatter over the placements and noise over the draws) + 0.01 px. These check the committed default
  calibration (``detection_model.json``: the threshold detector ``detection.detect_holes``), so the script's
  world is set to it; the closed loop's rim-edge detector has almost no interior-contrast offset (its raster
  calibration: k_i 0.04 against 0.27), tests/measures/test_pose_calibrations.py.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("cadquery")

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

import calibrate_detection as C  # noqa: E402

from cadfeat.cad.features import extract_holes, holes_to_arrays  # noqa: E402
from cadfeat.camera import Camera  # noqa: E402
from cadfeat.measures.pose_models import (  # noqa: E402
    HOLE_ALBEDO,
    SHADE_AMBIENT,
    _radius_along,
    default_models,
    hole_geometry,
)
from cadfeat.vision.images import render_sequence  # noqa: E402


@pytest.fixture(autouse=True)
def _threshold_world(monkeypatch):
    monkeypatch.setattr(C, "WORLD", C.World(detector="threshold"))


def _hole(wp):
    return [h for h in extract_holes(wp) if np.linalg.norm(h.centre[:2]) < 1e-6]


def _level(cos_g: float) -> float:
    return SHADE_AMBIENT + (1.0 - SHADE_AMBIENT) * cos_g


def _grey_along(img: np.ndarray, centre: np.ndarray, d: np.ndarray, t: float) -> float:
    p = centre + t * d
    return float(img[int(round(p[1])), int(round(p[0]))])


WIDE = Camera(fx=800.0, fy=800.0, cx=320.0, cy=240.0, width=640, height=480, focus_distance_mm=300.0)


@pytest.mark.parametrize("angle, shift_mm", [(0.0, 0.0), (20.0, 0.0), (40.0, 0.0), (0.0, 62.5)])
def test_the_shading_law_matches_the_renderers_grey_levels(angle, shift_mm):
    """Face, wall and floor levels on the line through the rim centre along the image direction d̂ of the hole's
    axis: face and floor ∝ L(c_f), the wall (inside the rim, opposite d̂) ∝ q L(c_w), one scale from the face at
    normal view. The last case: a plate square to the optical axis, the hole 250 px off the image centre (seen
    17° from its axis): the directional headlight leaves the wall at the ambient level (c_w = 0), where a light
    at the camera would light it at sin 17°."""
    wp = C.plate(4.0, "blind", 0.6)   # 4.8 mm deep: the floor shows past the rim
    holes = _hole(wp)
    c, n, r = holes_to_arrays(holes)
    T = C.pose(angle, 200.0)
    T[0, 3] += shift_mm
    img = render_sequence(wp.val(), holes, WIDE, T[None])[0]
    geo = hole_geometry(WIDE, T[None], c, n, r)
    centre = geo.rims[0][0, 0]
    d = geo.axis_dir_px[0, 0] if np.linalg.norm(geo.axis_dir_px[0, 0]) > 0 else np.array([1.0, 0.0])
    ang = geo.rims[2][0, 0]
    semi = float(_radius_along(geo.rims[1][0, 0], np.array([np.cos(ang), np.sin(ang)]), d))  # the rim along d̂
    face0 = 180.57 / _level(1.0)          # the face at normal view (BT.601 luma of the lit PART_GREY)
    cf, cw = float(geo.light_face[0, 0]), float(geo.light_wall[0, 0])
    if shift_mm:
        assert np.degrees(np.arccos(geo.facing[0, 0])) > 15 and cw < 1e-6
    else:
        np.testing.assert_allclose([cf, cw], [np.cos(np.radians(angle)), np.sin(np.radians(angle))], atol=1e-9)
    assert abs(_grey_along(img, centre, d, -semi - 6.0) - face0 * _level(cf)) <= 1.5
    assert abs(_grey_along(img, centre, d, semi - 3.0) - face0 * HOLE_ALBEDO * _level(cf)) <= 1.5  # floor
    if angle > 0 or shift_mm:
        wall = _grey_along(img, centre, d, -semi + 2.0)       # inside the rim opposite d̂: the wall's band
        assert abs(wall - face0 * HOLE_ALBEDO * _level(cw)) <= 1.5, wall


def _counterbore_plate():
    import cadquery as cq

    return (cq.Workplane("XY").box(60, 60, 5).translate((0, 0, -2.5)).faces(">Z").workplane()
            .cboreHole(12.0, 18.0, 2.0))


HELD_OUT = [  # plate, radius (rim), view angle, distance, blur, sign of the offset along d̂
    ("blind", 7.0, 11.0, 220.0, 1.0, -1),
    ("through", 7.0, 11.0, 220.0, 1.0, +1),
    ("counterbore", 9.0, 11.0, 220.0, 1.0, -1),
]


@pytest.mark.parametrize("kind, radius, angle, dist, blur, sign", HELD_OUT)
def test_interior_contrast_offset_on_held_out_renders(kind, radius, angle, dist, blur, sign):
    wp = _counterbore_plate() if kind == "counterbore" else C.plate(radius, kind, 0.25)
    holes = _hole(wp)
    assert len(holes) == 1 and abs(holes[0].radius_mm - radius) < 1e-6
    assert holes[0].kind.startswith(kind if kind == "counterbore" else "plain")
    Ts = C.placements(C.pose(angle, dist), seed=7)
    row = C.measure_placements(C.render_many(wp.val(), holes, Ts), holes[0], Ts, blur, 4)
    c, n, r = holes_to_arrays(holes)
    geo = hole_geometry(C.CAMERA, Ts[:1], c, n, r)
    geo = geo._replace(blur_px=np.full((1, 1), blur))  # the blur applied to the render
    ratio = holes[0].depth_mm / (2 * holes[0].radius_mm)
    _, off = default_models().measurement_model(geo, depth_ratio=[ratio], through=[holes[0].through],
                                                kinds=[holes[0].kind], noise_grey=C.NOISE_GREY)
    model = float(off[0, 0] @ geo.axis_dir_px[0, 0])
    measured = row["offset_axis_px"]
    uncertainty = np.hypot(row["alias_px"] / np.sqrt(row["placements"]), row["sigma_px"] / np.sqrt(row["draws"]))
    assert np.sign(model) == sign, (model, row)
    assert np.sign(measured) == sign, (measured, row)
    assert abs(measured - model) <= 3 * uncertainty + 0.01, (measured, model, uncertainty)
