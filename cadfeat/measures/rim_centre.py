"""The measurement function of the pose filters: image positions of hole features and their Jacobian.

A hole is seen as the image of its rim circle, an ellipse. What a detector measures (``cv2.fitEllipse``
of the dark region) is the **centre of that ellipse**, which under perspective is *not* the image of the
rim's centre: the ellipse centre is the pole of the image's line at infinity, the projected circle centre
the pole of the plane's vanishing line. The offset grows with the radius and the obliquity (about
R²·sin θ·cos θ / Z² in normalised units — a few tenths of a pixel for typical holes, more near the
image border), so the filters model it instead of treating the hole as a point.

Conic of the rim (``cadfeat.measures.ellipse`` module docstring), centre c, unit normal n, radius R
(camera frame, mm), s = n·c, q = ‖c‖² − R²:

    C = s² I − s (n cᵀ + c nᵀ) + q n nᵀ,      A = C[:2, :2],  b = C[:2, 2],  x₀ = −A⁻¹ b.

The pixel measurement is ``distort(x₀)`` (the same centre as ``cadfeat.measures.hole_ellipse``).

Jacobian (convention of ``cadfeat.measures.image_jacobian``, thesis eq. 4.9–4.11): for a camera moving
with the screw γ = (v, ω) (camera frame) the rim moves as ċ = −v − ω × c, ṅ = −ω × n (eq. 4.3), so

    Ċ = 2 s ṡ I − ṡ (n cᵀ + c nᵀ) − s (ṅ cᵀ + n ċᵀ + ċ nᵀ + c ṅᵀ) + q̇ n nᵀ + q (ṅ nᵀ + n ṅᵀ),
    ṡ = ṅ·c + n·ċ,  q̇ = 2 c·ċ,   ẋ₀ = −A⁻¹ (Ȧ x₀ + ḃ),   ṗ = D(x₀) ẋ₀,

with D the pixel distortion Jacobian (``Camera.distortion_jacobian``). For R → 0 the ellipse shrinks to
the projected centre and this Jacobian becomes the point Jacobian ``image_jacobian`` (tested), which is the
measurement Jacobian used for point features (``radii_mm = 0``).

Pose perturbation (the filters' error state): T_cam_part = (R, p) perturbed on the left,
R ← exp([δθ]×) R, p ← p + δp, moves a part point as Ṗ = δp + δθ × (P − p); matching Ṗ = −v − ω × P gives
γ = M (δp, δθ) with ``M = [[−I, −[p]×], [0, −I]]`` (``pose_to_screw``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import MIN_DEPTH_MM, Camera
from cadfeat.measures.jacobian import image_jacobian
from cadfeat.measures.lens import distort_terms
from cadfeat.poses import hat


def _basis_motion(c: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ċ and ṅ (..., 6, 3) for the six unit camera screws e_j (v then ω), eq. 4.3: ċ = −e_j (j < 3),
    ċ = −e_j × c = [c]× e_j and ṅ = −e_j × n = [n]× e_j (j ≥ 3)."""
    dc = np.zeros(c.shape[:-1] + (6, 3))
    dn = np.zeros(c.shape[:-1] + (6, 3))
    dc[..., 0, 0] = dc[..., 1, 1] = dc[..., 2, 2] = -1.0
    dc[..., 3:, :] = np.swapaxes(hat(c), -1, -2)
    dn[..., 3:, :] = np.swapaxes(hat(n), -1, -2)
    return dc, dn


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)  # zero normals: point features


def _centre_system(c: np.ndarray, n: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, ...]:
    """A = C[:2, :2] entries (a00, a01, a11), b = C[:2, 2] (b0, b1), s = n·c, q = ‖c‖² − R² (module docstring)."""
    s = np.sum(n * c, axis=-1)
    q = np.sum(c * c, axis=-1) - R * R
    s2 = s * s
    a00 = s2 - 2.0 * s * n[..., 0] * c[..., 0] + q * n[..., 0] ** 2
    a11 = s2 - 2.0 * s * n[..., 1] * c[..., 1] + q * n[..., 1] ** 2
    a01 = -s * (n[..., 0] * c[..., 1] + c[..., 0] * n[..., 1]) + q * n[..., 0] * n[..., 1]
    b0 = -s * (n[..., 0] * c[..., 2] + c[..., 0] * n[..., 2]) + q * n[..., 0] * n[..., 2]
    b1 = -s * (n[..., 1] * c[..., 2] + c[..., 1] * n[..., 2]) + q * n[..., 1] * n[..., 2]
    return a00, a01, a11, b0, b1, s, q


def _solve_centre(c: np.ndarray, n: np.ndarray, R: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
    """Ellipse centre x₀ (..., 2), validity (...) and the system (``_centre_system``) it came from."""
    system = _centre_system(c, n, R)
    a00, a01, a11, b0, b1 = system[:5]
    det = a00 * a11 - a01 * a01
    ok = (R > 0) & (np.abs(det) > 1e-300)
    inv = 1.0 / np.where(ok, det, 1.0)
    x0 = -(a11 * b0 - a01 * b1) * inv
    y0 = -(a00 * b1 - a01 * b0) * inv
    point = c[..., :2] / np.maximum(c[..., 2:3], MIN_DEPTH_MM)
    return np.where(ok[..., None], np.stack([x0, y0], axis=-1), point), ok, system


def _inputs(centre_cam: ArrayLike, normal_cam: ArrayLike, radius_mm: ArrayLike) -> tuple[np.ndarray, ...]:
    c = np.asarray(centre_cam, dtype=float)
    n = _unit(np.asarray(normal_cam, dtype=float))
    R = np.broadcast_to(np.asarray(radius_mm, dtype=float), c.shape[:-1])
    return c, n, R


def rim_centre_normalised(centre_cam: ArrayLike, normal_cam: ArrayLike, radius_mm: ArrayLike) -> np.ndarray:
    """Centre x₀ (..., 2) of the rim's image ellipse in normalised coordinates (no distortion, no K).

    centre_cam, normal_cam (..., 3) mm / unit, radius_mm (...) mm. R = 0 gives the projection (X/Z, Y/Z)
    (the conic degenerates to that point).
    """
    return _solve_centre(*_inputs(centre_cam, normal_cam, radius_mm))[0]


def rim_centre_px(camera: Camera, centre_cam: ArrayLike, normal_cam: ArrayLike, radius_mm: ArrayLike) -> np.ndarray:
    """Measured pixel position (..., 2) of holes: the centre of each rim's image ellipse, distortion applied.

    Equals ``cadfeat.measures.hole_ellipse(...).centre_px`` for valid ellipses; ``radius_mm = 0`` gives
    ``camera.project(centre_cam)`` (a point feature).
    """
    return camera.distort_normalized(rim_centre_normalised(centre_cam, normal_cam, radius_mm))


def _centre_and_jacobian(camera: Camera, c: np.ndarray, n: np.ndarray, R: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (..., 2) and ∂/∂γ (..., 2, 6) of the ellipse centres (module docstring).

    With m = (x₀, y₀, 1) the first two rows of C m vanish, so A ẋ₀ = −(Ċ m)[:2], and Ċ m needs only the
    products c·m, n·m, ċ·m, ṅ·m — no 3×3 matrix derivatives.
    """
    x0, ok, (a00, a01, a11, _, _, s, q) = _solve_centre(c, n, R)
    m = np.concatenate([x0, np.ones(x0.shape[:-1] + (1,))], axis=-1)
    dc, dn = _basis_motion(c, n)                                           # (..., 6, 3)
    ds = (dn @ c[..., :, None] + dc @ n[..., :, None])[..., 0]            # ṡ (..., 6)
    dq = 2.0 * (dc @ c[..., :, None])[..., 0]                             # q̇
    dcm = (dc @ m[..., :, None])[..., 0]                                  # ċ·m, ṅ·m (..., 6)
    dnm = (dn @ m[..., :, None])[..., 0]
    cm, nm = np.sum(c * m, axis=-1), np.sum(n * m, axis=-1)
    S, Q, CM, NM = s[..., None, None], q[..., None, None], cm[..., None, None], nm[..., None, None]
    c2, n2, m2 = c[..., None, :2], n[..., None, :2], m[..., None, :2]
    dCm = (2.0 * S * ds[..., None] * m2 - ds[..., None] * (n2 * CM + c2 * NM)
           - S * (dn[..., :2] * CM + n2 * dcm[..., None] + dc[..., :2] * NM + c2 * dnm[..., None])
           + dq[..., None] * n2 * NM + Q * (dn[..., :2] * NM + n2 * dnm[..., None]))    # (..., 6, 2)
    det = a00 * a11 - a01 * a01
    inv = 1.0 / np.where(ok, det, 1.0)
    dx = -(a11[..., None] * dCm[..., 0] - a01[..., None] * dCm[..., 1]) * inv[..., None]  # (..., 6)
    dy = -(a00[..., None] * dCm[..., 1] - a01[..., None] * dCm[..., 0]) * inv[..., None]
    u, v, d00, d01, d10, d11 = distort_terms(camera, x0[..., 0], x0[..., 1])
    J = np.empty(x0.shape[:-1] + (2, 6))
    J[..., 0, :] = np.asarray(d00)[..., None] * dx + np.asarray(d01)[..., None] * dy
    J[..., 1, :] = np.asarray(d10)[..., None] * dx + np.asarray(d11)[..., None] * dy
    if not np.all(ok):
        J = np.where(ok[..., None, None], J, image_jacobian(camera, c))
    assert u is not None and v is not None  # (distort_terms with positions=True)
    return np.stack([u, v], axis=-1), J


def rim_centre_jacobian(camera: Camera, centre_cam: ArrayLike, normal_cam: ArrayLike,
                        radius_mm: ArrayLike) -> np.ndarray:
    """∂(ellipse centre px)/∂γ (..., 2, 6) for the camera screw γ = (v, ω) (mm/s, rad/s, camera frame).

    Module docstring for the derivation. Same convention and units as ``cadfeat.measures.image_jacobian``
    (px/mm, px/rad), to which it reduces for ``radius_mm = 0``.
    """
    return _centre_and_jacobian(camera, *_inputs(centre_cam, normal_cam, radius_mm))[1]


def pose_to_screw(p_mm: ArrayLike) -> np.ndarray:
    """M (..., 6, 6) with γ = M (δp, δθ) for the left pose perturbation of T_cam_part (module docstring)."""
    p = np.asarray(p_mm, dtype=float)
    M = np.zeros(p.shape[:-1] + (6, 6))
    M[..., :3, :3] = -np.eye(3)
    M[..., :3, 3:] = -hat(p)
    M[..., 3:, 3:] = -np.eye(3)
    return M


def measure(camera: Camera, T_cam_part: np.ndarray, points_part: np.ndarray, normals_part: np.ndarray,
            radii_mm: np.ndarray, jacobian: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """Predicted measurements (..., N, 2) px at poses T_cam_part (..., 4, 4), and ∂z/∂(δp, δθ) (..., N, 2, 6).

    points_part, normals_part (N, 3) part frame (mm, unit outward axes), radii_mm (N,) (0 = point feature).
    """
    T = np.asarray(T_cam_part, dtype=float)
    Rm, p = T[..., :3, :3], T[..., :3, 3]
    Rt = np.swapaxes(Rm, -1, -2)  # R x as x Rᵀ (one GEMM per pose, broadcast): holes (N, 3) or one set per pose
    c = np.asarray(points_part, dtype=float) @ Rt + p[..., None, :]
    n = np.asarray(normals_part, dtype=float) @ Rt
    R = np.broadcast_to(np.asarray(radii_mm, dtype=float), c.shape[:-1])
    if not jacobian:
        return rim_centre_px(camera, c, n, R), None
    z, J = _centre_and_jacobian(camera, c, _unit(n), R)
    return z, J @ pose_to_screw(p)[..., None, :, :]
