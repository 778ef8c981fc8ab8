"""The 12-state constant-velocity model of the pose filters (thesis §6.3.1, eq. 6.1) on SE(3).

The thesis's state is x = [X, Ẋ, Y, Ẏ, Z, Ż, ψ, ψ̇, θ, θ̇, φ, φ̇] (position and Euler angles of the part in
the camera frame, with their rates) and the process x_k = A x_{k−1} + w_k, A = diag([[1, T], [0, 1]]).
Euler angles break at large angles (gimbal lock, wrap-around), so here the orientation is a rotation
matrix and the filter works on an **error state** about the current estimate (a "multiplicative" or
error-state EKF):

    state       (R, p, ṗ, ω):  T_cam_part = [R, p],  ṗ (mm/s) the rate of p,  ω (rad/s) with Ṙ = [ω]× R
    error δ     (δp, δθ, δṗ, δω) ∈ R¹²:  p = p̂ + δp,  R = exp([δθ]×) R̂,  ṗ = ṗ̂ + δṗ,  ω = ω̂ + δω

δθ is a rotation vector *about the current estimate*, always small, so nothing breaks at any attitude;
after each update it is folded back into R̂ ("reset"). Process over a step T (eq. 6.1):

    p ← p + T ṗ,   R ← exp([T ω]×) R,   ṗ, ω constant,

and its error transition (exact to first order, J_l the left Jacobian of SO(3)):

    F = [[I, 0, T I, 0], [0, exp([Tω]×), 0, T J_l(Tω)], [0, 0, I, 0], [0, 0, 0, I]],

which is the thesis's A for small T ω. The process noise is diagonal on the rates, as in the thesis
(Q = diag(0, q, 0, q, …), §6.3.3), with separate q for the linear (mm²/s²) and angular (rad²/s²) rates
and an optional pose term.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from cadfeat.poses import hat, make_T


def _series(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """sin θ/θ, (1 − cos θ)/θ², (θ − sin θ)/θ³ with Taylor series below 1e-4 rad (the closed forms lose all
    digits to cancellation there; the series are exact to double precision)."""
    small = theta < 1e-4
    t = np.where(small, 1.0, theta)
    t2 = theta * theta
    A = np.where(small, 1.0 - t2 / 6.0, np.sin(t) / t)
    B = np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(t)) / (t * t))
    C = np.where(small, 1.0 / 6.0 - t2 / 120.0, (t - np.sin(t)) / (t * t * t))
    return A, B, C


def so3_exp(w: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors w (..., 3): Rodrigues I + A W + B W², series near 0
    (exact for tiny angles, unlike cv2.Rodrigues — docs/design.md "Known pitfalls")."""
    w = np.asarray(w, dtype=float)
    A, B, _ = _series(np.linalg.norm(w, axis=-1))
    W = hat(w)
    return np.eye(3) + A[..., None, None] * W + B[..., None, None] * (W @ W)


def so3_log(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) of rotation matrices (..., 3, 3), ‖w‖ ≤ π.

    θ = arccos((tr R − 1)/2), w = θ/(2 sin θ) vee(R − Rᵀ), with the series θ/sin θ ≈ 1 + θ²/6 below 1e-4 rad
    (no cancellation, exact for tiny angles); within 1e-3 rad of π, where vee(R − Rᵀ) vanishes, scipy's
    quaternion route is used for those entries only (it is ~100× slower per call).
    """
    R = np.asarray(R, dtype=float)
    cos = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1.0) * 0.5, -1.0, 1.0)
    theta = np.arccos(cos)
    vee = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    small = theta < 1e-4
    sin = np.sin(np.where(small, 1.0, theta))
    scale = np.where(small, 0.5 * (1.0 + theta * theta / 6.0), theta / (2.0 * sin))
    w = scale[..., None] * vee
    near_pi = theta > np.pi - 1e-3
    if np.any(near_pi):
        w[near_pi] = Rotation.from_matrix(R[near_pi].reshape(-1, 3, 3)).as_rotvec()
    return w


def left_jacobian(w: np.ndarray) -> np.ndarray:
    """Left Jacobian of SO(3) (..., 3, 3), J_l(w) = I + (1 − cos θ)/θ² [w]× + (θ − sin θ)/θ³ [w]×²."""
    w = np.asarray(w, dtype=float)
    _, B, C = _series(np.linalg.norm(w, axis=-1))
    W = hat(w)
    return np.eye(3) + B[..., None, None] * W + C[..., None, None] * (W @ W)


@dataclass
class PoseState:
    """Filter state, batched over leading axes B (Monte-Carlo runs): rotation ``R`` (B, 3, 3) and translation
    ``p_mm`` (B, 3) of T_cam_part, their rates ``p_rate_mm_s`` (B, 3) and ``omega_rad_s`` (B, 3)
    (Ṙ = [ω]× R, camera frame)."""

    R: np.ndarray
    p_mm: np.ndarray
    p_rate_mm_s: np.ndarray
    omega_rad_s: np.ndarray

    @classmethod
    def at_rest(cls, T_cam_part: np.ndarray) -> PoseState:
        """A state at pose T_cam_part with zero rates (the thesis starts from a stationary robot, §6.3.1)."""
        T = np.asarray(T_cam_part, dtype=float)
        p = T[..., :3, 3].copy()
        return cls(T[..., :3, :3].copy(), p, np.zeros_like(p), np.zeros_like(p))

    @property
    def T_cam_part(self) -> np.ndarray:
        return make_T(self.R, self.p_mm)

    def boxplus(self, delta: np.ndarray) -> PoseState:
        """State ⊞ δ (B, 12): p + δp, exp([δθ]×) R, rates + δ rates."""
        return PoseState(so3_exp(delta[..., 3:6]) @ self.R, self.p_mm + delta[..., :3],
                         self.p_rate_mm_s + delta[..., 6:9], self.omega_rad_s + delta[..., 9:12])

    def boxminus(self, other: PoseState) -> np.ndarray:
        """δ (B, 12) with self = other ⊞ δ."""
        return np.concatenate([self.p_mm - other.p_mm, so3_log(self.R @ np.swapaxes(other.R, -1, -2)),
                               self.p_rate_mm_s - other.p_rate_mm_s, self.omega_rad_s - other.omega_rad_s], axis=-1)


def predict(state: PoseState, dt_s: float) -> tuple[PoseState, np.ndarray]:
    """Constant-velocity prediction over ``dt_s`` (module docstring): the new state and F (B, 12, 12)."""
    phi = dt_s * state.omega_rad_s
    R_step = so3_exp(phi)
    new = PoseState(R_step @ state.R, state.p_mm + dt_s * state.p_rate_mm_s, state.p_rate_mm_s.copy(),
                    state.omega_rad_s.copy())
    F = np.broadcast_to(np.eye(12), phi.shape[:-1] + (12, 12)).copy()
    F[..., 0:3, 6:9] = dt_s * np.eye(3)
    F[..., 3:6, 3:6] = R_step
    F[..., 3:6, 9:12] = dt_s * left_jacobian(phi)
    return new, F


def process_noise(dt_s: float, q_rate_mm2_s2: float, q_omega_rad2_s2: float, q_pose: tuple[float, float] = (0.0, 0.0),
                  ) -> np.ndarray:
    """Q (12, 12) diagonal: the thesis's diag(0, q, 0, q, …) (§6.3.3) with q per rate kind, per step.

    ``q_pose = (mm², rad²)`` adds noise on the pose itself (0 in the thesis). ``dt_s`` is unused (the thesis
    gives Q per sample, not per second) but kept so a continuous-time Q can replace it.
    """
    del dt_s
    return np.diag(np.concatenate([np.full(3, q_pose[0]), np.full(3, q_pose[1]),
                                   np.full(3, q_rate_mm2_s2), np.full(3, q_omega_rad2_s2)]))
