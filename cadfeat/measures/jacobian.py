"""Image Jacobian of point features and its diagnostics (thesis eq. 4.9–4.15, 4.20–4.21).

Convention (docs/design.md "Conventions", the same as ViSP's and the Machine Vision Toolbox's interaction
matrix): a point
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
from cadfeat.measures.lens import Array, distort_terms

#: A stacked Jacobian counts as singular (rank < 6) when σ_min ≤ SINGULAR_RTOL · σ_max.
SINGULAR_RTOL = 1e-6

#: Reported condition number of a singular Jacobian (finite, so sums over a trajectory stay finite).
CONDITION_CAP = 1e12


def fill_jacobian(out: list[np.ndarray], x: np.ndarray, y: np.ndarray, inv_z: np.ndarray,
                  D: tuple[Array, Array, Array, Array]) -> None:
    """Write the 12 entries of J = D · L (eq. 4.9–4.11) into the arrays ``out`` (views of one buffer), ordered
    column by column: [J_u0, J_v0, J_u1, J_v1, …, J_u5, J_v5]. x, y are normalised coordinates, inv_z = 1/Z
    (1/mm), D = (d00, d01, d10, d11) the pixel distortion Jacobian (arrays, or scalars without distortion;
    weights may be folded into D). L = [[-1/Z, 0, x/Z, xy, -(1+x²), y], [0, -1/Z, y/Z, 1+y², -xy, -x]]."""
    d00, d01, d10, d11 = D
    xy = x * y
    xx1 = 1.0 + x * x
    yy1 = 1.0 + y * y
    xiz, yiz = x * inv_z, y * inv_z
    mul = np.multiply
    if np.isscalar(d01) and np.isscalar(d10) and d01 == 0.0 and d10 == 0.0:  # no distortion: D diagonal
        mul(d00, inv_z, out=out[0])
        np.negative(out[0], out=out[0])
        out[1][...] = 0.0
        out[2][...] = 0.0
        mul(d11, inv_z, out=out[3])
        np.negative(out[3], out=out[3])
        mul(d00, xiz, out=out[4])
        mul(d11, yiz, out=out[5])
        mul(d00, xy, out=out[6])
        mul(d11, yy1, out=out[7])
        mul(d00, xx1, out=out[8])
        np.negative(out[8], out=out[8])
        mul(d11, xy, out=out[9])
        np.negative(out[9], out=out[9])
        mul(d00, y, out=out[10])
        mul(d11, x, out=out[11])
        np.negative(out[11], out=out[11])
        return
    for row, (da, db) in enumerate(((d00, d01), (d10, d11))):  # u row, v row
        o = out[row::2]
        mul(da, inv_z, out=o[0])
        np.negative(o[0], out=o[0])
        mul(db, inv_z, out=o[1])
        np.negative(o[1], out=o[1])
        mul(da, xiz, out=o[2])
        o[2] += mul(db, yiz)
        mul(da, xy, out=o[3])
        o[3] += mul(db, yy1)
        mul(da, xx1, out=o[4])
        o[4] += mul(db, xy)
        np.negative(o[4], out=o[4])
        mul(da, y, out=o[5])
        o[5] -= db * x


def image_jacobian(camera: Camera, points_cam: ArrayLike) -> np.ndarray:
    """Pixel-unit image Jacobian J (..., 2, 6) of points (..., 3) in mm, camera frame: ṗ = J [v, ω].

    Thesis eq. 4.9–4.11 (f_C/s_x = fx, f_C/s_y = fy, principal point irrelevant for velocities), times
    the distortion Jacobian when the camera has lens distortion, so J matches finite differences of
    ``Camera.project`` under small camera motions. Units: px/mm (v columns) and px/rad (ω columns).
    """
    P = np.asarray(points_cam, dtype=float)
    inv_z = 1.0 / np.maximum(P[..., 2], MIN_DEPTH_MM)
    x, y = P[..., 0] * inv_z, P[..., 1] * inv_z
    D = distort_terms(camera, x, y, positions=False)[2:]
    J = np.empty(x.shape + (2, 6))
    fill_jacobian([J[..., j % 2, j // 2] for j in range(12)], x, y, inv_z, D)
    return J


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

    Singular values are square roots of the eigenvalues of JᵀJ (batched ``eigvalsh``). The eigenvalues
    carry an absolute round-off of ~ε λ_max whatever the BLAS kernel, so σ_i is known to ~√ε σ_max
    (1e-8 σ_max) near zero and to a relative ε (σ_max/σ_i)² elsewhere — enough for the rank test
    σ_min ≤ ``SINGULAR_RTOL`` σ_max, not for the value of a vanishing σ. A singular Jacobian (rank < 6:
    fewer than 3 usable features, collinear or degenerate sets, eq. 4.15 discussion) therefore reports
    what its numerical rank defines, not round-off: σ_min = 0, manipulability √det(JᵀJ) = 0, and the
    finite ``CONDITION_CAP`` as its condition number.
    """
    lam = np.linalg.eigvalsh(np.asarray(G, dtype=float))
    sigma = np.sqrt(np.clip(lam, 0.0, None))
    s_min, s_max = sigma[..., 0], sigma[..., -1]
    singular = ~(s_min > SINGULAR_RTOL * s_max)
    with np.errstate(divide="ignore", invalid="ignore"):
        condition = np.where(singular, CONDITION_CAP, s_max / np.where(singular, 1.0, s_min))
    return {
        "sigma_min": np.where(singular, 0.0, s_min),
        "condition": np.minimum(condition, CONDITION_CAP),
        "manipulability": np.where(singular, 0.0, np.prod(sigma, axis=-1)),
        "singular": singular,
    }


def jacobian_diagnostics(J: ArrayLike) -> dict[str, np.ndarray]:
    """Diagnostics of stacked Jacobians J (L, 2N, 6): dict of ``sigma_min`` (L,), ``condition`` (L,),
    ``manipulability`` (L,) (= σ_1⋯σ_6, eq. 4.20) and ``singular`` (L,) bool (rank < 6). See
    ``diagnostics_from_gram``."""
    return diagnostics_from_gram(gram(J))
