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
from cadfeat.measures import image_jacobian
from cadfeat.poses import hat


def _basis_motion(c: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ċ and ṅ (..., 6, 3) for the six unit camera screws e_j (v then ω), eq. 4.3."""
    eye = np.eye(3)
    dc = np.empty(c.shape[:-1] + (6, 3))
    dn = np.zeros(c.shape[:-1] + (6, 3))
    dc[..., :3, :] = -eye
    dc[..., 3:, :] = -np.cross(eye, c[..., None, :])           # −e_j × c
    dn[..., 3:, :] = -np.cross(eye, n[..., None, :])           # −e_j × n
    return dc, dn


def _rim_conic_matrix(c: np.ndarray, n: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The rim conic C (..., 3, 3) in normalised image coordinates (module docstring)."""
    s = np.sum(n * c, axis=-1)[..., None, None]
    q = (np.sum(c * c, axis=-1) - R * R)[..., None, None]
    nc = n[..., :, None] * c[..., None, :]
    nn = n[..., :, None] * n[..., None, :]
    return s * s * np.eye(3) - s * (nc + np.swapaxes(nc, -1, -2)) + q * nn


def rim_centre_normalised(centre_cam: ArrayLike, normal_cam: ArrayLike, radius_mm: ArrayLike) -> np.ndarray:
    """Centre x₀ (..., 2) of the rim's image ellipse in normalised coordinates (no distortion, no K).

    centre_cam, normal_cam (..., 3) mm / unit, radius_mm (...) mm. R = 0 gives (X/Z, Y/Z). The centre must be
    in front of the camera; for R = 0 the conic is degenerate and the projection is returned directly.
    """
    c = np.asarray(centre_cam, dtype=float)
    n = np.asarray(normal_cam, dtype=float)
    n = n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)  # zero normals: point features
    R = np.broadcast_to(np.asarray(radius_mm, dtype=float), c.shape[:-1])
    point = c[..., :2] / np.maximum(c[..., 2:3], MIN_DEPTH_MM)
    if not np.any(R > 0):
        return point
    C = _rim_conic_matrix(c, n, R)
    A, b = C[..., :2, :2], C[..., :2, 2]
    det = A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]
    ok = (R > 0) & (np.abs(det) > 0)
    safe = np.where(ok, det, 1.0)
    x0 = -(A[..., 1, 1] * b[..., 0] - A[..., 0, 1] * b[..., 1]) / safe
    y0 = -(A[..., 0, 0] * b[..., 1] - A[..., 1, 0] * b[..., 0]) / safe
    return np.where(ok[..., None], np.stack([x0, y0], axis=-1), point)


def rim_centre_px(camera: Camera, centre_cam: ArrayLike, normal_cam: ArrayLike, radius_mm: ArrayLike) -> np.ndarray:
    """Measured pixel position (..., 2) of holes: the centre of each rim's image ellipse, distortion applied.

    Equals ``cadfeat.measures.hole_ellipse(...).centre_px`` for valid ellipses; ``radius_mm = 0`` gives
    ``camera.project(centre_cam)`` (a point feature).
    """
    return camera.distort_normalized(rim_centre_normalised(centre_cam, normal_cam, radius_mm))


def rim_centre_jacobian(camera: Camera, centre_cam: ArrayLike, normal_cam: ArrayLike,
                        radius_mm: ArrayLike) -> np.ndarray:
    """∂(ellipse centre px)/∂γ (..., 2, 6) for the camera screw γ = (v, ω) (mm/s, rad/s, camera frame).

    Module docstring for the derivation. Same convention and units as ``cadfeat.measures.image_jacobian``
    (px/mm, px/rad), to which it reduces for ``radius_mm = 0``.
    """
    c = np.asarray(centre_cam, dtype=float)
    n = np.asarray(normal_cam, dtype=float)
    n = n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)  # zero normals: point features
    R = np.broadcast_to(np.asarray(radius_mm, dtype=float), c.shape[:-1])
    J_point = image_jacobian(camera, c)
    if not np.any(R > 0):
        return J_point
    C = _rim_conic_matrix(c, n, R)
    A, b = C[..., :2, :2], C[..., :2, 2]
    det = A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]
    ok = (R > 0) & (np.abs(det) > 0)
    A_inv = np.linalg.inv(np.where(ok[..., None, None], A, np.eye(2)))
    x0 = -np.einsum("...ij,...j->...i", A_inv, b)
    dc, dn = _basis_motion(c, n)                                           # (..., 6, 3)
    s = np.sum(n * c, axis=-1)[..., None]                                  # (..., 1)
    q = (np.sum(c * c, axis=-1) - R * R)[..., None]
    ds = np.einsum("...jk,...k->...j", dn, c) + np.einsum("...jk,...k->...j", dc, n)    # (..., 6)
    dq = 2.0 * np.einsum("...jk,...k->...j", dc, c)
    cc, nn = c[..., None, :], n[..., None, :]                              # (..., 1, 3)

    def outer(a: np.ndarray, b_: np.ndarray) -> np.ndarray:
        return a[..., :, None] * b_[..., None, :]

    sym_nc = outer(nn, cc) + outer(cc, nn)                                 # (..., 1, 3, 3)
    dC = (2.0 * (s * ds)[..., None, None] * np.eye(3)
          - ds[..., None, None] * sym_nc
          - s[..., None, None] * (outer(dn, cc) + outer(nn, dc) + outer(dc, nn) + outer(cc, dn))
          + dq[..., None, None] * outer(nn, nn)
          + q[..., None, None] * (outer(dn, nn) + outer(nn, dn)))          # (..., 6, 3, 3)
    dA, db = dC[..., :2, :2], dC[..., :2, 2]
    rhs = np.einsum("...jab,...b->...ja", dA, x0) + db                     # (..., 6, 2)
    dx0 = -np.einsum("...ab,...jb->...aj", A_inv, rhs)                     # (..., 2, 6)
    D = camera.distortion_jacobian(x0)                                     # (..., 2, 2)
    J = D @ dx0
    return np.where(ok[..., None, None], J, J_point)


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
    """Predicted measurements (N, 2) px at pose T_cam_part (4, 4), and ∂z/∂(δp, δθ) (N, 2, 6) if asked.

    points_part, normals_part (N, 3) part frame (mm, unit outward axes), radii_mm (N,) (0 = point feature).
    """
    Rm, p = T_cam_part[:3, :3], T_cam_part[:3, 3]
    c = points_part @ Rm.T + p
    n = normals_part @ Rm.T
    z = rim_centre_px(camera, c, n, radii_mm)
    if not jacobian:
        return z, None
    return z, rim_centre_jacobian(camera, c, n, radii_mm) @ pose_to_screw(p)
