"""SE(3) helpers: homogeneous transforms, look-at camera poses, the exponential and logarithm, twists.

Conventions (docs/design.md "Conventions"): ``T_a_b`` is the 4x4 transform mapping coordinates in frame b to frame a,
``p_a = T_a_b @ p_b``; millimetres and radians; cameras use the OpenCV frame (x right, y down,
z forward). Every function is batched over leading axes (``(..., 4, 4)``, ``(..., 3)``, ``(..., 6)``)
and broadcasts like numpy; rotations go through ``scipy.spatial.transform.Rotation``.

A twist ``xi = (v, ω)`` (6,) stacks a linear part v (mm, or mm/s for a velocity) and an angular part
ω (rad, or rad/s). ``twist_between(T_a, T_b)`` is the *body* twist with ``T_b = T_a @ se3_exp(xi)``:
for a camera pose ``T_task_cam`` it is expressed in the camera frame, as the velocity screw of the
thesis's eq. 4.3 (``Ṗ_cam = −V − Ω × P_cam`` for a point fixed in the task frame).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from cadfeat.errors import CadfeatError

#: Below this rotation angle (rad) the V-matrix coefficients use their Taylor series.
SMALL_ANGLE_RAD = 1e-4

#: Fallback ``up`` vectors of ``look_at`` when ``up`` is parallel to the viewing direction, tried in order.
LOOK_AT_FALLBACK_UP = ((0.0, 1.0, 0.0), (1.0, 0.0, 0.0))

#: ``up`` counts as parallel to the viewing direction when ``‖z × up‖ / ‖up‖`` is below this.
PARALLEL_TOL = 1e-9


# ---------------------------------------------------------------------- homogeneous transforms
def make_T(R: ArrayLike, t: ArrayLike) -> np.ndarray:
    """Homogeneous transforms (..., 4, 4) from rotations R (..., 3, 3) and translations t (..., 3), mm."""
    R = np.asarray(R, dtype=float)
    t = np.asarray(t, dtype=float)
    shape = np.broadcast_shapes(R.shape[:-2], t.shape[:-1])
    T = np.zeros(shape + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def invert_T(T: ArrayLike) -> np.ndarray:
    """Inverse of rigid transforms (..., 4, 4): ``[Rᵀ, −Rᵀ t]`` (exact, no matrix inversion)."""
    T = np.asarray(T, dtype=float)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    return make_T(Rt, -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3]))


def cam_from_part(T_task_cam: ArrayLike, T_task_part: ArrayLike) -> np.ndarray:
    """``T_cam_part = inv(T_task_cam) @ T_task_part`` (..., 4, 4): the part in the camera frame at each camera pose of
    a trajectory (``T_task_cam``, the camera in the task frame) with the part placed at ``T_task_part`` (mm)."""
    return invert_T(T_task_cam) @ np.asarray(T_task_part, dtype=float)


def transform_points(T: ArrayLike, p: ArrayLike) -> np.ndarray:
    """``R p + t`` for transforms (..., 4, 4) and points (..., 3) broadcast against each other, mm."""
    T = np.asarray(T, dtype=float)
    p = np.asarray(p, dtype=float)
    return np.einsum("...ij,...j->...i", T[..., :3, :3], p) + T[..., :3, 3]


def points_in_frames(T: ArrayLike, p: ArrayLike) -> np.ndarray:
    """Every point in every frame: transforms (L, 4, 4) and points (N, 3) → (L, N, 3).

    Leading axes generalise: T (*A, 4, 4) with p (*B, 3) gives (*A, *B, 3). For camera-frame points
    pass ``invert_T(T_task_cam)`` and task-frame points.
    """
    T = np.asarray(T, dtype=float)
    p = np.asarray(p, dtype=float)
    nb = p.ndim - 1
    T = T.reshape(T.shape[:-2] + (1,) * nb + (4, 4))
    return transform_points(T, p)


def rotate_vectors(T: ArrayLike, v: ArrayLike) -> np.ndarray:
    """Rotate directions (..., 3) by the rotation of T (..., 4, 4) or R (..., 3, 3); no translation."""
    T = np.asarray(T, dtype=float)
    return np.einsum("...ij,...j->...i", T[..., :3, :3], np.asarray(v, dtype=float))


# ---------------------------------------------------------------------- look-at
def look_at(eye: ArrayLike, target: ArrayLike, up: ArrayLike = (0.0, 0.0, 1.0)) -> np.ndarray:
    """Camera poses ``T_task_cam`` (..., 4, 4) at ``eye`` looking at ``target`` (task frame, mm).

    OpenCV camera frame: z (forward) points from eye to target, so the target projects to the
    principal point; x is right and y is down, with ``up`` (task frame) pointing up in the image
    (towards smaller v): ``x = z × up / ‖z × up‖``, ``y = z × x``. When ``up`` is parallel to the
    viewing direction (``‖z × up‖ < 1e-9 ‖up‖``) the first of ``LOOK_AT_FALLBACK_UP`` — task +y, else
    task +x — not parallel to it is used instead: a camera looking straight down with the default
    ``up = +z`` sees task +y as image up. Note that a path passing *close* to that pole (but not on
    it) turns quickly about the optical axis; give such paths an ``up`` across the view.
    Raises ``CadfeatError`` when eye and target coincide.
    """
    eye, target, up = (np.asarray(a, dtype=float) for a in (eye, target, up))
    z, x, y, _ = _look_at_axes(eye, target, up)
    return make_T(np.stack([x, y, z], axis=-1), eye)


def _look_at_axes(eye: np.ndarray, target: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, ...]:
    """Unit camera axes (z, x, y) in the task frame for ``look_at``, and the ``up`` actually used."""
    d = target - eye
    dist = np.linalg.norm(d, axis=-1, keepdims=True)
    if np.any(dist <= 0.0) or not np.all(np.isfinite(dist)):
        raise CadfeatError("look_at: eye and target must be distinct finite points")
    z = d / dist
    u = _effective_up(z, up)
    x = np.cross(z, u)
    x /= np.linalg.norm(x, axis=-1, keepdims=True)
    return z, x, np.cross(z, x), u


def _effective_up(z: np.ndarray, up: np.ndarray) -> np.ndarray:
    """``up`` broadcast to z's shape, replaced by the fallback where it is parallel to z."""
    u = np.array(np.broadcast_to(up, z.shape), dtype=float)
    if np.any(np.linalg.norm(u, axis=-1) == 0.0):
        raise CadfeatError("look_at: up must be a non-zero vector")
    for fallback in LOOK_AT_FALLBACK_UP:
        bad = np.linalg.norm(np.cross(z, u), axis=-1) < PARALLEL_TOL * np.linalg.norm(u, axis=-1)
        if not np.any(bad):
            break
        u[bad] = fallback
    return u


def look_at_screws(eye: ArrayLike, target: ArrayLike, eye_velocity: ArrayLike,
                   target_velocity: ArrayLike = (0.0, 0.0, 0.0), up: ArrayLike = (0.0, 0.0, 1.0)) -> np.ndarray:
    """Analytic velocity screws (..., 6) = (v, ω) in the camera frame of moving ``look_at`` poses.

    ``eye_velocity``, ``target_velocity`` (mm/s, task frame) are the time derivatives of eye and target;
    ``up`` is fixed. With z = d/‖d‖, d = target − eye: ż = (ḋ − z (z·ḋ)) / ‖d‖ and, from ż = ω × z and
    x = z × u / ‖z × u‖, the body angular velocity is ω = (−ż·y, ż·x, y·(ż × u) / ‖z × u‖);
    v = Rᵀ ėye. These are the γ̇_k of eq. 4.3 for the library trajectories.
    """
    eye, target, up = (np.asarray(a, dtype=float) for a in (eye, target, up))
    eye_dot = np.asarray(eye_velocity, dtype=float)
    d_dot = np.asarray(target_velocity, dtype=float) - eye_dot
    z, x, y, u = _look_at_axes(eye, target, up)
    dist = np.linalg.norm(target - eye, axis=-1, keepdims=True)
    z_dot = (d_dot - z * np.sum(z * d_dot, axis=-1, keepdims=True)) / dist
    wz = np.sum(y * np.cross(z_dot, u), axis=-1) / np.linalg.norm(np.cross(z, u), axis=-1)
    omega = np.stack([-np.sum(z_dot * y, axis=-1), np.sum(z_dot * x, axis=-1), wz], axis=-1)
    v = np.stack([np.sum(x * eye_dot, axis=-1), np.sum(y * eye_dot, axis=-1), np.sum(z * eye_dot, axis=-1)], axis=-1)
    return np.concatenate([v, omega], axis=-1)


# ---------------------------------------------------------------------- exponential and logarithm
def hat(w: ArrayLike) -> np.ndarray:
    """Skew-symmetric matrices [w]× (..., 3, 3) with ``[w]× a = w × a``."""
    w = np.asarray(w, dtype=float)
    W = np.zeros(w.shape[:-1] + (3, 3))
    W[..., 0, 1], W[..., 0, 2] = -w[..., 2], w[..., 1]
    W[..., 1, 0], W[..., 1, 2] = w[..., 2], -w[..., 0]
    W[..., 2, 0], W[..., 2, 1] = -w[..., 1], w[..., 0]
    return W


def rotvec_matrix(w: ArrayLike) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors w (..., 3) rad (scipy's Rotation: exact for small angles,
    unlike ``cv2.Rodrigues`` — docs/design.md "Known pitfalls")."""
    w = np.asarray(w, dtype=float)
    return Rotation.from_rotvec(w.reshape(-1, 3)).as_matrix().reshape(w.shape[:-1] + (3, 3))


def _matrix_to_rotvec(R: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(R.reshape(-1, 3, 3)).as_rotvec().reshape(R.shape[:-2] + (3,))


def _v_coefficients(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """B = (1 − cos θ)/θ², C = (θ − sin θ)/θ³ of V = I + B W + C W², Taylor series near 0."""
    small = theta < SMALL_ANGLE_RAD
    t = np.where(small, 1.0, theta)
    t2 = theta * theta
    B = np.where(small, 0.5 - t2 / 24.0 + t2 * t2 / 720.0, (1.0 - np.cos(t)) / (t * t))
    C = np.where(small, 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0, (t - np.sin(t)) / (t * t * t))
    return B, C


def se3_exp(xi: ArrayLike) -> np.ndarray:
    """Exponential of twists xi = (v, ω) (..., 6) → transforms (..., 4, 4).

    Exact: R = exp([ω]×) (scipy), t = V v with V = I + (1 − cos θ)/θ² [ω]× + (θ − sin θ)/θ³ [ω]×²,
    θ = ‖ω‖; series below ``SMALL_ANGLE_RAD`` so tiny rotations stay exact (unlike cv2.Rodrigues).
    """
    xi = np.asarray(xi, dtype=float)
    if xi.shape[-1:] != (6,):
        raise CadfeatError(f"se3_exp: twists must have shape (..., 6), got {xi.shape}")
    v, w = xi[..., :3], xi[..., 3:]
    B, C = _v_coefficients(np.linalg.norm(w, axis=-1))
    t = v + B[..., None] * np.cross(w, v) + C[..., None] * np.cross(w, np.cross(w, v))
    return make_T(rotvec_matrix(w), t)


def se3_log(T: ArrayLike) -> np.ndarray:
    """Logarithm of rigid transforms (..., 4, 4) → twists (v, ω) (..., 6), with ‖ω‖ ≤ π.

    ω from scipy (robust near 0 and π); v = V⁻¹ t with
    V⁻¹ = I − ½[ω]× + (1 − (θ/2) cot(θ/2))/θ² [ω]×² (series 1/12 + θ²/720 + θ⁴/30240 near 0).
    """
    T = np.asarray(T, dtype=float)
    if T.shape[-2:] != (4, 4):
        raise CadfeatError(f"se3_log: transforms must have shape (..., 4, 4), got {T.shape}")
    w = _matrix_to_rotvec(T[..., :3, :3])
    t = T[..., :3, 3]
    theta = np.linalg.norm(w, axis=-1)
    small = theta < SMALL_ANGLE_RAD
    h = np.where(small, 1.0, theta) / 2.0
    t2 = theta * theta
    D = np.where(small, 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0,
                 (1.0 - h * np.cos(h) / np.sin(h)) / (4.0 * h * h))
    v = t - 0.5 * np.cross(w, t) + D[..., None] * np.cross(w, np.cross(w, t))
    return np.concatenate([v, w], axis=-1)


def twist_between(T_a: ArrayLike, T_b: ArrayLike) -> np.ndarray:
    """Body twist xi (..., 6) with ``T_b = T_a @ se3_exp(xi)``, i.e. ``se3_log(T_a⁻¹ T_b)`` (frame a)."""
    return se3_log(invert_T(T_a) @ np.asarray(T_b, dtype=float))


def rotation_error(R: ArrayLike) -> np.ndarray:
    """Deviation of (..., 3, 3) from a proper rotation: max(|RᵀR − I|, |det R − 1|) elementwise-max."""
    R = np.asarray(R, dtype=float)
    ortho = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(-1, -2))
    return np.maximum(ortho, np.abs(np.linalg.det(R) - 1.0))
