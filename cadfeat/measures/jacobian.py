"""Image Jacobian of point features and its diagnostics (thesis eq. 4.9–4.15, 4.20–4.21).

Convention (DESIGN.md, the same as ViSP's and the Machine Vision Toolbox's interaction matrix): a point
fixed in the task frame seen from a camera moving with the velocity screw γ̇ = (v, ω) (mm/s, rad/s,
camera frame) moves as Ṗ = −v − ω × P (eq. 4.3), and its pixel image moves as ṗ = J γ̇ with
``J = D(x, y) · L(x, y, Z)``: L the normalised-coordinate interaction matrix (eq. 4.10–4.11 with
f_C/s_x = 1) and D the 2×2 Jacobian of the distortion + camera matrix (``Camera.distortion_jacobian``).
Without distortion D = diag(fx, fy) and J is eq. 4.9–4.11 in pixels.

Points at or behind the camera (Z ≤ ``MIN_DEPTH_MM``) use the clamped depth of ``Camera.project`` so
the result stays finite; callers zero-weight them (``stacked_jacobian`` weights).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import MIN_DEPTH_MM, Camera

#: A stacked Jacobian counts as singular (rank < 6) when σ_min ≤ SINGULAR_RTOL · σ_max.
SINGULAR_RTOL = 1e-6

#: Reported condition number of a singular Jacobian (finite, so sums over a trajectory stay finite).
CONDITION_CAP = 1e12


def normalised_interaction(points_cam: ArrayLike) -> np.ndarray:
    """Interaction matrix L (..., 2, 6) of normalised coordinates (x, y) = (X/Z, Y/Z), eq. 4.10–4.11.

    ``ẋ = L [v, ω]`` with ``L = [[-1/Z, 0, x/Z, xy, -(1+x²), y], [0, -1/Z, y/Z, 1+y², -xy, -x]]``.
    """
    P = np.asarray(points_cam, dtype=float)
    inv_z = 1.0 / np.maximum(P[..., 2], MIN_DEPTH_MM)
    x, y = P[..., 0] * inv_z, P[..., 1] * inv_z
    L = np.empty(P.shape[:-1] + (2, 6))
    L[..., 0, 0] = -inv_z
    L[..., 0, 1] = 0.0
    L[..., 0, 2] = x * inv_z
    L[..., 0, 3] = x * y
    L[..., 0, 4] = -(1.0 + x * x)
    L[..., 0, 5] = y
    L[..., 1, 0] = 0.0
    L[..., 1, 1] = -inv_z
    L[..., 1, 2] = y * inv_z
    L[..., 1, 3] = 1.0 + y * y
    L[..., 1, 4] = -L[..., 0, 3]
    L[..., 1, 5] = -x
    return L


def image_jacobian(camera: Camera, points_cam: ArrayLike) -> np.ndarray:
    """Pixel-unit image Jacobian J (..., 2, 6) of points (..., 3) in mm, camera frame: ṗ = J [v, ω].

    Thesis eq. 4.9–4.11 (f_C/s_x = fx, f_C/s_y = fy, principal point irrelevant for velocities), times
    the distortion Jacobian when the camera has lens distortion, so J matches finite differences of
    ``Camera.project`` under small camera motions. Units: px/mm (v columns) and px/rad (ω columns).
    """
    P = np.asarray(points_cam, dtype=float)
    L = normalised_interaction(P)
    if camera.has_distortion:
        D = camera.distortion_jacobian(Camera.normalize(P))
        return D @ L
    L[..., 0, :] *= camera.fx
    L[..., 1, :] *= camera.fy
    return L


def stacked_jacobian(camera: Camera, points_cam: ArrayLike, weights: ArrayLike | None = None) -> np.ndarray:
    """Stacked image Jacobian J_k (L, 2N, 6) of N points per pose (eq. 4.13–4.14); points (L, N, 3), mm.

    ``weights`` (L, N) multiply each point's two rows (0 removes an invisible feature); None = all 1.
    """
    J = image_jacobian(camera, points_cam)
    if weights is not None:
        J = J * np.asarray(weights, dtype=float)[..., None, None]
    return J.reshape(J.shape[:-3] + (-1, 6))


def gram(J: ArrayLike) -> np.ndarray:
    """JᵀJ (..., 6, 6) of stacked Jacobians (..., 2N, 6) — Σ_j J_jᵀ J_j over the 2×6 point blocks."""
    J = np.asarray(J, dtype=float)
    return np.swapaxes(J, -1, -2) @ J


def diagnostics_from_gram(G: ArrayLike) -> dict[str, np.ndarray]:
    """σ_min, condition σ_max/σ_min, manipulability √det(JᵀJ) (eq. 4.20–4.21), singular flag from JᵀJ.

    Singular values are square roots of the eigenvalues of JᵀJ (batched ``eigvalsh``), accurate to
    ~1e-8 σ_max — enough for the rank test σ_min ≤ ``SINGULAR_RTOL`` σ_max. A singular Jacobian (rank < 6:
    fewer than 3 usable features, collinear or degenerate sets, eq. 4.15 discussion) reports the
    finite ``CONDITION_CAP`` as its condition number.
    """
    lam = np.linalg.eigvalsh(np.asarray(G, dtype=float))
    sigma = np.sqrt(np.clip(lam, 0.0, None))
    s_min, s_max = sigma[..., 0], sigma[..., -1]
    singular = ~(s_min > SINGULAR_RTOL * s_max)
    with np.errstate(divide="ignore", invalid="ignore"):
        condition = np.where(singular, CONDITION_CAP, s_max / np.where(singular, 1.0, s_min))
    return {
        "sigma_min": s_min,
        "condition": np.minimum(condition, CONDITION_CAP),
        "manipulability": np.prod(sigma, axis=-1),
        "singular": singular,
    }


def jacobian_diagnostics(J: ArrayLike) -> dict[str, np.ndarray]:
    """Diagnostics of stacked Jacobians J (L, 2N, 6): dict of ``sigma_min`` (L,), ``condition`` (L,),
    ``manipulability`` (L,) (= σ_1⋯σ_6, eq. 4.20) and ``singular`` (L,) bool (rank < 6). See
    ``diagnostics_from_gram``."""
    return diagnostics_from_gram(gram(J))
