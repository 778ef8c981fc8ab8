"""Pose tracking (EKF, IEKF, solvePnP) against independent references.

Measurements come from ``cv2.projectPoints`` (points) or from the exact rim conic of ``measures.hole_ellipse``
(rim ellipse centres) along a constant-velocity trajectory (the filters' process model, so noise-free data has
an exact answer). Noise-free: every method reaches the true pose to 1e-6 mm. With noise: NEES over Monte-Carlo
runs within its χ² bounds, errors comparable to solvePnP, and the IEKF converges from initial errors the EKF
does not (thesis §6.3.3), with both basins measured.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.stats import chi2

from cadfeat.camera import Camera
from cadfeat.measures import hole_ellipse
from cadfeat.poses import make_T
from cadfeat.vision import FilterTuning, TrackingError, estimate_poses
from cadfeat.vision.metrics import pose_errors
from cadfeat.vision.motion import so3_exp, so3_log

pytestmark = pytest.mark.numerics  # run again under another BLAS kernel (Makefile: test)

CAMERA = Camera(fx=800.0, fy=790.0, cx=320.0, cy=240.0, width=640, height=480,
                dist=(-0.2, 0.05, 0.001, -0.002, 0.0))
X = np.array([[-40, -30, 0], [40, -30, 0], [40, 30, 0], [-40, 30, 0], [0, 0, 12], [15, -10, -6]], float)
NORMALS = np.tile([0.0, 0.0, -1.0], (6, 1))
RADII = np.full(6, 4.0)
F, DT = 40, 0.05
TIMES = np.arange(F) * DT


def _truth(w=(0.1, -0.2, 0.3), v=(20.0, -10.0, 30.0)):
    R0, p0 = so3_exp(np.array([0.3, -0.2, 0.1])), np.array([5.0, -3.0, 300.0])
    return np.stack([make_T(so3_exp(np.array(w) * t) @ R0, p0 + np.array(v) * t) for t in TIMES])


def _project(T):
    return np.stack([cv2.projectPoints(X, so3_log(Tk[:3, :3]), Tk[:3, 3], CAMERA.K, CAMERA.dist_coeffs)[0][:, 0]
                     for Tk in T])


def _perturb(T, mm, deg, seed=0):
    rng = np.random.default_rng(seed)
    u, w = rng.normal(size=3), rng.normal(size=3)
    T0 = T.copy()
    T0[:3, 3] += mm * u / np.linalg.norm(u)
    T0[:3, :3] = so3_exp(np.radians(deg) * w / np.linalg.norm(w)) @ T0[:3, :3]
    return T0


EXACT = FilterTuning(r_px2=1e-8, q_rate_mm2_s2=1e-6, q_omega_rad2_s2=1e-10)


@pytest.mark.parametrize("method", ["ekf", "iekf", "pnp"])
def test_noise_free_points_reach_the_true_pose(method):
    T = _truth()
    track = estimate_poses(CAMERA, X, _project(T), TIMES, method, _perturb(T[0], 10.0, 3.0), tuning=EXACT)
    et, er = pose_errors(track.T_cam_part, T)
    assert track.T_cam_part.shape == (F, 4, 4) and track.covariance.shape[0] == F
    assert et[-1] < 1e-6 and er[-1] < 1e-6  # mm, deg


@pytest.mark.parametrize("method", ["ekf", "iekf", "pnp"])
def test_rim_centres_need_the_rim_model(method):
    """Measured = ellipse centres (exact conic): with the rim model exact, as points biased."""
    T = _truth()
    c = np.einsum("fij,nj->fni", T[:, :3, :3], X) + T[:, None, :3, 3]
    n = np.einsum("fij,nj->fni", T[:, :3, :3], NORMALS)
    pixels = hole_ellipse(CAMERA, c, n, RADII).centre_px
    T0 = _perturb(T[0], 10.0, 3.0)
    rim = estimate_poses(CAMERA, X, pixels, TIMES, method, T0, normals_part=NORMALS, radii_mm=RADII, tuning=EXACT)
    point = estimate_poses(CAMERA, X, pixels, TIMES, method, T0, tuning=EXACT)
    assert pose_errors(rim.T_cam_part, T)[0][-1] < 1e-6
    assert pose_errors(point.T_cam_part, T)[0][-5:].min() > 1e-3


def test_missing_detections_and_lost_frames():
    T = _truth()
    pixels = _project(T)
    pixels[5:8, :3] = np.nan     # three holes missing: PnP lost, filters keep going on the other three
    pixels[20] = np.nan          # nothing detected: prediction only
    for method in ("ekf", "iekf", "pnp"):
        track = estimate_poses(CAMERA, X, pixels, TIMES, method, _perturb(T[0], 5.0, 1.0), tuning=EXACT)
        lost = track.lost
        if method == "pnp":
            assert set(np.flatnonzero(lost)) == {5, 6, 7, 20}
        else:
            assert not lost.any() and track.n_measured[6] == 3 and track.n_measured[20] == 0
        assert pose_errors(track.T_cam_part, T)[0][-1] < 1e-6


def test_bad_input_is_refused():
    with pytest.raises(TrackingError, match="method"):
        estimate_poses(CAMERA, X, _project(_truth()), TIMES, "ukf")
    with pytest.raises(TrackingError, match="pixels"):
        estimate_poses(CAMERA, X, np.zeros((F, 5, 2)), TIMES)
    with pytest.raises(TrackingError, match="times_s"):
        estimate_poses(CAMERA, X, _project(_truth()), TIMES[::-1])


def _monte_carlo(method, runs, sigma_px, tuning, seed=0):
    T = _truth()
    clean = _project(T)
    rng = np.random.default_rng(seed)
    pixels = clean[None] + sigma_px * rng.standard_normal((runs, F, len(X), 2))
    P0 = tuning.P0()
    T0 = np.empty((runs, 4, 4))
    for r in range(runs):  # initial errors drawn from P0 itself (what consistency assumes)
        d = rng.normal(size=6) * np.sqrt(np.diag(P0)[:6])
        T0[r] = make_T(so3_exp(d[3:]) @ T[0, :3, :3], T[0, :3, 3] + d[:3])
    track = estimate_poses(CAMERA, X, pixels, TIMES, method, T0, tuning=tuning)
    return T, track


@pytest.mark.parametrize("method", ["ekf", "iekf"])
def test_nees_within_chi2_bounds(method):
    """Average NEES of the 6 pose states over 40 runs, frames 10..39: inside the two-sided 99 % χ² interval."""
    runs, sigma = 40, 0.5
    tuning = FilterTuning(r_px2=sigma**2, q_rate_mm2_s2=1e-2, q_omega_rad2_s2=1e-6, sigma0_mm=5.0, sigma0_rad=0.02,
                          sigma0_rate_mm_s=50.0, sigma0_omega_rad_s=0.5)
    T, track = _monte_carlo(method, runs, sigma, tuning)
    Te = track.T_cam_part
    e = np.concatenate([T[None, :, :3, 3] - Te[..., :3, 3],
                        so3_log(T[None, :, :3, :3] @ np.swapaxes(Te[..., :3, :3], -1, -2))], axis=-1)  # (R, F, 6)
    nees = np.einsum("rfi,rfi->rf", e, np.linalg.solve(track.pose_covariance, e[..., None])[..., 0])
    mean = nees[:, 10:].mean(axis=0)                                        # per frame, over runs
    lo, hi = chi2.ppf([0.005, 0.995], 6 * runs) / runs
    assert np.mean((mean > lo) & (mean < hi)) >= 0.9, (mean.round(2), lo, hi)
    assert lo < mean.mean() < hi


def test_filters_comparable_to_pnp_with_noise():
    tuning = FilterTuning(r_px2=0.25, q_rate_mm2_s2=1e-2, q_omega_rad2_s2=1e-6)
    rms = {}
    for method in ("ekf", "iekf", "pnp"):
        T, track = _monte_carlo(method, 10, 0.5, tuning, seed=3)
        et, _ = pose_errors(track.T_cam_part, T[None])
        rms[method] = float(np.sqrt(np.mean(et[:, 10:] ** 2)))
    assert rms["ekf"] < 1.5 * rms["pnp"] and rms["iekf"] < 1.5 * rms["pnp"], rms


def _basin(method, sizes_mm, deg_per_mm):
    """Largest initial error (mm; with rotation deg_per_mm·mm) from which all 4 random directions converge to
    < 0.5 mm within 10 frames (thesis: 'steady state in the first five sampling periods', doubled)."""
    T = _truth()
    pixels = _project(T)
    tuning = FilterTuning(r_px2=0.01, q_rate_mm2_s2=1.0, q_omega_rad2_s2=1e-4, sigma0_mm=100.0, sigma0_rad=0.5)
    ok_size = 0.0
    for size in sizes_mm:
        T0 = np.stack([_perturb(T[0], size, deg_per_mm * size, seed=s) for s in range(4)])
        track = estimate_poses(CAMERA, X, np.broadcast_to(pixels, (4,) + pixels.shape), TIMES, method, T0,
                               tuning=tuning)
        et, _ = pose_errors(track.T_cam_part, T[None])
        if not np.all(np.nan_to_num(et[:, 10:], nan=np.inf) < 0.5):
            break
        ok_size = size
    return ok_size


def test_iekf_basin_larger_than_ekf_basin():
    """Thesis §6.3.3: the IEKF converges from larger initial errors than the EKF. Measured here (6 holes at
    300 mm, 640×480): EKF 80 mm / 8°, IEKF at least 160 mm / 16° (the largest size scanned)."""
    sizes = [10.0, 20.0, 40.0, 80.0, 120.0, 160.0]
    ekf, iekf = _basin("ekf", sizes, 0.1), _basin("iekf", sizes, 0.1)
    print(f"basin: EKF {ekf} mm, IEKF {iekf} mm (rotation 0.1 deg per mm)")
    assert iekf > ekf > 0


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-5, 1e-3, 0.5, 3.0, np.pi - 1e-4, np.pi])
def test_rotation_parametrisation_matches_scipy(angle):
    """The filters' exp/log of SO(3) (own closed forms with series) against scipy's quaternion route."""
    from scipy.spatial.transform import Rotation

    w = np.random.default_rng(1).normal(size=(20, 3))
    w *= angle / np.linalg.norm(w, axis=1, keepdims=True)
    R = Rotation.from_rotvec(w).as_matrix()
    np.testing.assert_allclose(so3_exp(w), R, atol=1e-13)
    np.testing.assert_allclose(so3_exp(so3_log(R)), R, atol=1e-12)


def test_pnp_on_a_planar_target_without_a_guess():
    """Four coplanar holes, three of them collinear (a weak, near-ambiguous target): solvePnP must start without
    T0 (SQPnP; EPnP returned garbage here) and keep to the right branch from frame to frame."""
    Xp = np.array([[-22.0, -12.0, 6.0], [-10.0, 5.0, 6.0], [0.0, 5.0, 6.0], [10.0, 5.0, 6.0]])
    T = _truth(w=(0.3, -0.4, 0.2), v=(60.0, -40.0, -50.0))
    pixels = np.stack([CAMERA.project(Xp @ Tk[:3, :3].T + Tk[:3, 3]) for Tk in T])
    track = estimate_poses(CAMERA, Xp, pixels, TIMES, "pnp")
    assert pose_errors(track.T_cam_part, T)[0].max() < 1e-6
