"""The equal-weight estimator's error (``measures.pose_estimator.equal_weight_errors``) against ``cv2.solvePnP``.

Independent reference: a Monte-Carlo of ``cv2.solvePnP`` (iterative, refined from the true pose: the closed loop's
PnP minimises the unweighted reprojection error) on point features whose image noise differs from point to point
(σ_j) and which carry fixed offsets b_j. The RMS translation and rotation errors over the draws must match the
equal-weight least squares' √(bias² + tr G Σ Gᵀ) within 10 %; the CRLB (1/σ_j² weights, ``pose_information``) is
lower than what that estimator reaches when the σ_j differ (the reason the panel reports both).
"""

from __future__ import annotations

import cv2
import numpy as np

from cadfeat.camera import Camera
from cadfeat.measures.pose_estimator import equal_weight_errors
from cadfeat.measures.pose_information import pose_information

CAMERA = Camera(fx=900.0, fy=900.0, cx=320.0, cy=240.0, width=640, height=480, focus_distance_mm=300.0)
DRAWS = 3000


def _scene():
    rng = np.random.default_rng(3)
    pts = np.column_stack([rng.uniform(-40, 40, 8), rng.uniform(-30, 30, 8), rng.uniform(-15, 15, 8)])
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(np.array([0.3, -0.2, 0.1]))[0]
    T[:3, 3] = [5.0, -3.0, 300.0]
    sigma = np.array([0.05, 0.05, 0.05, 0.05, 0.4, 0.4, 0.8, 0.8])       # px, very different per point
    offset = rng.normal(0.0, 0.1, (8, 2))                                 # px, fixed per point
    return pts, T, sigma, offset


def test_equal_weight_errors_match_a_solvepnp_monte_carlo():
    pts, T, sigma, offset = _scene()
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    pi = pose_information(CAMERA, T[None], pts, normals, np.zeros(len(pts)), sigma_px=sigma[None],
                          detection=False, offset_px=offset[None])
    eq = equal_weight_errors(pi)
    pred_t, pred_r = eq.translation_mm, eq.rotation_deg
    rng = np.random.default_rng(7)
    rvec0, tvec0 = cv2.Rodrigues(T[:3, :3])[0], T[:3, 3].copy()
    clean = CAMERA.project(pts @ T[:3, :3].T + T[:3, 3])
    et, er = [], []
    for _ in range(DRAWS):
        z = clean + offset + rng.standard_normal(clean.shape) * sigma[:, None]
        ok, rvec, tvec = cv2.solvePnP(pts, z, CAMERA.K, None, rvec0.copy(), tvec0.copy(), useExtrinsicGuess=True,
                                      flags=cv2.SOLVEPNP_ITERATIVE)
        assert ok
        R = cv2.Rodrigues(rvec)[0]
        et.append(np.linalg.norm(tvec.ravel() - T[:3, 3]))
        er.append(np.degrees(np.linalg.norm(cv2.Rodrigues(R @ T[:3, :3].T)[0])))
    mc_t, mc_r = np.sqrt(np.mean(np.square(et))), np.sqrt(np.mean(np.square(er)))
    assert abs(pred_t[0] / mc_t - 1.0) < 0.1, (pred_t[0], mc_t)
    assert abs(pred_r[0] / mc_r - 1.0) < 0.1, (pred_r[0], mc_r)
    # the CRLB-weighted prediction (what g_POSE uses) is well below this estimator's error here
    assert pi.error_translation_mm[0] < 0.8 * mc_t and pi.error_rotation_deg[0] < 0.8 * mc_r
