"""Image ellipses of hole rims (exact conic, DESIGN.md §Resolution) and of spheres (thesis eq. 3.13–3.18).

Rim circle: centre c, unit normal n (camera frame, mm), radius R. A ray m = (x, y, 1) (normalised
coordinates) meets the rim plane at t = (n·c)/(n·m); ‖t m − c‖² = R² multiplied by (n·m)² is the conic

    mᵀ C m = 0,   C = (n·c)² I − (n·c)(n cᵀ + c nᵀ) + (‖c‖² − R²) n nᵀ,

the same conic as H⁻ᵀ diag(1, 1, −R²) H⁻¹ with H = [u v c] for the rim plane (DESIGN.md), written
without the inverse. Sphere (thesis): the tangent cone of a sphere (centre c, radius R) is
C = c cᵀ − (‖c‖² − R²) I (eq. 3.17 with f_C = 1, up to sign and scale).

The conic's centre x₀ = −A⁻¹ b and shape M = A / (−k) (A its 2×2 block, b its linear part,
k = C₂₂ + bᵀx₀) give the ellipse (x − x₀)ᵀ M (x − x₀) = 1 in closed form (2×2 eigenvalues), with no
loops and no LAPACK. Pixels: the camera matrix maps it exactly (p = S x + p₀, S = diag(fx, fy)).

Lens distortion: the distorted rim is not an ellipse. ``hole_ellipse`` maps the undistorted ellipse
through the local affine approximation of the distortion at its centre — centre_px = distort(x₀),
M_px = D⁻ᵀ M D⁻¹ with D = ``Camera.distortion_jacobian(x₀)``. It is exact without distortion; with
distortion the error is second order in the ellipse size (tests: against ``cv2.fitEllipse`` of
``cv2.projectPoints`` rim points).

An ellipse is ``valid`` only when the whole rim (sphere) is in front of the camera (depth >
``MIN_DEPTH_MM``) and its conic is a real ellipse; invalid ones report the (clamped) projection of
the centre, zero axes and angle 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import MIN_DEPTH_MM, Camera


@dataclass(frozen=True)
class Ellipse:
    """Image ellipses: ``centre_px`` (..., 2), ``axes_px`` (..., 2) full lengths (major, minor) with
    major ≥ minor, ``angle_rad`` (...) of the major axis from the image u axis towards v, in [−π/2, π/2),
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


def rim_conic(centre_cam: ArrayLike, normal_cam: ArrayLike, radius_mm: ArrayLike) -> tuple[np.ndarray, ...]:
    """Entries (a, b, c, d, e, f) of the rim's normalised-image conic a x² + 2b xy + c y² + 2d x + 2e y + f."""
    c = np.asarray(centre_cam, dtype=float)
    n = _unit(np.asarray(normal_cam, dtype=float))
    R = np.asarray(radius_mm, dtype=float)
    nc = np.sum(n * c, axis=-1)
    q = np.sum(c * c, axis=-1) - R * R
    nc2 = nc * nc
    n0, n1, n2 = n[..., 0], n[..., 1], n[..., 2]
    c0, c1, c2 = c[..., 0], c[..., 1], c[..., 2]
    return (nc2 - 2.0 * nc * n0 * c0 + q * n0 * n0,
            -nc * (n0 * c1 + c0 * n1) + q * n0 * n1,
            nc2 - 2.0 * nc * n1 * c1 + q * n1 * n1,
            -nc * (n0 * c2 + c0 * n2) + q * n0 * n2,
            -nc * (n1 * c2 + c1 * n2) + q * n1 * n2,
            nc2 - 2.0 * nc * n2 * c2 + q * n2 * n2)


def sphere_conic(centre_cam: ArrayLike, radius_mm: ArrayLike) -> tuple[np.ndarray, ...]:
    """Entries (a, b, c, d, e, f) of the normalised-image outline conic of a sphere: C = c cᵀ − (‖c‖² − R²) I."""
    c = np.asarray(centre_cam, dtype=float)
    R = np.asarray(radius_mm, dtype=float)
    q = np.sum(c * c, axis=-1) - R * R
    c0, c1, c2 = c[..., 0], c[..., 1], c[..., 2]
    return c0 * c0 - q, c0 * c1, c1 * c1 - q, c0 * c2, c1 * c2, c2 * c2 - q


def conic_to_ellipse(camera: Camera, conic: tuple[np.ndarray, ...], in_front: np.ndarray,
                     fallback_cam: np.ndarray) -> Ellipse:
    """Pixel ellipse of a normalised-image conic (a, b, c, d, e, f); see the module docstring.

    ``in_front`` (...) marks conics whose 3-D source lies wholly in front of the camera;
    ``fallback_cam`` (..., 3) is projected as the centre of invalid ellipses.
    """
    a, b, c, d, e, f = conic
    det = a * c - b * b
    ok = in_front & (np.abs(det) > 0)
    det = np.where(ok, det, 1.0)
    x0 = (b * e - c * d) / det
    y0 = (b * d - a * e) / det
    k = f + d * x0 + e * y0
    ok &= np.abs(k) > 0
    s = -1.0 / np.where(ok, k, 1.0)
    ma, mb, mc = a * s, b * s, c * s  # M = A / (−k) in normalised coordinates
    xy0 = np.stack([x0, y0], axis=-1)
    if camera.has_distortion:
        D = camera.distortion_jacobian(xy0)
        centre = camera.distort_normalized(xy0)
        ma, mb, mc = _congruent_inverse(ma, mb, mc, D)
    else:
        centre = np.stack([camera.fx * x0 + camera.cx, camera.fy * y0 + camera.cy], axis=-1)
        ma, mb, mc = ma / (camera.fx * camera.fx), mb / (camera.fx * camera.fy), mc / (camera.fy * camera.fy)
    half_tr = 0.5 * (ma + mc)
    root = np.hypot(0.5 * (ma - mc), mb)
    lam_big, lam_small = half_tr + root, half_tr - root
    ok &= lam_small > 0
    lam_big, lam_small = np.where(ok, lam_big, 1.0), np.where(ok, lam_small, 1.0)
    axes = np.stack([2.0 / np.sqrt(lam_small), 2.0 / np.sqrt(lam_big)], axis=-1)
    angle = 0.5 * np.arctan2(2.0 * mb, ma - mc) + 0.5 * np.pi  # major axis ⟂ eigenvector of λ_big
    angle = np.mod(angle + 0.5 * np.pi, np.pi) - 0.5 * np.pi
    okx = ok[..., None]
    centre = np.where(okx, centre, camera.project(fallback_cam))
    return Ellipse(centre_px=centre, axes_px=np.where(okx, axes, 0.0), angle_rad=np.where(ok, angle, 0.0), valid=ok)


def _congruent_inverse(ma: np.ndarray, mb: np.ndarray, mc: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, ...]:
    """Entries of D⁻ᵀ M D⁻¹ for symmetric M = [[ma, mb], [mb, mc]] and D (..., 2, 2)."""
    d00, d01, d10, d11 = D[..., 0, 0], D[..., 0, 1], D[..., 1, 0], D[..., 1, 1]
    det = d00 * d11 - d01 * d10
    det = np.where(det != 0, det, 1.0)
    i00, i01, i10, i11 = d11 / det, -d01 / det, -d10 / det, d00 / det  # D⁻¹
    # (D⁻ᵀ M D⁻¹)_{pq} = Σ_rs i_{rp} M_{rs} i_{sq}
    t00 = ma * i00 + mb * i10
    t01 = ma * i01 + mb * i11
    t10 = mb * i00 + mc * i10
    t11 = mb * i01 + mc * i11
    return (i00 * t00 + i10 * t10, i00 * t01 + i10 * t11, i01 * t01 + i11 * t11)


def rim_min_depth_mm(centre_cam: ArrayLike, normal_cam: ArrayLike, radius_mm: ArrayLike) -> np.ndarray:
    """Smallest depth Z over the rim circle, mm: c_z − R √(1 − n_z²)."""
    c = np.asarray(centre_cam, dtype=float)
    n = _unit(np.asarray(normal_cam, dtype=float))
    return c[..., 2] - np.asarray(radius_mm, dtype=float) * np.sqrt(np.clip(1.0 - n[..., 2] ** 2, 0.0, None))


def hole_ellipse(camera: Camera, centre_cam: ArrayLike, normal_cam: ArrayLike, radius_mm: ArrayLike) -> Ellipse:
    """Image ellipse of a hole's rim circle (centre (..., 3), normal (..., 3), radius (...) mm, camera frame).

    Exact conic of the circle (DESIGN.md, §3.3.3 done on the circle instead of the thesis's sphere);
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
