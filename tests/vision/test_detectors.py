"""The hole detectors (``vision.detectors``) on synthetic holes with an exact answer.

Reference, independent of the detectors: ellipses drawn by ``cv2.ellipse`` at 1/16 px (16× canvas, 4 shift
bits, pixel centres at integer coordinates) and area-averaged back (``cv2.resize`` INTER_AREA), as a sensor
integrates each pixel; the rim centre is the drawn ellipse's centre. Faces and holes of the physical cases
cadfeat's threshold detector fails on (docs/design.md "Closed loop"), each with 2 grey levels of Gaussian noise:

(a) ``dark``: a dark bore (face 130, bore 25);
(b) ``crescent``: the far wall lit brighter than the face (165) with a dark crescent (30) on one side — the
    wall is the rim ellipse minus the same ellipse shifted by 0.35 of its semi-major axis; (b') the same with
    the wall lit to nearly the face's grey (142);
(c) ``mirror``: a saturated blind-hole floor (255) inside a thin dark wall ring (20, 1.5 px); (c') ``mirror_thin``:
    a shallow blind hole in machined metal seen obliquely under a ring light (the flagship's original target,
    docs/results.md): a bright face (200), the far wall a dark crescent at most 1.2 px wide (100) and the
    saturated floor (255) reaching the rim on the near side — the floor ellipse shifted 1.2 px across the axis;
(d) ``chamfer``: the rim (outer chamfer edge) around a band of 80 and the bore's edge (20) at 0.72 of its size,
    shifted 1.5 px (seen obliquely the bore's edge is a different circle at a different depth); (d') the band
    lit brighter than the face (200);
(e) ``plastic``: low contrast (face 120, bore 95).

cadfeat's detector (``"cadfeat"``, with a prior off by (2, −1.5) px, 8 % in size and 5° in angle) must find the
outer rim's centre in every case. EDCircles and the blob detector must run and be sane on (a); where they miss
or lock onto another edge is measured and recorded here (``test_other_detectors_measured``), not required.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from cadfeat.camera import Camera
from cadfeat.measures.ellipse import Ellipse
from cadfeat.vision.detection import associate, detect_holes
from cadfeat.vision.detectors import DETECTORS, detect
from cadfeat.vision.edcircles import to_detections

S = 16                                   # canvas sub-pixels per pixel side
H, W = 96, 128
CENTRE = np.array([61.37, 47.81])        # rim centre, px
SEMI = np.array([18.0, 12.0])            # rim semi-axes, px
ANGLE_DEG = 25.0                         # rim major axis from +u towards +v
CASES = ("dark", "crescent", "crescent_similar", "mirror", "mirror_thin", "chamfer", "chamfer_bright", "plastic")


def _mask(centre: np.ndarray, semi: np.ndarray, angle_deg: float, shape: tuple[int, int] = (H, W)) -> np.ndarray:
    """The ellipse's interior on the 16× canvas (bool)."""
    m = np.zeros((shape[0] * S, shape[1] * S), np.uint8)
    sh = 4
    c = tuple(int(round((S * (v + 0.5) - 0.5) * (1 << sh))) for v in centre)
    ax = tuple(int(round(S * v * (1 << sh))) for v in semi)
    cv2.ellipse(m, c, ax, angle_deg, 0, 360, 1, -1, cv2.LINE_8, sh)
    return m.astype(bool)


def _compose(face: float, layers: list[tuple[np.ndarray, float]], noise: float = 2.0, seed: int = 0,
             shape: tuple[int, int] = (H, W)) -> np.ndarray:
    """Layers (canvas mask, grey) painted in order over the face, area-averaged to pixels, noise, uint8."""
    big = np.full((shape[0] * S, shape[1] * S), float(face), np.float32)
    for m, g in layers:
        big[m] = g
    img = cv2.resize(big, (shape[1], shape[0]), interpolation=cv2.INTER_AREA)
    img = img + np.random.default_rng(seed).normal(0.0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def _case(name: str, seed: int = 0) -> np.ndarray:
    rim = _mask(CENTRE, SEMI, ANGLE_DEG)
    u = np.array([np.cos(np.radians(ANGLE_DEG)), np.sin(np.radians(ANGLE_DEG))])
    wall = rim & _mask(CENTRE + 0.35 * SEMI[0] * u, SEMI, ANGLE_DEG)
    bore = _mask(CENTRE + 1.5 * u, 0.72 * SEMI, ANGLE_DEG)
    floor = rim & _mask(CENTRE + 1.2 * np.array([-u[1], u[0]]), SEMI, ANGLE_DEG)
    layers = {"dark": (130, [(rim, 25)]),
              "crescent": (130, [(rim, 30), (wall, 165)]),
              "crescent_similar": (130, [(rim, 30), (wall, 142)]),
              "mirror": (130, [(rim, 20), (_mask(CENTRE, SEMI - 1.5, ANGLE_DEG), 255)]),
              "mirror_thin": (200, [(rim, 100), (floor, 255)]),
              "chamfer": (130, [(rim, 80), (bore, 20)]),
              "chamfer_bright": (130, [(rim, 200), (bore, 20)]),
              "plastic": (120, [(rim, 95)])}[name]
    return _compose(layers[0], layers[1], seed=seed)


def _prior(dc: tuple[float, float] = (2.0, -1.5), scale: float = 1.08, dangle_deg: float = 5.0) -> Ellipse:
    """The rim's ellipse, perturbed as a predicted pose would (full axes)."""
    angle = np.array([np.radians(ANGLE_DEG + dangle_deg)])
    return Ellipse(np.array([CENTRE + dc]), np.array([2 * SEMI * scale]), angle, np.array([True]))


def _error_px(kind: str, img: np.ndarray) -> float:
    """Distance (px) of the associated detection from the exact rim centre; NaN when none is associated."""
    got = associate(_prior(), detect(kind, img, predicted=_prior()), gate_px=10.0)[0]
    return float(np.linalg.norm(got - CENTRE))


@pytest.mark.parametrize(("angle_deg", "semi"), [(25.0, (25.0, 12.0)), (-50.0, (22.0, 14.0)), (120.0, (22.0, 14.0)),
                                                 (0.0, (20.0, 20.0))])
def test_edcircles_output_layout(angle_deg: float, semi: tuple[float, float]) -> None:
    """detectEllipses rows are (cx, cy, r, a, b, angle_deg): r the radius of a circle (a = b = 0), else a, b the
    semi-axes with angle_deg the a axis's angle in degrees; ``to_detections`` gives full axes, major first."""
    centre = np.array([70.31, 55.74])
    img = _compose(160, [(_mask(centre, np.array(semi), angle_deg, (120, 160)), 30)], noise=0.0, shape=(120, 160))
    ed = cv2.ximgproc.createEdgeDrawing()
    ed.detectEdges(img)
    rows = ed.detectEllipses().reshape(-1, 6)
    assert len(rows) == 1
    row = rows[0]
    np.testing.assert_allclose(row[:2], centre, atol=0.1)
    if semi[0] == semi[1]:
        assert row[2] == pytest.approx(semi[0], abs=0.1) and row[3] == row[4] == 0.0
    else:
        assert row[2] == 0.0
        assert sorted(row[3:5]) == pytest.approx(sorted(semi), abs=0.3)
        a_is_major = row[3] >= row[4]
        major_deg = row[5] if a_is_major else row[5] + 90.0
        assert (major_deg - angle_deg + 90.0) % 180.0 - 90.0 == pytest.approx(0.0, abs=1.5)
    det = to_detections(rows)
    np.testing.assert_allclose(det.axes_px[0], 2 * np.array(sorted(semi, reverse=True)), atol=0.6)
    if semi[0] != semi[1]:
        wrapped = (np.radians(angle_deg) + np.pi / 2) % np.pi - np.pi / 2
        assert det.angle_rad[0] == pytest.approx(wrapped, abs=np.radians(1.5))
    assert -np.pi / 2 <= det.angle_rad[0] < np.pi / 2


@pytest.mark.parametrize("name", CASES)
def test_cadfeat_detector_finds_the_outer_rim(name: str) -> None:
    errs = [_error_px("cadfeat", _case(name, seed)) for seed in range(3)]
    # (b), (b'): on the lit side the rim is a 35- (12-) grey step beside the wall's edge to the dark crescent;
    # measured worst of 3 seeds 0.09 (0.14) px; (c') the far wall's two edges 1.2 px apart: 0.17 px (0.38 px when
    # the refinement also smoothed by 0.8 px, RimSettings(fine_sigma_px=0.8)); the other cases ≤ 0.06 px
    tol = {"crescent": 0.15, "crescent_similar": 0.2, "mirror_thin": 0.25}.get(name, 0.1)
    assert max(errs) < tol, errs


def test_cadfeat_detector_fits_the_rim_shape() -> None:
    d = detect("cadfeat", _case("chamfer"), predicted=_prior())
    assert len(d) == 1
    np.testing.assert_allclose(d.axes_px[0], 2 * SEMI, atol=0.15)
    assert d.angle_rad[0] == pytest.approx(np.radians(ANGLE_DEG), abs=np.radians(0.5))
    assert d.residual_px[0] < 0.5


def test_edcircles_and_blob_are_sane_on_a_dark_hole() -> None:
    img = _case("dark")
    for kind in ("edcircles", "blob"):
        d = detect(kind, img)
        assert len(d) >= 1 and d.centre_px.shape == (len(d), 2) and d.axes_px.shape == (len(d), 2)
        assert np.all(d.axes_px[:, 0] >= d.axes_px[:, 1]) and np.all(np.abs(d.angle_rad) <= np.pi / 2)
        assert _error_px(kind, img) < 0.2, kind
        j = int(np.argmin(np.linalg.norm(d.centre_px - CENTRE, axis=1)))
        assert 2 * SEMI[1] * 0.8 < d.axes_px[j, 0] < 2 * SEMI[0] * 1.2, (kind, d.axes_px[j])


def test_other_detectors_measured() -> None:
    """Measured (seed 0; in brackets the worst of seeds 0–2 where it differs), recorded as facts, not
    requirements — centre error px, NaN = no detection associated:

    ================ ============ ============ ====== =========
    case             cadfeat      edcircles    blob   threshold
    ================ ============ ============ ====== =========
    dark             0.03         0.05         0.01   0.00
    crescent         0.06         0.87 (0.96)  NaN    NaN
    crescent_similar 0.07 (0.09)  0.21 (0.89)  NaN    NaN
    mirror           0.03         0.99 (1.01)  NaN    NaN
    mirror_thin      0.17         0.88 (0.89)  NaN    NaN
    chamfer          0.05         0.09 (0.12)  0.69   0.04
    chamfer_bright   0.02 (0.03)  1.56 (1.59)  1.12   1.49
    plastic          0.02 (0.04)  0.06         0.01   0.01
    ================ ============ ============ ====== =========

    EDCircles fits the lit/dark boundary inside the bore (crescent, mirror, mirror_thin) and, where the chamfer band is
    brighter than the face, the bore's edge (it finds both ellipses; the bore's centre is nearer the prior);
    the blob detector reports a dark region's centroid (the bore's, or nothing when the dark part is a crescent
    or a thin ring); the threshold detector (``detect_holes``, no prior) needs a dark region bounded by the rim
    (a dark chamfer band is part of it, a bright one is not)."""
    table = {name: [_error_px(k, _case(name)) for k in DETECTORS] for name in CASES}
    assert all(np.isfinite(v[0]) for v in table.values())
    assert np.isnan(_error_px_threshold("crescent")) and np.isnan(_error_px_threshold("mirror"))
    assert table["mirror_thin"][1] > 0.5                  # EDCircles: the far wall's edge to the floor
    assert table["chamfer_bright"][1] > 1.0               # EDCircles: the bore's edge, not the rim


def _error_px_threshold(name: str) -> float:
    got = associate(_prior(), detect_holes(_case(name)), gate_px=10.0)[0]
    return float(np.linalg.norm(got - CENTRE))


def test_a_neighbouring_face_edge_within_the_reach_is_not_the_rim() -> None:
    """A darker face beyond a straight edge 4 px right of the rim (inside the rays' reach, outside the surround
    ring): the rim is still found (measured on the flagship: an M5 hole beside the motor plate's edge)."""
    rim = _mask(CENTRE, SEMI, ANGLE_DEG)
    right = np.cos(np.radians(ANGLE_DEG)) ** 2 * SEMI[0] ** 2 + np.sin(np.radians(ANGLE_DEG)) ** 2 * SEMI[1] ** 2
    beyond = np.zeros_like(rim)
    beyond[:, int((CENTRE[0] + np.sqrt(right) + 4.0 + 0.5) * S):] = True
    errs = [_error_px("cadfeat", _compose(130, [(beyond, 100), (rim, 25)], seed=seed)) for seed in range(3)]
    assert max(errs) < 0.1, errs


def test_rejections() -> None:
    """Nothing is reported for a rim crossed by another edge, a prior farther off than the reach, a face
    without a hole, or a prior of the wrong size."""
    rim = _mask(CENTRE, SEMI, ANGLE_DEG)
    band = np.zeros_like(rim)
    band[:, (int(CENTRE[0] + 10) * S):] = True                      # a darker face beyond a vertical edge
    crossed = _compose(130, [(band, 70), (rim, 25)])
    assert len(detect("cadfeat", crossed, predicted=_prior())) == 0
    assert len(detect("cadfeat", _case("dark"), predicted=_prior(dc=(9.0, 0.0)))) == 0
    assert len(detect("cadfeat", _compose(130, []), predicted=_prior())) == 0
    assert len(detect("cadfeat", _case("dark"), predicted=_prior(scale=1.6))) == 0
    p = _prior()
    hidden = Ellipse(p.centre_px, p.axes_px, p.angle_rad, np.array([False]))        # not in front of the camera
    assert len(detect("cadfeat", _case("dark"), predicted=hidden)) == 0
    none = Ellipse(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0, bool))
    assert len(detect("cadfeat", _case("dark"), predicted=none)) == 0


def test_without_a_prior_cadfeat_is_the_threshold_detector() -> None:
    img = _case("dark")
    a, b = detect("cadfeat", img), detect_holes(img)
    np.testing.assert_array_equal(a.centre_px, b.centre_px)
    with pytest.raises(ValueError, match="unknown detector"):
        detect("hough", img)


def test_region_of_interest_and_distortion() -> None:
    """A region of interest gives the same centre (image px + origin); with a distorting camera the centre is
    the undistorted fit's (``detection.undistorted_centre``), independent reference as in
    test_detection_distortion.py: the pinhole ellipse's centre through the lens (``cv2.projectPoints``)."""
    cam = Camera.preset("dalsa-cad1-128a")
    normal = np.array([0.15, -0.1, -1.0]) / np.linalg.norm([0.15, -0.1, -1.0])
    c = np.array([-12.0, -9.0, 60.0])
    u = np.cross(normal, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    t = np.linspace(0.0, 2 * np.pi, 2000, endpoint=False)
    rim = c + 2.5 * (np.cos(t)[:, None] * u + np.sin(t)[:, None] * v)
    z = np.zeros(3)
    rim_px = cv2.projectPoints(rim.reshape(-1, 1, 3), z, z, cam.K, cam.dist_coeffs)[0].reshape(-1, 2)
    canvas = np.full((cam.height * S, cam.width * S), 200, np.uint8)
    cv2.fillPoly(canvas, [np.round((rim_px + 0.5) * S - 0.5).astype(np.int32)], 30)
    img = cv2.resize(canvas, (cam.width, cam.height), interpolation=cv2.INTER_AREA)
    (x0, y0), _, _ = cv2.fitEllipse(cv2.projectPoints(rim.reshape(-1, 1, 3), z, z, cam.K, np.zeros(5))[0]
                                    .reshape(-1, 2).astype(np.float32))
    ray = np.array([(x0 - cam.cx) / cam.fx, (y0 - cam.cy) / cam.fy, 1.0])
    expected = cv2.projectPoints(ray.reshape(1, 1, 3) * 50.0, z, z, cam.K, cam.dist_coeffs)[0].reshape(2)
    (px, py), (d1, d2), deg = cv2.fitEllipse(rim_px.astype(np.float32))
    major = np.radians(deg) if d1 >= d2 else np.radians(deg + 90)
    prior = Ellipse(np.array([[px + 1.0, py - 1.0]]), np.array([[max(d1, d2), min(d1, d2)]]), np.array([major]),
                    np.array([True]))
    fixed = detect("cadfeat", img, camera=cam, predicted=prior)
    plain = detect("cadfeat", img, predicted=prior)
    assert len(fixed) == 1 and len(plain) == 1
    err_fixed, err_plain = (float(np.linalg.norm(d.centre_px[0] - expected)) for d in (fixed, plain))
    assert err_fixed < 0.08 and err_plain > 2 * err_fixed, (err_fixed, err_plain)
    u0, v0 = (int(q) - 20 for q in fixed.centre_px[0])
    roi = detect("cadfeat", img[v0:, u0:], camera=cam, origin_px=(u0, v0), predicted=prior)
    np.testing.assert_allclose(roi.centre_px[0] + (u0, v0), fixed.centre_px[0], atol=1e-6)


def test_cadfeat_detector_on_raster_renders_of_a_part() -> None:
    """Real raster frames (the closed loop's renderer, as test_vision_closed_loop.py): a plate with four plain
    holes and a counterbore, four views, 2 grey levels of noise. With the predicted rim ellipses shifted by
    (1.5, −1) px as the prior, the rim detector finds every hole the threshold detector finds, within 0.3 px
    of the exact rim-ellipse centres (``measures.hole_ellipse``)."""
    cq = pytest.importorskip("cadquery")
    from cadfeat.cad.features import extract_holes, holes_to_arrays
    from cadfeat.measures import hole_ellipse
    from cadfeat.poses import invert_T, look_at
    from cadfeat.vision.images import render_sequence, sensor_images

    camera = Camera(fx=420.0, fy=420.0, cx=160.0, cy=120.0, width=320, height=240,
                    dist=(-0.12, 0.02, 0.0, 0.0, 0.0), focus_distance_mm=300.0)
    wp = cq.Workplane("XY").box(100, 80, 5).faces(">Z").workplane().pushPoints(
        [(-30, -20), (25, -15), (-10, 22), (30, 25)]).hole(8)
    wp = wp.faces(">Z").workplane().pushPoints([(0, 0)]).cboreHole(6, 12, 2)
    holes = extract_holes(wp)
    eyes = [(0, 0, 300), (60, -80, 260), (-90, 50, 250), (110, 40, 240)]
    T = np.stack([invert_T(look_at(np.array(e, float), np.array([0.0, 0.0, 2.5]), up=(0, 1, 0))) for e in eyes])
    images = sensor_images(render_sequence(wp.val(), holes, camera, T), 2.0, 3)
    centres, axes, radii = holes_to_arrays(holes)
    found, worst = {"cadfeat": 0, "threshold": 0}, 0.0
    for k in range(len(T)):
        e = hole_ellipse(camera, centres @ T[k, :3, :3].T + T[k, :3, 3], axes @ T[k, :3, :3].T, radii)
        prior = Ellipse(e.centre_px + np.array([1.5, -1.0]), e.axes_px, e.angle_rad, e.valid)
        ours = associate(e, detect("cadfeat", images[k], camera=camera, predicted=prior))
        theirs = associate(e, detect_holes(images[k], camera=camera))
        found["cadfeat"] += int(np.all(np.isfinite(ours), axis=1).sum())
        found["threshold"] += int(np.all(np.isfinite(theirs), axis=1).sum())
        worst = max(worst, float(np.nanmax(np.linalg.norm(ours - e.centre_px, axis=1))))
    assert found["cadfeat"] >= found["threshold"] and found["cadfeat"] >= 0.9 * len(T) * len(holes), found
    assert worst < 0.3, worst
