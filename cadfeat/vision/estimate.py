"""Pose tracking from hole measurements: EKF and IEKF (thesis §6.3.1–6.3.2) and OpenCV solvePnP per frame.

``estimate_poses(camera, points_part, pixels, times_s, method=...)`` is the public entry point
(docs/design.md "Closed loop"). All three use the same measurement model (``cadfeat.measures.rim_centre``):
the image positions of the holes through the full camera model with distortion, and — when the holes'
normals and radii are given — the centre of each rim's image ellipse rather than the projected centre.

EKF (eq. 6.5–6.10), on the error state of ``cadfeat.vision.motion`` (12 states, constant velocity):

    x̂_k|k−1 = f(x̂_k−1),  P_k|k−1 = F P Fᵀ + Q,                                        (6.5, 6.6)
    K = P_k|k−1 Cᵀ (C P_k|k−1 Cᵀ + R)⁻¹,   δ = K (z − G(x̂_k|k−1)),   x̂_k = x̂_k|k−1 ⊞ δ,   (6.8, 6.9)
    P_k = (I − K C) P_k|k−1 (I − K C)ᵀ + K R Kᵀ    (Joseph form of 6.10, symmetric and positive),

C the analytic measurement Jacobian (eq. 6.4) ``measurement.measure``. IEKF (§6.3.2): the same
prediction, then the update re-linearised at each iterate x̂ⁱ = x̂_k|k−1 ⊞ δⁱ (Gauss–Newton on the
prior + measurement cost),

    δⁱ⁺¹ = Kⁱ (z − G(x̂ⁱ) + Cⁱ δⁱ),   Kⁱ = P_k|k−1 Cⁱᵀ (Cⁱ P_k|k−1 Cⁱᵀ + R)⁻¹,

until i = n (thesis: n = 30) or ‖δⁱ⁺¹ − δⁱ‖² < τ (the thesis's (K r)ᵀ(K r) < τ), and P_k from the last
Kⁱ, Cⁱ. Missing detections (NaN pixels) drop their rows of z, C and R for that frame; a frame with none
is a prediction only. R = r I (px²) and Q = diag(0, q, …) are diagonal as in the thesis (§6.3.3).

PnP: ``cv2.solvePnP`` (iterative from the previous frame's pose, and SQPnP), refined by
``cv2.solvePnPRefineLM``, the candidate of least reprojection error; with rim radii given, the ellipse-centre
offset predicted at the current estimate is subtracted from the pixels and the pose solved again (a fixed-point
correction, 3 rounds).
Frames with fewer than 4 detections are lost (NaN pose). Its covariance is r (CᵀC)⁻¹ (Gauss–Newton).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import Camera
from cadfeat.errors import CadfeatError
from cadfeat.measures.rim_centre import measure
from cadfeat.poses import make_T
from cadfeat.vision.motion import PoseState, predict, process_noise, so3_exp, so3_log

METHODS = ("ekf", "iekf", "pnp")


class TrackingError(CadfeatError):
    """Bad input to the pose estimators (shapes, method, too few points to start)."""


@dataclass(frozen=True)
class FilterTuning:
    """Filter parameters (thesis §6.3.3). Units: px², mm²/s², rad²/s², mm, rad.

    ``r_px2`` measurement variance (R = r I); ``q_rate_mm2_s2`` / ``q_omega_rad2_s2`` process noise on the
    linear / angular rates per step (Q = diag(0, q, …)); ``q_pose_mm2`` / ``q_pose_rad2`` optional pose noise;
    ``sigma0_mm`` / ``sigma0_rad`` / ``sigma0_rate_mm_s`` / ``sigma0_omega_rad_s`` initial standard deviations
    (P₀ diagonal); ``iterations`` the IEKF's n (thesis 30) and ``tau`` its stop threshold on ‖Δδ‖².
    """

    r_px2: float = 0.25
    q_rate_mm2_s2: float = 100.0
    q_omega_rad2_s2: float = 1e-3
    q_pose_mm2: float = 0.0
    q_pose_rad2: float = 0.0
    sigma0_mm: float = 20.0
    sigma0_rad: float = 0.1
    sigma0_rate_mm_s: float = 100.0
    sigma0_omega_rad_s: float = 0.5
    iterations: int = 30
    tau: float = 1e-16

    def P0(self) -> np.ndarray:
        return np.diag(np.repeat([self.sigma0_mm, self.sigma0_rad, self.sigma0_rate_mm_s,
                                  self.sigma0_omega_rad_s], 3) ** 2)


@dataclass
class Track:
    """Estimated poses of one image sequence.

    ``T_cam_part`` (F, 4, 4) (NaN where a PnP frame was lost), ``covariance`` (F, 12, 12) for the filters
    (error state δp mm, δθ rad, δṗ mm/s, δω rad/s) or (F, 6, 6) for PnP, ``iterations`` (F,) update
    iterations per frame, ``n_measured`` (F,) holes used per frame, ``method``. Batched input (B runs) gives
    the same fields with a leading B axis.
    """

    method: str
    T_cam_part: np.ndarray
    covariance: np.ndarray
    iterations: np.ndarray
    n_measured: np.ndarray
    times_s: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))

    @property
    def pose_covariance(self) -> np.ndarray:
        """(..., F, 6, 6) covariance of (δp mm, δθ rad), left perturbation of T_cam_part."""
        return self.covariance[..., :6, :6]

    @property
    def lost(self) -> np.ndarray:
        """(..., F) bool: frames without a pose estimate."""
        return ~np.all(np.isfinite(self.T_cam_part.reshape(self.T_cam_part.shape[:-2] + (16,))), axis=-1)


def _check_inputs(camera: Camera, points_part: ArrayLike, pixels: ArrayLike, times_s: ArrayLike, method: str,
                  normals_part: ArrayLike | None, radii_mm: ArrayLike | None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    if method not in METHODS:
        raise TrackingError(f"estimate_poses: method must be one of {', '.join(METHODS)}, got {method!r}")
    if not isinstance(camera, Camera):
        raise TrackingError(f"estimate_poses: camera must be a cadfeat.camera.Camera, got {type(camera).__name__}")
    X = np.asarray(points_part, dtype=float)
    z = np.asarray(pixels, dtype=float)
    t = np.asarray(times_s, dtype=float)
    if X.ndim != 2 or X.shape[1] != 3 or len(X) < 3:
        raise TrackingError(f"estimate_poses: points_part must have shape (N, 3) with N >= 3, got {X.shape}")
    if z.ndim not in (3, 4) or z.shape[-2:] != (len(X), 2):
        raise TrackingError(f"estimate_poses: pixels must have shape (F, {len(X)}, 2) or (B, F, {len(X)}, 2), "
                            f"got {z.shape}")
    F_ = z.shape[-3]
    if t.shape != (F_,) or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise TrackingError(f"estimate_poses: times_s must be {F_} increasing finite times (s), got shape "
                            f"{t.shape}")
    n = np.zeros_like(X) if normals_part is None else np.asarray(normals_part, dtype=float)
    r = np.zeros(len(X)) if radii_mm is None else np.broadcast_to(np.asarray(radii_mm, dtype=float), (len(X),))
    if n.shape != X.shape or (np.any(r > 0) and np.any(np.linalg.norm(n, axis=1)[r > 0] == 0)):
        raise TrackingError("estimate_poses: normals_part must be (N, 3) unit axes where radii_mm > 0")
    if np.any(~np.isfinite(r)) or np.any(r < 0):
        raise TrackingError("estimate_poses: radii_mm must be finite and >= 0 (0 = a point feature)")
    n = np.where(r[:, None] > 0, n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300), n)
    return X, z, t, n, r


def estimate_poses(camera: Camera, points_part: ArrayLike, pixels: ArrayLike, times_s: ArrayLike,
                   method: str = "ekf", T0_cam_part: ArrayLike | None = None, *,
                   normals_part: ArrayLike | None = None, radii_mm: ArrayLike | None = None,
                   tuning: FilterTuning | None = None) -> Track:
    """Estimate T_cam_part at every frame from the holes' image positions.

    Parameters
    ----------
    camera : the calibrated camera (intrinsics + distortion are used in the measurement model).
    points_part : (N, 3) hole (rim) centres in the part frame, mm.
    pixels : (F, N, 2) measured image positions, px; NaN where a hole was not detected. (B, F, N, 2) runs B
        independent sequences at once (Monte-Carlo runs; the filters are batched over B) and returns
        (B, F, ...) arrays.
    times_s : (F,) increasing frame times, s.
    method : ``"ekf"``, ``"iekf"`` (thesis §6.3.1–6.3.2) or ``"pnp"`` (``cv2.solvePnP`` per frame).
    T0_cam_part : (4, 4) (or (B, 4, 4)) initial pose guess; None = SQPnP on the first frame with 4 detections.
    normals_part, radii_mm : (N, 3) outward axes and (N,) rim radii (mm); with them the measured point is the
        centre of the rim's image ellipse (``measurement`` module), without them the projected point.
    tuning : ``FilterTuning`` (R, Q, P₀, IEKF iterations and τ).

    Returns
    -------
    Track with ``T_cam_part`` (F, 4, 4) and covariances (module docstring).
    """
    X, z, t, n, r = _check_inputs(camera, points_part, pixels, times_s, method, normals_part, radii_mm)
    tuning = tuning or FilterTuning()
    single = z.ndim == 3
    zb = z[None] if single else z
    B = len(zb)
    if T0_cam_part is None:
        T0 = np.stack([_first_pose(camera, X, zb[b], n, r) for b in range(B)])
    else:
        T0 = np.asarray(T0_cam_part, dtype=float)
        if T0.shape not in ((4, 4), (B, 4, 4)) or not np.all(np.isfinite(T0)):
            raise TrackingError(f"estimate_poses: T0_cam_part must be a finite 4x4 transform (or one per run, "
                                f"({B}, 4, 4)), got shape {T0.shape}")
        T0 = np.broadcast_to(T0, (B, 4, 4)).copy()
    if method == "pnp":
        track = _track_pnp(camera, X, zb, t, n, r, T0, tuning)
    else:
        track = _track_filter(camera, X, zb, t, n, r, T0, tuning, iterated=(method == "iekf"))
    if single:
        track = Track(track.method, track.T_cam_part[0], track.covariance[0], track.iterations[0],
                      track.n_measured[0], t)
    return track


def _first_pose(camera: Camera, X: np.ndarray, z: np.ndarray, n: np.ndarray, r: np.ndarray) -> np.ndarray:
    """SQPnP on the first frame with >= 4 detections, then refined (the filters' start when T0 is not given)."""
    for k in range(len(z)):
        ok = np.all(np.isfinite(z[k]), axis=1)
        if ok.sum() >= 4:
            T = _solve_pnp(camera, X[ok], z[k, ok], n[ok], r[ok], None)
            if T is not None:
                return T
    raise TrackingError("estimate_poses: no frame has 4 detected holes to start from; give T0_cam_part")


# ---------------------------------------------------------------------------------------------- filters
def _track_filter(camera: Camera, X: np.ndarray, z: np.ndarray, t: np.ndarray, n: np.ndarray, r: np.ndarray,
                  T0: np.ndarray, tuning: FilterTuning, iterated: bool) -> Track:
    """Run the (I)EKF over frames, batched over the leading axis B of z (B, F, N, 2) and T0 (B, 4, 4)."""
    B, F_ = z.shape[:2]
    poses = np.empty((B, F_, 4, 4))
    covs = np.empty((B, F_, 12, 12))
    iters = np.zeros((B, F_), dtype=int)
    used = np.zeros((B, F_), dtype=int)
    state = PoseState.at_rest(T0)
    P = np.broadcast_to(tuning.P0(), (B, 12, 12)).copy()
    n_iter = max(1, int(tuning.iterations)) if iterated else 1
    Q0 = process_noise(0.0, tuning.q_rate_mm2_s2, tuning.q_omega_rad2_s2, (tuning.q_pose_mm2, tuning.q_pose_rad2))
    for k in range(F_):
        if k > 0:
            dt = float(t[k] - t[k - 1])
            state, Fm = predict(state, dt)
            P = Fm @ P @ np.swapaxes(Fm, -1, -2) + Q0
        ok = np.all(np.isfinite(z[:, k]), axis=-1)                               # (B, N)
        if ok.any():
            state, P, iters[:, k] = _update(camera, state, P, z[:, k], ok, X, n, r, tuning.r_px2, n_iter,
                                            tuning.tau)
        used[:, k] = ok.sum(axis=1)
        poses[:, k] = state.T_cam_part
        covs[:, k] = P
    return Track("iekf" if iterated else "ekf", poses, covs, iters, used, t)


def _update(camera: Camera, prior: PoseState, P: np.ndarray, zk: np.ndarray, ok: np.ndarray, X: np.ndarray,
            n: np.ndarray, r: np.ndarray, r_px2: float, n_iter: int, tau: float
            ) -> tuple[PoseState, np.ndarray, np.ndarray]:
    """(I)EKF measurement update (module docstring), batched over B runs: zk (B, N, 2) with ``ok`` (B, N)
    marking the detected holes. Missing holes get zero rows in C and residual, which removes them exactly
    (their rows of S decouple, their columns of K vanish). Returns the posterior, P and iterations used (B,)."""
    B, N = ok.shape
    mask = np.repeat(ok, 2, axis=1).astype(float)                                # (B, 2N)
    z_flat = np.where(np.repeat(ok, 2, axis=1), zk.reshape(B, 2 * N), 0.0)
    Rm = r_px2 * np.eye(2 * N)
    delta = np.zeros((B, 12))
    state = prior
    count = np.zeros(B, dtype=int)
    active = np.ones(B, dtype=bool)
    C = np.zeros((B, 2 * N, 12))
    K = np.zeros((B, 12, 2 * N))
    for _ in range(n_iter):
        h, Jp = measure(camera, state.T_cam_part, X, n, r)
        C_new = np.zeros((B, 2 * N, 12))
        C_new[:, :, :6] = Jp.reshape(B, 2 * N, 6) * mask[..., None]
        S = C_new @ P @ np.swapaxes(C_new, -1, -2) + Rm
        K_new = np.swapaxes(np.linalg.solve(S, C_new @ P), -1, -2)              # P Cᵀ S⁻¹
        res = (z_flat - h.reshape(B, 2 * N)) * mask
        new_delta = (K_new @ (res + (C_new @ delta[..., None])[..., 0])[..., None])[..., 0]
        step = np.sum((new_delta - delta) ** 2, axis=1)
        a = active[:, None]
        delta = np.where(a, new_delta, delta)
        C = np.where(a[..., None], C_new, C)
        K = np.where(a[..., None], K_new, K)
        count += active
        state = prior.boxplus(delta)
        active &= step >= tau
        if n_iter == 1 or not active.any():
            break
    IKC = np.eye(12) - K @ C
    P_post = IKC @ P @ np.swapaxes(IKC, -1, -2) + r_px2 * K @ np.swapaxes(K * mask[:, None, :], -1, -2)
    return state, 0.5 * (P_post + np.swapaxes(P_post, -1, -2)), count


# ---------------------------------------------------------------------------------------------- PnP
def _rvec_of(R: np.ndarray) -> np.ndarray:
    # scipy, exact near 0 (docs/design.md "Known pitfalls": cv2.Rodrigues zeroes tiny rotations)
    return so3_log(R).reshape(3, 1)


def _pnp_candidates(obj: np.ndarray, img: np.ndarray, camera: Camera, guess: np.ndarray | None) -> list[np.ndarray]:
    """Poses from ``cv2.solvePnP``: iterative from the guess (if any) and SQPnP (global, planar or not), each
    refined by ``solvePnPRefineLM``. Both, because the iterative solver from last frame's pose can slide into
    the wrong branch of a near-planar target's two-fold ambiguity, and SQPnP alone is not always refined."""
    import cv2

    K, dist = camera.K, camera.dist_coeffs
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-15)
    out = []
    starts: list[tuple[int, np.ndarray | None]] = [(cv2.SOLVEPNP_SQPNP, None)]
    if guess is not None:
        starts.insert(0, (cv2.SOLVEPNP_ITERATIVE, guess))
    for flag, T0 in starts:
        try:
            if T0 is None:
                ok, rvec, tvec = cv2.solvePnP(obj, img, K, dist, flags=flag)
            else:
                ok, rvec, tvec = cv2.solvePnP(obj, img, K, dist, rvec=_rvec_of(T0[:3, :3]),
                                              tvec=T0[:3, 3].reshape(3, 1).copy(), useExtrinsicGuess=True, flags=flag)
            if ok:
                rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, dist, rvec, tvec, criteria)
                T = make_T(so3_exp(rvec.ravel()), tvec.ravel())
                if np.all(np.isfinite(T)) and T[2, 3] > 0:
                    out.append(T)
        except cv2.error:
            continue
    return out


def _solve_pnp(camera: Camera, X: np.ndarray, z: np.ndarray, n: np.ndarray, r: np.ndarray,
               guess: np.ndarray | None, rounds: int = 3) -> np.ndarray | None:
    """cv2.solvePnP (+ RefineLM) on (M >= 4) detections, the candidate of least reprojection error
    (``_pnp_candidates``); rim ellipse-centre offsets corrected by fixed point (module docstring)."""
    obj = np.ascontiguousarray(X, dtype=np.float64)
    target = z.copy()
    T = guess
    for _ in range(rounds if np.any(r > 0) else 1):
        img = np.ascontiguousarray(target, dtype=np.float64)
        candidates = _pnp_candidates(obj, img, camera, T)
        if not candidates:
            return None
        errors = [float(np.sum((camera.project(X @ C[:3, :3].T + C[:3, 3]) - img) ** 2)) for C in candidates]
        T = candidates[int(np.argmin(errors))]
        if not np.any(r > 0):
            break
        zp, _ = measure(camera, T, X, n, r, jacobian=False)
        zc = camera.project(X @ T[:3, :3].T + T[:3, 3])
        target = z - (zp - zc)  # the pixels a point feature at the rim centre would give
    return T


def _track_pnp(camera: Camera, X: np.ndarray, z: np.ndarray, t: np.ndarray, n: np.ndarray, r: np.ndarray,
               T0: np.ndarray, tuning: FilterTuning) -> Track:
    """solvePnP per frame and per run: z (B, F, N, 2), T0 (B, 4, 4) the first guess."""
    B, F_ = z.shape[:2]
    poses = np.full((B, F_, 4, 4), np.nan)
    covs = np.full((B, F_, 6, 6), np.nan)
    used = np.zeros((B, F_), dtype=int)
    for b in range(B):
        guess = T0[b]
        for k in range(F_):
            ok = np.all(np.isfinite(z[b, k]), axis=1)
            if ok.sum() < 4:
                continue
            T = _solve_pnp(camera, X[ok], z[b, k, ok], n[ok], r[ok], guess)
            if T is None:
                continue
            poses[b, k] = T
            _, Jp = measure(camera, T, X[ok], n[ok], r[ok])
            C = Jp.reshape(-1, 6)
            try:
                covs[b, k] = tuning.r_px2 * np.linalg.inv(C.T @ C)
            except np.linalg.LinAlgError:
                pass
            used[b, k] = int(ok.sum())
            guess = T
    return Track("pnp", poses, covs, np.ones((B, F_), dtype=int), used, t)
