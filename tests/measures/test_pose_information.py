"""Pose information (``cadfeat.measures.pose_information``) against independent references.

- the information matrix equals Σ JᵀJ/σ² with J from central differences of ``cv2.projectPoints`` of the
  rim-ellipse centres (conic centre of the circle's exact projection H⁻ᵀ diag(1, 1, −R²) H⁻¹, H = [u v c]),
  under the stated pose perturbation (R ← exp([δθ]×) R, p ← p + δp), which is also checked against the left
  SE(3) twist;
- the CRLB of a planar and a non-planar layout matches a Monte-Carlo of ``cv2.solvePnP`` (SQPnP, refined by
  Levenberg–Marquardt) with Gaussian pixel noise: translation and rotation traces within 10 %;
- offsets propagated by δ = (JᵀWJ)⁻¹JᵀW b match the pose ``cv2.solvePnP`` returns from offset pixels;
- the posterior CRLB matches the project's EKF: its own Riccati covariance, and the empirical error
  covariance over Monte-Carlo runs on data from the constant-velocity model with process noise Q;
- hidden holes add nothing: the information does not change when a hidden hole shrinks or moves.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

from cadfeat.camera import Camera
from cadfeat.measures.pose_information import direction_words, pose_information
from cadfeat.poses import hat, invert_T, look_at, make_T
from cadfeat.vision.crlb import posterior_crlb

pytestmark = pytest.mark.numerics  # run again under another BLAS kernel (Makefile: test)

cv2 = pytest.importorskip("cv2")

CAMERA = Camera(fx=900.0, fy=905.0, cx=640.0, cy=500.0, width=1280, height=1024,
                dist=(-0.15, 0.05, 0.001, -0.0005, 0.0), focus_distance_mm=300.0)
PINHOLE = Camera(fx=900.0, fy=900.0, cx=640.0, cy=500.0, width=1280, height=1024, focus_distance_mm=300.0)


def _poses(eyes, target=(0.0, 0.0, 0.0)) -> np.ndarray:
    return np.stack([invert_T(look_at(np.array(e, float), np.array(target, float), up=(0, 1, 0))) for e in eyes])


def _holes():
    c = np.array([[-30, -20, 0], [25, -15, 0], [-10, 22, 0], [30, 25, 0], [0, 0, 10], [40, -5, 5]], float)
    n = np.array([[0, 0, 1], [0, 0, 1], [0, 0, 1], [0.3, 0, 1], [0, -0.5, 1], [1, 0, 1]], float)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    r = np.array([4.0, 3.0, 2.5, 5.0, 3.5, 2.0])
    return c, n, r


def _conic_centre_px(camera: Camera, c: np.ndarray, n: np.ndarray, R: float) -> np.ndarray:
    """Rim-ellipse centre (px) by the exact circle projection and cv2.projectPoints (independent route)."""
    u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    H = np.column_stack([u, v, c])
    Hi = np.linalg.inv(H)
    C = Hi.T @ np.diag([1.0, 1.0, -R * R]) @ Hi
    x0 = -np.linalg.solve(C[:2, :2], C[:2, 2])
    pt, _ = cv2.projectPoints(np.array([[x0[0], x0[1], 1.0]]), np.zeros(3), np.zeros(3), camera.K, camera.dist_coeffs)
    return pt.reshape(2)


def _perturb(T: np.ndarray, d: np.ndarray) -> np.ndarray:
    return make_T(Rotation.from_rotvec(d[3:]).as_matrix() @ T[:3, :3], T[:3, 3] + d[:3])


def _measure_cv(camera, T, c, n, r):
    cc = c @ T[:3, :3].T + T[:3, 3]
    nn = n @ T[:3, :3].T
    return np.stack([_conic_centre_px(camera, cc[j], nn[j], r[j]) for j in range(len(c))])


def test_information_equals_finite_difference_jacobians_of_cv2_projectpoints():
    c, n, r = _holes()
    T = _poses([(60, -80, 260), (-90, 50, 250)])
    sigma = np.array([[0.3, 0.5, 0.2, 0.4, 0.25, 0.6], [0.35, 0.3, 0.3, 0.5, 0.2, 0.3]])
    res = pose_information(CAMERA, T, c, n, r, sigma_px=sigma, detection=False)
    h = 1e-5
    for k in range(len(T)):
        J = np.zeros((len(c), 2, 6))
        for i in range(6):
            d = np.zeros(6)
            d[i] = h
            J[:, :, i] = (_measure_cv(CAMERA, _perturb(T[k], d), c, n, r)
                          - _measure_cv(CAMERA, _perturb(T[k], -d), c, n, r)) / (2 * h)
        ref = np.einsum("nai,naj,n->ij", J, J, 1.0 / sigma[k] ** 2)
        scale = np.sqrt(np.outer(np.diag(ref), np.diag(ref)))
        assert np.max(np.abs(res.information[k] - ref) / scale) < 1e-5
        np.testing.assert_allclose(res.measured_px[k], _measure_cv(CAMERA, T[k], c, n, r), atol=1e-6)
        np.testing.assert_allclose(res.covariance[k] @ res.information[k], np.eye(6), atol=1e-8)


def test_parametrisation_is_the_left_se3_twist_with_rho_equal_dp_minus_dtheta_cross_p():
    c, n, r = _holes()
    T = _poses([(60, -80, 260)])[0]
    p = T[:3, 3]
    d = np.array([0.3, -0.2, 0.1, 2e-3, -1e-3, 1.5e-3]) * 1e-3
    xi = np.zeros((4, 4))
    xi[:3, :3] = hat(d[3:])
    xi[:3, 3] = d[:3] - np.cross(d[3:], p)
    a = _measure_cv(CAMERA, _perturb(T, d), c, n, r)
    b = _measure_cv(CAMERA, expm(xi) @ T, c, n, r)
    z0 = _measure_cv(CAMERA, T, c, n, r)
    assert np.max(np.abs(a - b)) < 1e-3 * np.max(np.abs(a - z0))  # equal to first order


def _pnp_errors(camera, X, T, sigma, draws, seed):
    rng = np.random.default_rng(seed)
    z = camera.project(X @ T[:3, :3].T + T[:3, 3])
    errs = np.empty((draws, 6))
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-12)
    for i in range(draws):
        img = (z + sigma * rng.standard_normal(z.shape)).astype(np.float64)
        _, rvec, tvec = cv2.solvePnP(X, img, camera.K, camera.dist_coeffs, flags=cv2.SOLVEPNP_SQPNP)
        rvec, tvec = cv2.solvePnPRefineLM(X, img, camera.K, camera.dist_coeffs, rvec, tvec, crit)
        R = Rotation.from_rotvec(rvec.ravel()).as_matrix()
        errs[i, :3] = tvec.ravel() - T[:3, 3]
        errs[i, 3:] = Rotation.from_matrix(R @ T[:3, :3].T).as_rotvec()
    return errs


@pytest.mark.parametrize("planar", [True, False])
def test_crlb_matches_a_monte_carlo_of_solvepnp(planar):
    rng = np.random.default_rng(3)
    X = np.column_stack([rng.uniform(-40, 40, 8), rng.uniform(-30, 30, 8),
                         np.zeros(8) if planar else rng.uniform(-25, 25, 8)])
    T = _poses([(50, -60, 280)], target=(5.0, 0.0, 0.0))[0]
    sigma = 0.5
    res = pose_information(CAMERA, T[None], X, np.zeros_like(X), np.zeros(8), sigma_px=sigma, detection=False)
    errs = _pnp_errors(CAMERA, X, T, sigma, 3000, seed=11)
    emp = errs.T @ errs / len(errs)
    cov = res.covariance[0]
    assert np.trace(emp[:3, :3]) == pytest.approx(np.trace(cov[:3, :3]), rel=0.10)
    assert np.trace(emp[3:, 3:]) == pytest.approx(np.trace(cov[3:, 3:]), rel=0.10)
    assert res.sigma_translation_mm[0] == pytest.approx(np.sqrt(np.trace(cov[:3, :3])))


def test_offsets_propagate_like_solvepnp_on_offset_pixels():
    rng = np.random.default_rng(5)
    X = np.column_stack([rng.uniform(-40, 40, 7), rng.uniform(-30, 30, 7), rng.uniform(-20, 20, 7)])
    T = _poses([(-40, 70, 260)])[0]
    b = rng.normal(0.0, 0.3, (1, 7, 2))
    sig = np.full((1, 7), 0.5)
    res = pose_information(PINHOLE, T[None], X, np.zeros_like(X), np.zeros(7), sigma_px=sig, detection=False,
                           offset_px=b)
    z = PINHOLE.project(X @ T[:3, :3].T + T[:3, 3]) + b[0]
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-15)
    _, rvec, tvec = cv2.solvePnP(X, z, PINHOLE.K, None, flags=cv2.SOLVEPNP_SQPNP)
    rvec, tvec = cv2.solvePnPRefineLM(X, z, PINHOLE.K, None, rvec, tvec, crit)
    d = np.concatenate([tvec.ravel() - T[:3, 3],
                        Rotation.from_matrix(Rotation.from_rotvec(rvec.ravel()).as_matrix() @ T[:3, :3].T).as_rotvec()])
    np.testing.assert_allclose(res.bias[0], d, rtol=0.02, atol=0.02 * np.abs(d).max())


def test_hidden_holes_add_nothing_whatever_their_size_or_position():
    c, n, r = _holes()
    T = _poses([(60, -80, 260), (-90, 50, 250), (0, 0, 300)])
    occ = np.zeros((3, len(c)))
    occ[:, 2] = 1.0
    base = pose_information(CAMERA, T, c, n, r, occlusion=occ)
    c2, r2 = c.copy(), r.copy()
    c2[2] += [7.0, -3.0, 0.0]
    r2[2] = 0.8
    moved = pose_information(CAMERA, T, c2, n, r2, occlusion=occ)
    np.testing.assert_allclose(moved.information, base.information, rtol=1e-12)
    assert np.all(base.share[:, 2] == 0) and np.all(base.probability[:, 2] == 0)
    seen = pose_information(CAMERA, T, c, n, r)
    assert np.all(np.linalg.eigvalsh(seen.information - base.information) > -1e-9 * np.abs(seen.information).max())


def test_share_sums_to_one_and_weakest_direction_has_words():
    c, n, r = _holes()
    T = _poses([(60, -80, 260)])
    res = pose_information(CAMERA, T, c, n, r, sigma_px=0.3, detection=False)
    assert res.share.sum(axis=1) == pytest.approx(1.0)
    assert direction_words(np.array([0, 0, 0, 0, 0, 1.0])) == "rotation about the optical axis"
    assert direction_words(np.array([0, 0, 1.0, 0, 0, 0])) == "translation along the optical axis"
    w = res.weakest[0]
    lam = w @ (res.information[0] * np.outer(*(2 * [[1, 1, 1, 1 / 50, 1 / 50, 1 / 50]]))) @ w
    assert res.weakest_sigma[0] == pytest.approx(1 / np.sqrt(lam))


def test_fewer_than_three_holes_give_an_infinite_bound_or_the_prior():
    c, n, r = _holes()
    T = _poses([(60, -80, 260)])
    res = pose_information(CAMERA, T, c[:2], n[:2], r[:2], sigma_px=0.3, detection=False)
    assert np.isinf(res.sigma_translation_mm[0]) or np.isinf(res.sigma_rotation_deg[0])
    res = pose_information(CAMERA, T, c[:2], n[:2], r[:2], sigma_px=0.3, detection=False, prior_sigma=(10.0, 0.1))
    assert np.isfinite(res.sigma_translation_mm[0]) and res.sigma_translation_mm[0] < np.sqrt(3) * 10.0


def _cv_truth(T0, B, F_, dt, q_rate, q_omega, rng):
    """Truth from the constant-velocity model with process noise (velocity random walks per step)."""
    from cadfeat.vision.motion import so3_exp

    T = np.empty((B, F_, 4, 4))
    T[:, 0] = T0
    v = np.zeros((B, 3))
    w = np.zeros((B, 3))
    omega = np.zeros((B, F_, 3))
    for k in range(1, F_):
        T[:, k] = T[:, k - 1]
        T[:, k, :3, 3] = T[:, k - 1, :3, 3] + dt * v
        T[:, k, :3, :3] = so3_exp(dt * w) @ T[:, k - 1, :3, :3]
        omega[:, k - 1] = w
        v = v + rng.normal(0, np.sqrt(q_rate), (B, 3))
        w = w + rng.normal(0, np.sqrt(q_omega), (B, 3))
    return T, omega


def test_posterior_crlb_matches_the_ekf_covariance_and_its_monte_carlo_errors():
    from cadfeat.vision import FilterTuning, estimate_poses
    from cadfeat.vision.metrics import pose_errors

    c, n, r = _holes()
    tuning = FilterTuning(r_px2=0.25, q_rate_mm2_s2=1.0, q_omega_rad2_s2=1e-6, sigma0_mm=0.5, sigma0_rad=0.005,
                          sigma0_rate_mm_s=0.1, sigma0_omega_rad_s=0.001)
    rng = np.random.default_rng(2)
    B, F_, dt = 150, 30, 0.1
    t = np.arange(F_) * dt
    T0 = _poses([(40, -60, 270)])[0]
    truth, omega = _cv_truth(T0, B, F_, dt, tuning.q_rate_mm2_s2, tuning.q_omega_rad2_s2, rng)
    res = pose_information(CAMERA, truth.reshape(-1, 4, 4), c, n, r, sigma_px=0.5, detection=False)
    z = res.measured_px.reshape(B, F_, len(c), 2) + 0.5 * rng.standard_normal((B, F_, len(c), 2))
    init = truth[:, 0].copy()
    init[:, :3, 3] += rng.normal(0, tuning.sigma0_mm, (B, 3))
    init[:, :3, :3] = Rotation.from_rotvec(rng.normal(0, tuning.sigma0_rad, (B, 3))).as_matrix() @ init[:, :3, :3]
    track = estimate_poses(CAMERA, c, z, t, "ekf", init, normals_part=n, radii_mm=r, tuning=tuning)
    bound, sig = posterior_crlb(res.information.reshape(B, F_, 6, 6), t, tuning, omega)  # one bound per truth
    # the EKF's own covariance (its Riccati recursion: Joseph form, in measurement space, linearised at its
    # estimates) against the information-form recursion at the truth
    P_ekf = track.covariance[:, :, :6, :6]
    for blk in (slice(0, 3), slice(3, 6)):
        np.testing.assert_allclose(np.trace(P_ekf[:, -10:, blk, blk], axis1=-2, axis2=-1),
                                   np.trace(bound[:, -10:, blk, blk], axis1=-2, axis2=-1), rtol=0.03)
    # and its actual errors (Monte-Carlo over truths and noise, last 10 frames pooled)
    et, er = pose_errors(track.T_cam_part, truth)
    rms_t = np.sqrt(np.mean(et[:, -10:] ** 2))
    rms_r = np.sqrt(np.mean(np.radians(er[:, -10:]) ** 2))
    assert rms_t == pytest.approx(np.sqrt(np.mean(sig[:, -10:, 0] ** 2)), rel=0.15)
    assert rms_r == pytest.approx(np.radians(np.sqrt(np.mean(sig[:, -10:, 1] ** 2))), rel=0.15)
