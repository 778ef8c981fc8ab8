"""Image ellipses of hole rims (exact conic, docs/design.md "The measures") and of spheres (thesis eq. 3.13–3.18).

Rim circle: centre c, unit normal n (camera frame, mm), radius R. A ray m = (x, y, 1) (normalised
coordinates) meets the rim plane at t = (n·c)/(n·m); ‖t m − c‖² = R² multiplied by (n·m)² is the conic

    mᵀ C m = 0,   C = (n·c)² I − (n·c)(n cᵀ + c nᵀ) + (‖c‖² − R²) n nᵀ,

the same conic as H⁻ᵀ diag(1, 1, −R²) H⁻¹ with H = [u v c] for the rim plane (docs/design.md "The measures"), written
without the inverse. Sphere (thesis): the tangent cone of a sphere (centre c, radius R) is
C = c cᵀ − (‖c‖² − R²) I (eq. 3.17 with f_C = 1, up to sign and scale).

The conic's centre x₀ = −A⁻¹ b and shape M = A / (−k) (A its 2×2 block, b its linear part,
k = C₂₂ + bᵀx₀) give the ellipse (x − x₀)ᵀ M (x − x₀) = 1 in closed form (2×2 eigenvalues), with no
loops and no LAPACK. Pixels: the camera matrix maps it exactly (p = S x + p₀, S = diag(fx, fy)).

Lens distortion: the distorted rim is not an ellipse. ``hole_ellipse`` maps the undistorted ellipse
through the local affine approximation of the distortion at its centre — centre_px = distort(x₀),
M_px = D⁻ᵀ M D⁻¹ with D = ``Camera.distortion_jacobian(x₀)``. It is exact without distortion; with
distortion the error is second order in the ellipse size. Measured against ``cv2.fitEllipse`` of densely
``cv2.projectPoints``-projected rim points: for a typical lens (k1 = −0.21, 640×480, holes of 10–60 px)
axes within 0.04 % and centres within 0.15 px; for the thesis's very strong lens (k1 = −1.45, 128×128)
holes of ~10 px near the image corners differ by up to 6 % in axes and 2 px in centre (median 0.8 %) —
there the distorted rim is visibly not an ellipse. A secant (conjugate-diameter) variant was tried and
only moved the centre closer; not worth the extra cost in the hot path.

An ellipse is ``valid`` only when the whole rim (sphere) is in front of the camera (depth >
``MIN_DEPTH_MM``) and its conic is a real ellipse; invalid ones report the (clamped) projection of
the centre, zero axes and angle 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import MIN_DEPTH_MM, Camera
from cadfeat.measures.lens import Array, distort_terms


@dataclass(frozen=True)
class Ellipse:
    """Image ellipses: ``centre_px`` (..., 2), ``axes_px`` (..., 2) full lengths (major, minor) with
    major ≥ minor, ``angle_rad`` (...) of the major axis from the image u axis towards v, in [−π/2, π/2],
    and ``valid`` (...) bool (see the module docstring)."""

    centre_px: np.ndarray
    axes_px: np.ndarray
    angle_rad: np.ndarray
    valid: np.ndarray

    @property
    def minor_px(self) -> np.ndarray:
        """Minor full axis, px."""
        return self.axes_px[..., 1]

    @property
    def half_extent_px(self) -> np.ndarray:
        """Half-widths (..., 2) of the axis-aligned bounding box along u and v, px."""
        a, b = 0.5 * self.axes_px[..., 0], 0.5 * self.axes_px[..., 1]
        c, s = np.cos(self.angle_rad), np.sin(self.angle_rad)
        return np.stack([np.hypot(a * c, b * s), np.hypot(a * s, b * c)], axis=-1)


def _unit(v: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(norm > 0, norm, 1.0)


def rim_conic_xyz(X: np.ndarray, Y: np.ndarray, Z: np.ndarray, nx: np.ndarray, ny: np.ndarray, nz: np.ndarray,
                  nc: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, ...]:
    """Rim conic entries (a, b, c, d, e, f) from components: centre (X, Y, Z), unit normal (nx, ny, nz),
    nc = n·c and q = ‖c‖² − R² (camera frame, mm)."""
    nc2 = nc * nc
    qx, qy, qz = q * nx, q * ny, q * nz
    return (nc2 - nx * (2.0 * nc * X - qx),
            ny * (qx - nc * X) - nc * nx * Y,
            nc2 - ny * (2.0 * nc * Y - qy),
            nz * (qx - nc * X) - nc * nx * Z,
            nz * (qy - nc * Y) - nc * ny * Z,
            nc2 - nz * (2.0 * nc * Z - qz))


def rim_conic(centre_cam: ArrayLike, normal_cam: ArrayLike, radius_mm: ArrayLike) -> tuple[np.ndarray, ...]:
    """Entries (a, b, c, d, e, f) of the rim's normalised-image conic a x² + 2b xy + c y² + 2d x + 2e y + f."""
    c = np.asarray(centre_cam, dtype=float)
    n = _unit(np.asarray(normal_cam, dtype=float))
    R = np.asarray(radius_mm, dtype=float)
    nc = np.sum(n * c, axis=-1)
    q = np.sum(c * c, axis=-1) - R * R
    return rim_conic_xyz(c[..., 0], c[..., 1], c[..., 2], n[..., 0], n[..., 1], n[..., 2], nc, q)


def sphere_conic_xyz(X: np.ndarray, Y: np.ndarray, Z: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, ...]:
    """Sphere outline conic entries from components: centre (X, Y, Z), q = ‖c‖² − R² (camera frame, mm)."""
    return X * X - q, X * Y, Y * Y - q, X * Z, Y * Z, Z * Z - q


def sphere_conic(centre_cam: ArrayLike, radius_mm: ArrayLike) -> tuple[np.ndarray, ...]:
    """Entries (a, b, c, d, e, f) of the normalised-image outline conic of a sphere: C = c cᵀ − (‖c‖² − R²) I."""
    c = np.asarray(centre_cam, dtype=float)
    q = np.sum(c * c, axis=-1) - np.asarray(radius_mm, dtype=float) ** 2
    return sphere_conic_xyz(c[..., 0], c[..., 1], c[..., 2], q)


class EllipseParts(NamedTuple):
    """Component arrays of pixel ellipses: centre (u, v), full axes (major, minor), angle, bounding-box
    half-widths (hu, hv) and validity. Invalid entries have zero axes, angle and half-widths, and a finite
    but meaningless centre (callers substitute the projected centre)."""

    u: np.ndarray
    v: np.ndarray
    major: np.ndarray
    minor: np.ndarray
    angle: np.ndarray
    hu: np.ndarray
    hv: np.ndarray
    valid: np.ndarray


def ellipse_parts(camera: Camera, conic: tuple[np.ndarray, ...], in_front: np.ndarray) -> EllipseParts:
    """Pixel ellipse of a normalised-image conic (a, b, c, d, e, f) (module docstring), component arrays.

    ``in_front`` marks conics whose 3-D source lies wholly in front of the camera. Invalid entries are
    computed with safe substitutes (never inf/NaN) and zeroed by multiplying with the validity mask.
    """
    a, b, c, d, e, f = conic
    det = a * c - b * b
    ok = in_front & (det != 0)
    inv_det = 1.0 / np.where(ok, det, 1.0)
    x0 = (b * e - c * d) * inv_det
    y0 = (b * d - a * e) * inv_det
    k = f + d * x0 + e * y0
    ok &= k != 0
    s = -1.0 / np.where(ok, k, 1.0)
    ma, mb, mc = a * s, b * s, c * s  # M = A / (−k): (x − x0)ᵀ M (x − x0) = 1, normalised coordinates
    u, v, d00, d01, d10, d11 = distort_terms(camera, x0, y0)
    assert u is not None and v is not None  # positions=True
    if any(camera.dist):
        ma, mb, mc = _congruent_inverse(ma, mb, mc, d00, d01, d10, d11)
    else:
        ma, mb, mc = ma / (d00 * d00), mb / (d00 * d11), mc / (d11 * d11)
    half_tr = 0.5 * (ma + mc)
    h = 0.5 * (ma - mc)
    root = np.sqrt(h * h + mb * mb)
    lam_small = half_tr - root
    ok &= lam_small > 0
    lam_big, lam_small = np.where(ok, half_tr + root, 1.0), np.where(ok, lam_small, 1.0)
    okf = ok.astype(float)
    angle = _major_axis_angle(h, mb, root)
    inv_det_m = okf / (lam_big * lam_small)  # 1/det M (0 where invalid)
    return EllipseParts(
        u=np.asarray(u), v=np.asarray(v), major=okf * 2.0 / np.sqrt(lam_small), minor=okf * 2.0 / np.sqrt(lam_big),
        angle=angle * okf,
        hu=np.sqrt(np.abs(mc * inv_det_m)), hv=np.sqrt(np.abs(ma * inv_det_m)), valid=ok)


def _major_axis_angle(h: np.ndarray, mb: np.ndarray, root: np.ndarray) -> np.ndarray:
    """Angle in [−π/2, π/2] of the eigenvector of the smaller eigenvalue of [[p, mb], [mb, r]] (the major axis),
    h = (p − r)/2, root = √(h² + mb²). Uses ``arctan`` of a ratio bounded by 1 (no ``arctan2``, which is
    several times slower): the eigenvector is (root − h, −mb) for h < 0 and (−mb, h + root) for h ≥ 0."""
    den = root + np.abs(h)
    t = np.arctan(mb / np.where(den > 0, den, 1.0))
    return np.where(h >= 0, np.where(t > 0, t - 0.5 * np.pi, t + 0.5 * np.pi), -t)


def conic_to_ellipse(camera: Camera, conic: tuple[np.ndarray, ...], in_front: np.ndarray,
                     fallback_cam: np.ndarray) -> Ellipse:
    """``Ellipse`` of a normalised-image conic; invalid ones are centred on ``camera.project(fallback_cam)``."""
    parts = ellipse_parts(camera, conic, in_front)
    okx = parts.valid[..., None]
    centre = np.where(okx, np.stack([parts.u, parts.v], axis=-1), camera.project(fallback_cam))
    return Ellipse(centre_px=centre, axes_px=np.stack([parts.major, parts.minor], axis=-1),
                   angle_rad=parts.angle, valid=parts.valid)


def _congruent_inverse(ma: np.ndarray, mb: np.ndarray, mc: np.ndarray, d00: Array, d01: Array,
                       d10: Array, d11: Array) -> tuple[np.ndarray, ...]:
    """Entries of D⁻ᵀ M D⁻¹ = adj(D)ᵀ M adj(D) / det(D)² for symmetric M = [[ma, mb], [mb, mc]]."""
    det = d00 * d11 - d01 * d10
    w = 1.0 / np.where(det != 0, det * det, 1.0)
    # adj(D) = [[d11, −d01], [−d10, d00]]; t = M adj(D)
    t00 = ma * d11 - mb * d10
    t01 = mb * d00 - ma * d01
    t10 = mb * d11 - mc * d10
    t11 = mc * d00 - mb * d01
    return ((d11 * t00 - d10 * t10) * w, (d11 * t01 - d10 * t11) * w, (d00 * t11 - d01 * t01) * w)


def rim_min_depth_mm(centre_cam: ArrayLike, normal_cam: ArrayLike, radius_mm: ArrayLike) -> np.ndarray:
    """Smallest depth Z over the rim circle, mm: c_z − R √(1 − n_z²)."""
    c = np.asarray(centre_cam, dtype=float)
    n = _unit(np.asarray(normal_cam, dtype=float))
    return c[..., 2] - np.asarray(radius_mm, dtype=float) * np.sqrt(np.clip(1.0 - n[..., 2] ** 2, 0.0, None))


def hole_ellipse(camera: Camera, centre_cam: ArrayLike, normal_cam: ArrayLike, radius_mm: ArrayLike) -> Ellipse:
    """Image ellipse of a hole's rim circle (centre (..., 3), normal (..., 3), radius (...) mm, camera frame).

    Exact conic of the circle (docs/design.md "The measures", §3.3.3 done on the circle instead of the thesis's sphere);
    distortion by the local affine map at the centre (module docstring). Batched over leading axes.
    """
    c = np.asarray(centre_cam, dtype=float)
    n = np.asarray(normal_cam, dtype=float)
    R = np.asarray(radius_mm, dtype=float)
    in_front = rim_min_depth_mm(c, n, R) > MIN_DEPTH_MM
    return conic_to_ellipse(camera, rim_conic(c, n, R), in_front, c)


def sphere_ellipse(camera: Camera, centre_cam: ArrayLike, radius_mm: ArrayLike) -> Ellipse:
    """Image outline ellipse of a sphere (the thesis's model of a hole, eq. 3.13–3.18); valid when the
    whole sphere is in front of the camera (c_z − R > ``MIN_DEPTH_MM``)."""
    c = np.asarray(centre_cam, dtype=float)
    R = np.asarray(radius_mm, dtype=float)
    return conic_to_ellipse(camera, sphere_conic(c, R), c[..., 2] - R > MIN_DEPTH_MM, c)
