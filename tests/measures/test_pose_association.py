"""The detection model's association term (``PoseModels.association``) against the closed loop's association.

Independent reference: a Monte-Carlo of the cell's placement error (translation and rotation about the part's
origin, N(0, σ²) per axis, as ``vision.closed_loop.placement_errors`` draws them), the rim centres at each placed
pose from ``measures.hole_ellipse``, matched by ``vision.detection.associate`` (the closed loop's code) against the
predictions at the nominal pose. A hole on the far face whose predicted centre falls a few px from a seen hole's
shrinks that hole's gate (½ the distance): the fraction of draws in which the seen hole is still matched must
agree with the model's a(G) = 1 − exp(−G²/(2σ̄²)).
"""

from __future__ import annotations

import numpy as np
import pytest

from cadfeat.camera import Camera
from cadfeat.measures import hole_ellipse
from cadfeat.measures.pose_models import PoseModels, hole_geometry
from cadfeat.poses import invert_T, look_at
from cadfeat.vision.detection import Detections, associate
from cadfeat.vision.motion import so3_exp

CAMERA = Camera(fx=1200.0, fy=1200.0, cx=320.0, cy=240.0, width=640, height=480, focus_distance_mm=250.0)
DRAWS = 3000


def _scene(offset_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Hole 0 on the top face (seen), hole 1 on the bottom face 5 mm below (facing away), ``offset_mm`` apart
    along x; the camera 250 mm away, 35° off the top face's normal, looking at a point 20 mm from the origin
    (an offset near −5 · tan 35° = −3.5 mm puts the far hole's image next to the seen hole's)."""
    centres = np.array([[12.0, 8.0, 0.0], [12.0 + offset_mm, 8.0, -5.0]])
    normals = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    radii = np.array([2.0, 2.0])
    a = np.radians(35.0)
    eye = 250.0 * np.array([np.sin(a), 0.0, np.cos(a)])
    T = invert_T(look_at(eye, np.array([20.0, 0.0, 0.0]), up=(0.0, 1.0, 0.0)))
    return T, centres, normals, radii


def _matched_fraction(T: np.ndarray, centres: np.ndarray, normals: np.ndarray, radii: np.ndarray,
                      models: PoseModels) -> float:
    rng = np.random.default_rng(5)
    R, t = T[:3, :3], T[:3, 3]
    nominal = hole_ellipse(CAMERA, centres @ R.T + t, normals @ R.T, radii)
    hits = 0
    for _ in range(DRAWS):
        d = np.eye(4)
        d[:3, 3] = rng.normal(0.0, models.placement_mm, 3)
        d[:3, :3] = so3_exp(np.radians(rng.normal(0.0, models.placement_deg, 3)))
        Tp = T @ d
        true = hole_ellipse(CAMERA, centres @ Tp[:3, :3].T + Tp[:3, 3], normals @ Tp[:3, :3].T, radii)
        seen = Detections(np.asarray(true.centre_px)[:1], np.asarray(true.axes_px)[:1], np.zeros(1), np.zeros(1))
        hits += bool(np.all(np.isfinite(associate(nominal, seen, models.gate_px)[0])))
    return hits / DRAWS


@pytest.mark.parametrize("offset_mm", [-4.4, -3.7, -3.4])
def test_association_matches_the_closed_loops_gate(offset_mm):
    models = PoseModels()
    T, c, n, r = _scene(offset_mm)
    geo = hole_geometry(CAMERA, T[None], c, n, r)
    assert geo.half_spacing_px is not None
    gate = float(geo.half_spacing_px[0, 0])
    assert 0.3 < gate < 8.0                        # the far hole's prediction shrinks the seen hole's gate
    model = float(np.asarray(models.association(geo))[0, 0])
    mc = _matched_fraction(T, c, n, r, models)
    assert abs(model - mc) < 0.04, (gate, model, mc)          # measured: within 0.006 (3000 draws: ±0.009)


def test_association_is_one_where_holes_are_apart_and_without_placement_error():
    T, c, n, r = _scene(20.0)
    geo = hole_geometry(CAMERA, T[None], c, n, r)
    assert float(np.asarray(PoseModels().association(geo))[0, 0]) > 0.999
    T, c, n, r = _scene(-3.5)
    geo = hole_geometry(CAMERA, T[None], c, n, r)
    exact = PoseModels(placement_mm=0.0, placement_deg=0.0)
    assert float(np.asarray(exact.association(geo))[0, 0]) == pytest.approx(1.0)


def test_association_settings_are_the_closed_loops_defaults():
    from cadfeat.vision.closed_loop import TrackingConfig

    m, cfg = PoseModels(), TrackingConfig()
    assert (m.gate_px, m.placement_mm, m.placement_deg) == (cfg.gate_px, cfg.placement_mm, cfg.placement_deg)
