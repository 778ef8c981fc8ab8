"""Physically based camera images (``render.pbr.PbrRenderer``, Mitsuba 3) against independent geometry.

References: ``Camera.project`` (the OpenCV model, cross-checked with ``cv2.projectPoints``) for points, and
``measures.hole_ellipse`` for a hole's rim; the camera has fx ≠ fy, an off-centre principal point and lens
distortion, so each of the renderer's steps (fov, principal point's half-pixel shift, the row resampling, the
distortion remap) shows as a shift if it is wrong.

- Thin dark discs parallel to the image plane against the uniform dome (the background reads exactly the dome's
  radiance): the pinhole image of each is a circle centred on its centre's projection, so the centroid of
  (background − image) — pixels integrate over their area (box filter) — lands on ``Camera.project`` of its
  centre (distortion adds ≲ 0.01 px over a 6 px disc).
- A deep blind hole seen at ~30° under a spot light behind the camera: a matt face, a darker far wall (cosine
  law), the floor hidden; edge points where each ray from the predicted centre crosses the level midway between
  the face and the bore, an ellipse fitted to them (``cv2.fitEllipse``).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

pytest.importorskip("mitsuba")
cq = pytest.importorskip("cadquery")

from cadfeat.camera import Camera  # noqa: E402
from cadfeat.cell.light import Light  # noqa: E402
from cadfeat.cell.material import Material  # noqa: E402
from cadfeat.measures import hole_ellipse  # noqa: E402
from cadfeat.poses import invert_T, look_at  # noqa: E402
from cadfeat.render import CameraRenderer, RenderError, camera_renderer, grey_sequence  # noqa: E402
from cadfeat.render.pbr import PbrRenderer, row_resampling  # noqa: E402

CAMERA = Camera(fx=400.0, fy=430.0, cx=81.3, cy=62.7, width=160, height=128, focus_distance_mm=100.0,
                dist=(-0.12, 0.04, 0.001, -0.002, 0.0))
DISC_CENTRES = np.array([[0.0, 0.0, 0.0], [12.0, 5.0, 0.0], [-10.0, -8.0, 0.0], [9.0, -9.0, 0.0]])
DISC_RADIUS_MM = 1.5
WINDOW_PX = 11


def _discs() -> object:
    """Thin discs (20 µm) facing +z at ``DISC_CENTRES``: their top faces' centres are the centres given."""
    pts = [(float(x), float(y)) for x, y, _ in DISC_CENTRES]
    return cq.Workplane("XY").workplane(offset=-0.02).pushPoints(pts).circle(DISC_RADIUS_MM).extrude(0.02).val()


def _centroid(weights: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Weighted centroid (x, y) px of ``weights`` in a window of ±WINDOW_PX around ``at``."""
    u0, v0 = (int(round(a)) for a in at)
    win = weights[v0 - WINDOW_PX:v0 + WINDOW_PX + 1, u0 - WINDOW_PX:u0 + WINDOW_PX + 1].astype(float)
    v, u = np.mgrid[v0 - WINDOW_PX:v0 + WINDOW_PX + 1, u0 - WINDOW_PX:u0 + WINDOW_PX + 1]
    return np.array([(win * u).sum(), (win * v).sum()]) / win.sum()


def test_projected_points_land_within_a_tenth_of_a_pixel():
    T = invert_T(look_at(np.array([2.0, -1.5, 100.0]), np.array([2.0, -1.5, 0.0]), up=(0.3, 1.0, 0.0)))
    light = Light(kind="dome", intensity=1.0)
    with PbrRenderer(_discs(), [], CAMERA, light=light, material=Material(name="black_anodised"), spp=16) as r:
        image = r.render(T)
    assert image.shape == (CAMERA.height, CAMERA.width) and image.dtype == np.float32
    centres_cam = DISC_CENTRES @ T[:3, :3].T + T[:3, 3]
    expected = CAMERA.project(centres_cam)
    rvec, _ = cv2.Rodrigues(np.eye(3))
    cv_px, _ = cv2.projectPoints(centres_cam, rvec, np.zeros(3), CAMERA.K, CAMERA.dist_coeffs)
    np.testing.assert_allclose(expected, cv_px.reshape(-1, 2), atol=1e-6)        # the reference is OpenCV's
    background = np.median(image)
    assert background == pytest.approx(1.0, abs=1e-3)                            # the dome seen directly
    found = np.array([_centroid(background - image, p) for p in expected])
    error = np.linalg.norm(found - expected, axis=1)
    assert error.max() < 0.1, f"centroid errors {error} px"


def test_fx_fy_and_the_principal_point_are_not_ignored():
    """The same check fails by pixels when fy is taken equal to fx (the test can tell)."""
    T = invert_T(look_at(np.array([2.0, -1.5, 100.0]), np.array([2.0, -1.5, 0.0]), up=(0.3, 1.0, 0.0)))
    square = CAMERA.replace(fy=CAMERA.fx)
    with PbrRenderer(_discs(), [], square, light=Light(kind="dome"), material=Material(name="black_anodised"),
                     spp=4) as r:
        image = r.render(T)
    expected = CAMERA.project(DISC_CENTRES @ T[:3, :3].T + T[:3, 3])
    found = np.array([_centroid(1.0 - image, p) for p in expected])
    assert np.linalg.norm(found - expected, axis=1).max() > 1.0


def _edge_points(image: np.ndarray, centre: np.ndarray, radius_px: float, rays: int = 120) -> np.ndarray:
    """Where each ray from ``centre`` first crosses, going outward, the level midway between the bore (2 px inside
    the edge) and the face (2 px outside), searched between 0.5 and 1.6 × ``radius_px`` (bilinear samples)."""
    phi = np.linspace(0, 2 * np.pi, rays, endpoint=False)
    s = np.arange(0.4 * radius_px, 1.8 * radius_px, 0.05)
    d = np.stack([np.cos(phi), np.sin(phi)], axis=-1)
    pts = centre[None, None, :] + s[None, :, None] * d[:, None, :]                 # (rays, S, 2)
    prof = cv2.remap(image, pts[..., 0].astype(np.float32), pts[..., 1].astype(np.float32), cv2.INTER_LINEAR)
    face = np.median(image)
    step = int(round(2.0 / 0.05))
    out = []
    for k in range(rays):                                                          # loop over rays: a test helper
        p = prof[k]
        i = int(np.argmax(p > 0.5 * face + 0.5 * p[: len(p) // 3].mean()))      # first clearly-face sample
        inner, outer = p[max(i - step, 0)], p[min(i + step, len(p) - 1)]
        level = 0.5 * (inner + outer)
        j = max(i - step, 0) + int(np.argmax(p[max(i - step, 0):] >= level))
        t = (level - p[j - 1]) / (p[j] - p[j - 1])
        out.append(centre + (s[j - 1] + t * 0.05) * d[k])
    return np.array(out)


def test_hole_rim_ellipse_centre_matches_hole_ellipse():
    plate = cq.Workplane("XY").box(40, 40, 15).faces(">Z").workplane().hole(5.0, 12.0)
    from cadfeat.cad.features import extract_holes

    holes = extract_holes(plate)
    eye = np.array([4.0, -45.0, 7.5 + 80.0])
    T = invert_T(look_at(eye, np.array([1.0, 0.0, 7.5]), up=(0.0, 1.0, 0.0)))
    behind = eye + 30.0 * (eye - np.array([1.0, 0.0, 7.5])) / np.linalg.norm(eye - np.array([1.0, 0.0, 7.5]))
    light = Light(kind="spot", position_mm=tuple(behind), target_mm=(0.0, 0.0, 7.5), cutoff_deg=40.0,
                  beam_deg=35.0)
    with PbrRenderer(plate, holes, CAMERA, light=light, material=Material(name="grey_plastic"), spp=16) as r:
        image = r.render(T)
    h = holes[0]
    predicted = hole_ellipse(CAMERA, T[:3, :3] @ h.centre + T[:3, 3], T[:3, :3] @ h.axis, h.radius_mm)
    centre = np.asarray(predicted.centre_px)
    edges = _edge_points(image, centre, float(np.asarray(predicted.axes_px)[0]) / 2)
    (fx, fy), (a, b), _ = cv2.fitEllipse(edges.astype(np.float32))
    assert abs(max(a, b) - float(np.asarray(predicted.axes_px)[0])) < 0.5
    assert np.hypot(fx - centre[0], fy - centre[1]) < 0.3


def test_row_resampling_is_an_area_mean():
    """Each output row is the mean of the input over its span (a constant stays, a step keeps its area)."""
    M = row_resampling(10, 11, 1.075)
    np.testing.assert_allclose(M.sum(axis=1), 1.0, atol=1e-6)
    step = (np.arange(11) < 4.0).astype(float)                 # input edge at 4.0 → output edge at 4 / 1.075
    assert (M @ step).sum() == pytest.approx(4.0 / 1.075, abs=1e-5)


def test_interface_and_factory():
    T = invert_T(look_at(np.array([0.0, 0.0, 100.0]), np.zeros(3), up=(0.0, 1.0, 0.0)))
    with camera_renderer("pbr", _discs(), [], CAMERA, light=Light(kind="dome"), spp=1) as r:
        assert isinstance(r, CameraRenderer)
        frames = grey_sequence(r, np.stack([T, T]))
        assert frames.shape == (2, CAMERA.height, CAMERA.width) and frames.dtype == np.float32
        assert 0.0 <= frames.min() and frames.max() <= 255.0
        assert r.estimate_seconds(T) > 0
    with camera_renderer("raster", _discs(), [], CAMERA) as raster:
        assert isinstance(raster, CameraRenderer)
        grey = raster.render_grey(T)
        np.testing.assert_allclose(grey, cv2.cvtColor(raster.render(T), cv2.COLOR_RGB2GRAY), atol=0.51)
    with pytest.raises(RenderError, match="allowed: raster, pbr"):
        camera_renderer("opengl", _discs(), [], CAMERA)
    with pytest.raises(RenderError, match="hole_ends"):
        PbrRenderer(_discs(), [], CAMERA, hole_ends="reamed")


def test_drilled_ends_change_only_the_blind_holes_floor():
    """A Ø6 blind hole 3 mm deep seen head-on under the coaxial light: ``hole_ends="drilled"`` changes the image
    only inside the rim (the face outside is the same part, the same light, the same sampler seeds: identical),
    and the cone's facets (normals 31° off the axis) send blasted aluminium's glossy lobe away from the lens: the
    floor reads darker than the flat one, which sends it straight back (≈ 0.4 of it here)."""
    plate = cq.Workplane("XY").box(30, 30, 10).faces(">Z").workplane().hole(6.0, 3.0)
    from cadfeat.cad.features import extract_holes

    holes = extract_holes(plate)
    T = invert_T(look_at(np.array([0.0, 0.0, 5.0 + 90.0]), np.array([0.0, 0.0, 5.0]), up=(0.0, 1.0, 0.0)))
    light = Light(kind="coaxial", reference_mm=90.0)
    images = {}
    for ends in ("milled", "drilled"):
        with PbrRenderer(plate, holes, CAMERA.replace(dist=(0.0, 0.0, 0.0, 0.0, 0.0)), light=light,
                         material=Material(name="blasted_aluminium"), spp=16, hole_ends=ends) as r:
            images[ends] = r.render(T)
    centre = CAMERA.project(np.array([[0.0, 0.0, 90.0]]))[0]
    v, u = np.mgrid[:CAMERA.height, :CAMERA.width]
    rho = np.hypot((u - centre[0]) / CAMERA.fx, (v - centre[1]) / CAMERA.fy) * 90.0     # mm on the face plane
    outside, floor = rho > 3.0 + 0.5, rho < 2.0
    diff = np.abs(images["drilled"] - images["milled"])
    assert diff[outside].max() < 1e-3 * images["milled"][outside].max()
    assert images["drilled"][floor].mean() < 0.95 * images["milled"][floor].mean()
    assert images["drilled"][floor].mean() > 0.2 * images["milled"][floor].mean()


@pytest.mark.parametrize("kind", ["ring", "coaxial", "dome", "spot"])
def test_light_strength_reads_as_irradiance_on_a_white_target(kind):
    """A Lambertian white target (reflectance 0.99) facing the camera at the light's reference distance reads
    0.99 × intensity at the image centre: the emitters' strengths (``cell.light.emitter_strength``: closed-form
    irradiance of a disc, an annulus, a point, a hemisphere) agree with the path tracer's radiometry."""
    D = 250.0
    target = cq.Workplane("XY").box(400, 400, 2).translate((0, 0, -1)).val()
    eye = np.array([0.0, 0.0, D])
    T = invert_T(look_at(eye, np.zeros(3), up=(0.0, 1.0, 0.0)))
    light = Light(kind=kind, intensity=0.6, reference_mm=D, position_mm=(0.0, 0.0, D), target_mm=(0.0, 0.0, 0.0))
    cam = Camera(fx=200.0, fy=200.0, cx=31.5, cy=23.5, width=64, height=48, focus_distance_mm=D)
    with PbrRenderer(target, [], cam, light=light, material=Material(name="white_reference"), spp=64) as r:
        image = r.render(T)
    centre = image[20:28, 28:36].mean()        # ±4 px: ±5 mm on the target, irradiance flat there to < 0.1 %
    assert centre == pytest.approx(0.99 * 0.6, rel=0.01)


@pytest.fixture
def scalar_variant():
    """Mitsuba's plain C++ variant for one test (the process-global variant is restored after it)."""
    from cadfeat.render.pbr_scene import use_variant

    before = use_variant()
    yield use_variant("scalar_rgb")
    use_variant(before)


def test_scalar_variant_projects_the_same(scalar_variant):
    """The fallback variant (no LLVM) renders the same geometry: disc centroids on ``Camera.project``."""
    T = invert_T(look_at(np.array([2.0, -1.5, 100.0]), np.array([2.0, -1.5, 0.0]), up=(0.3, 1.0, 0.0)))
    with PbrRenderer(_discs(), [], CAMERA, light=Light(kind="dome"), material=Material(name="black_anodised"),
                     spp=4, variant=scalar_variant) as r:
        assert r.variant == "scalar_rgb"
        image = r.render(T)
    expected = CAMERA.project(DISC_CENTRES @ T[:3, :3].T + T[:3, 3])
    found = np.array([_centroid(1.0 - image, p) for p in expected])
    assert np.linalg.norm(found - expected, axis=1).max() < 0.15


def test_the_part_window_is_the_same_image_at_the_cost_of_the_part():
    """``crop`` path-traces only ``part_window`` and gives the rest the background's radiance. Reference: the whole
    film path-traced (``crop=False``): outside the window it reads the background to float32 round-off (a ray that
    misses the part sees only the dome/ambient), and inside it the two images differ by sampling noise only — no
    more than two whole-film renders with different seeds differ. A camera with fx ≠ fy and distortion: the window
    is found in the rendered film, before the row resampling and the remap."""
    plate = cq.Workplane("XY").box(40, 30, 6).faces(">Z").workplane().pushPoints([(-10, 0), (10, 4)]).hole(5.0, 4.0)
    from cadfeat.cad.features import extract_holes

    holes = extract_holes(plate)
    T = invert_T(look_at(np.array([0.0, -75.0, 130.0]), np.array([2.0, 0.0, 3.0]), up=(0.0, 1.0, 0.0)))
    light = Light(kind="ring", ambient=0.05)
    kwargs = {"light": light, "material": Material(name="machined_aluminium"), "spp": 16}
    with PbrRenderer(plate, holes, CAMERA, crop=False, **kwargs) as full, \
            PbrRenderer(plate, holes, CAMERA, crop=True, seed=50, **kwargs) as cropped:
        x, y, w, h = cropped.part_window(T)
        film = full.render_raw(T)
        assert film.shape == (cropped.render_height, cropped.pinhole.width)
        assert w * h < 0.6 * film.size                                          # the point of it
        outside = np.ones(film.shape, bool)
        outside[y:y + h, x:x + w] = False
        np.testing.assert_allclose(film[outside], 0.05, rtol=1e-6)              # (ambient / π) × π
        np.testing.assert_allclose(cropped.render_film(T)[outside], film[outside], rtol=1e-6)  # what a miss reads
        a, b, c = full.render(T), full.render(T), cropped.render(T)
    assert c.shape == a.shape
    noise = np.sqrt(np.mean((a - b) ** 2))
    assert noise > 0 and np.sqrt(np.mean((c - a) ** 2)) < 1.3 * noise


def test_the_image_does_not_depend_on_the_thread_count():
    """A check beside the optimiser renders on one thread (``closed_loop_check._track_design``): the same image
    as on every core, bit for bit (the sampler's seed is per pixel and frame, not per thread)."""
    import drjit as dr

    plate = cq.Workplane("XY").box(40, 30, 6).faces(">Z").workplane().pushPoints([(-10, 0), (10, 4)]).hole(5.0, 4.0)
    from cadfeat.cad.features import extract_holes

    T = invert_T(look_at(np.array([0.0, -75.0, 130.0]), np.array([2.0, 0.0, 3.0]), up=(0.0, 1.0, 0.0)))
    before = dr.thread_count()
    images = []
    try:
        for n in (1, 2):
            dr.set_thread_count(n)
            with PbrRenderer(plate.val(), extract_holes(plate), CAMERA, spp=4) as r:
                images.append(r.render(T))
    finally:
        dr.set_thread_count(before)
    assert np.array_equal(images[0], images[1])
