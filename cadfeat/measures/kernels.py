"""Compiled (numba) kernel of the Jacobian part of ``evaluate``: JᵀJ and ‖J γ̇‖ per pose, fused.

Same entries as ``jacobian.fill_jacobian`` (eq. 4.9–4.11, J = D · L, distortion Jacobian D) accumulated point
by point into the 6×6 Gram matrix J̃ᵀJ̃ (J̃ = J diag(1, 1, 1, 1/ℓ, 1/ℓ, 1/ℓ)) and the image speed ‖J γ̇‖,
without the (L, 6, 2N) stacked Jacobian and the ~50 full-size temporaries of the numpy path. Only
feature-poses of non-zero weight contribute (their rows are zero in the numpy path). Results agree with
the numpy path to rounding (different summation order). numba comes with cadquery; without it
``gram_and_speed()`` is None and ``evaluate`` uses the numpy path. Compiled on first use (cached on disk).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np


def _gram_and_speed(x: np.ndarray, y: np.ndarray, inv_z: np.ndarray, d00: np.ndarray, d01: np.ndarray,
                    d10: np.ndarray, d11: np.ndarray, w: np.ndarray, screws: np.ndarray, ell: float,
                    gram: np.ndarray, speed: np.ndarray) -> None:
    """Per pose l: gram[l] = Σ_j w² J̃_jᵀ J̃_j (6×6) and speed[l] = ‖J γ̇_l‖ of the rows J_j scaled by w[l, j]
    (features with w = 0 skipped).

    x, y normalised coordinates, inv_z = 1/Z (1/mm), d.. the pixel distortion Jacobian (all (L, N), the
    d.. may be broadcast views), w (L, N) bool or float weights, screws (L, 6), ell = ℓ (mm)."""
    L, N = x.shape
    ju = np.empty(6)
    jv = np.empty(6)
    for l in range(L):
        g = np.zeros((6, 6))
        sq = 0.0
        for j in range(N):
            if not w[l, j]:
                continue
            xl, yl, iz = x[l, j], y[l, j], inv_z[l, j]
            xy = xl * yl
            xx1 = 1.0 + xl * xl
            yy1 = 1.0 + yl * yl
            xiz, yiz = xl * iz, yl * iz
            for row in range(2):
                if row == 0:
                    da, db, jr = d00[l, j], d01[l, j], ju
                else:
                    da, db, jr = d10[l, j], d11[l, j], jv
                jr[0] = -(da * iz)
                jr[1] = -(db * iz)
                jr[2] = da * xiz + db * yiz
                jr[3] = da * xy + db * yy1
                jr[4] = -(da * xx1 + db * xy)
                jr[5] = da * yl - db * xl
            wj = w[l, j]
            if wj != 1:  # a partly seen feature: its rows scaled by its weight (``evaluate``: the rim seen)
                for k in range(6):
                    ju[k] *= wj
                    jv[k] *= wj
            fu = 0.0
            fv = 0.0
            for k in range(6):
                fu += screws[l, k] * ju[k]
                fv += screws[l, k] * jv[k]
            sq += fu * fu + fv * fv
            for k in range(3, 6):
                ju[k] /= ell
                jv[k] /= ell
            for a in range(6):
                for b in range(a, 6):
                    g[a, b] += ju[a] * ju[b] + jv[a] * jv[b]
        for a in range(6):
            for b in range(a, 6):
                gram[l, a, b] = g[a, b]
                gram[l, b, a] = g[a, b]
        speed[l] = np.sqrt(sq)


@functools.cache
def compiled(func: Callable[..., None]) -> Callable[..., None] | None:
    """``func`` compiled by numba (imported and compiled on the first call, cached on disk), or None without
    numba (the callers then use their numpy form)."""
    try:  # numba is a cadquery dependency; fall back to numpy without it
        import numba
    except ImportError:  # pragma: no cover - exercised only without numba
        return None
    return numba.njit(cache=True, nogil=True, error_model="numpy")(func)


def gram_and_speed() -> Callable[..., None] | None:
    """The compiled kernel (numba imported and the kernel compiled on first call), or None without numba."""
    return compiled(_gram_and_speed)


def _nmin(a: float, b: float) -> float:
    """``numpy.minimum`` of two floats (NaN propagates)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a < b else b


def _nmax(a: float, b: float) -> float:
    """``numpy.maximum`` of two floats (NaN propagates)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a > b else b


def _distort(x: float, y: float, cam: np.ndarray, mode: int) -> tuple[float, ...]:
    """``lens.distort_terms`` on one point, same operation order. cam = (fx, fy, cx, cy, k1, k2, p1, p2, k3);
    mode 0: no distortion, 1: k1 only, 2: up to k2, 3: up to k3 (``lens._radial``)."""
    fx, fy, cx, cy, k1, k2, p1, p2, k3 = cam[0], cam[1], cam[2], cam[3], cam[4], cam[5], cam[6], cam[7], cam[8]
    if mode == 0:
        return fx * x + cx, fy * y + cy, fx, 0.0, 0.0, fy
    xx, yy, xy = x * x, y * y, x * y
    r2 = xx + yy
    if mode == 3:
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        g = 2.0 * k1 + r2 * (4.0 * k2 + 6.0 * k3 * r2)
    elif mode == 2:
        t = k2 * r2
        radial = 1.0 + r2 * (k1 + t)
        g = 2.0 * k1 + 4.0 * t
    else:
        radial = 1.0 + k1 * r2
        g = 2.0 * k1
    xd, yd = x * radial, y * radial
    tangential = p1 != 0.0 or p2 != 0.0
    if tangential:
        xd += 2.0 * p1 * xy + p2 * (r2 + 2.0 * xx)
        yd += p1 * (r2 + 2.0 * yy) + 2.0 * p2 * xy
    cross = g * xy
    d00 = radial + g * xx
    d11 = radial + g * yy
    if tangential:
        cross += 2.0 * (p1 * x + p2 * y)
        d00 += 2.0 * p1 * y + 6.0 * p2 * x
        d11 += 6.0 * p1 * y + 2.0 * p2 * x
    return fx * xd + cx, fy * yd + cy, fx * d00, fx * cross, fy * cross, fy * d11


def _ellipse(a: float, b: float, c: float, d: float, e: float, f: float, in_front: bool, cam: np.ndarray,
             mode: int) -> tuple:
    """``ellipse.ellipse_parts`` of one conic, same operation order: (u, v, major, minor, angle, hu, hv, ok)."""
    det = a * c - b * b
    ok = in_front and det != 0
    inv_det = 1.0 / (det if ok else 1.0)
    x0 = (b * e - c * d) * inv_det
    y0 = (b * d - a * e) * inv_det
    k = f + d * x0 + e * y0
    ok = ok and k != 0
    s = -1.0 / (k if ok else 1.0)
    ma, mb, mc = a * s, b * s, c * s
    u, v, d00, d01, d10, d11 = _distort(x0, y0, cam, mode)
    if mode != 0:
        detd = d00 * d11 - d01 * d10
        w = 1.0 / (detd * detd if detd != 0 else 1.0)
        t00 = ma * d11 - mb * d10
        t01 = mb * d00 - ma * d01
        t10 = mb * d11 - mc * d10
        t11 = mc * d00 - mb * d01
        ma, mb, mc = (d11 * t00 - d10 * t10) * w, (d11 * t01 - d10 * t11) * w, (d00 * t11 - d01 * t01) * w
    else:
        ma, mb, mc = ma / (d00 * d00), mb / (d00 * d11), mc / (d11 * d11)
    half_tr = 0.5 * (ma + mc)
    h = 0.5 * (ma - mc)
    root = np.sqrt(h * h + mb * mb)
    lam_small = half_tr - root
    ok = ok and lam_small > 0
    lam_big = half_tr + root if ok else 1.0
    lam_small = lam_small if ok else 1.0
    okf = 1.0 if ok else 0.0
    den = root + abs(h)
    t = np.arctan(mb / (den if den > 0 else 1.0))
    if h >= 0:
        angle = t - 0.5 * np.pi if t > 0 else t + 0.5 * np.pi
    else:
        angle = -t
    inv_det_m = okf / (lam_big * lam_small)
    return (u, v, okf * 2.0 / np.sqrt(lam_small), okf * 2.0 / np.sqrt(lam_big), angle * okf,
            np.sqrt(abs(mc * inv_det_m)), np.sqrt(abs(ma * inv_det_m)), ok)


def _features(X, Y, Z, nx, ny, nz, nc, dist2, r, cam, mode, consts, sphere, out_f, visible, valid, centre, axes,
              lens):  # noqa: ANN001 - numba kernel
    """Per feature-pose measures of ``evaluate._evaluate`` (same formulas and order), one pass over (L, N).

    consts = (min_depth, W, H, cos_half, near, far, focus_scale, min_axis_px, penalty, low).
    out_f (7, L, N): fov, fov_px, focus, resolution_px, minor_axis_px, facing, angle_rad; visible (L, N) (before
    occlusion), valid (L, N) rim ellipse valid, centre (L, N, 2) rim ellipse centre px, axes (L, N, 2) px;
    lens (7, L, N): x, y, inv_z, d00, d01, d10, d11 of the centres' projections (for the Jacobian)."""
    L, N = X.shape
    min_depth, W, H, cos_half, near, far = consts[0], consts[1], consts[2], consts[3], consts[4], consts[5]
    fscale, min_axis, penalty, low = consts[6], consts[7], consts[8], consts[9]
    far_finite = np.isfinite(far)
    for l in range(L):
        for j in range(N):
            Xv, Yv, Zv, nxv, nyv, nzv, ncv, d2 = (X[l, j], Y[l, j], Z[l, j], nx[l, j], ny[l, j], nz[l, j],
                                                   nc[l, j], dist2[l, j])
            rv = r[j]
            dist = np.sqrt(_nmax(d2, 0.0))
            in_front = Zv - rv * np.sqrt(_nmax(1.0 - nzv * nzv, 0.0)) > min_depth
            q = d2 - rv * rv
            nc2 = ncv * ncv
            qx, qy, qz = q * nxv, q * nyv, q * nzv
            u, v, major, minor, angle, hu, hv, ok = _ellipse(
                nc2 - nxv * (2.0 * ncv * Xv - qx), nyv * (qx - ncv * Xv) - ncv * nxv * Yv,
                nc2 - nyv * (2.0 * ncv * Yv - qy), nzv * (qx - ncv * Xv) - ncv * nxv * Zv,
                nzv * (qy - ncv * Yv) - ncv * nyv * Zv, nc2 - nzv * (2.0 * ncv * Zv - qz), in_front, cam, mode)
            margin = _nmin(_nmin(u - hu, W - u - hu), _nmin(v - hv, H - v - hv))
            fov_px = _nmax(margin, low) if ok else low
            inv_dist = 1.0 / (dist if dist > 0 else 1.0)
            facing = ncv * -inv_dist
            visible[l, j] = facing > 0.0 and ok and fov_px >= 0
            valid[l, j] = ok
            out_f[0, l, j] = Zv * inv_dist - cos_half
            out_f[1, l, j] = fov_px
            out_f[2, l, j] = (_nmin(Zv - near, far - Zv) if far_finite else Zv - near) / fscale
            rminor, rok = minor, ok
            if sphere:
                rr = sphere_ellipse_minor(Xv, Yv, Zv, q, Zv - rv > min_depth, cam, mode)
                rminor, rok = rr[0], rr[1]
            out_f[3, l, j] = rminor - min_axis if rok else -min_axis - penalty
            out_f[4, l, j] = rminor
            out_f[5, l, j] = facing
            out_f[6, l, j] = angle
            axes[l, j, 0] = major
            axes[l, j, 1] = minor
            centre[l, j, 0] = u
            centre[l, j, 1] = v
            iz = 1.0 / _nmax(Zv, min_depth)
            xv, yv = Xv * iz, Yv * iz
            _, _, e00, e01, e10, e11 = _distort(xv, yv, cam, mode)
            lens[0, l, j] = xv
            lens[1, l, j] = yv
            lens[2, l, j] = iz
            lens[3, l, j] = e00
            lens[4, l, j] = e01
            lens[5, l, j] = e10
            lens[6, l, j] = e11


def sphere_ellipse_minor(X: float, Y: float, Z: float, q: float, in_front: bool, cam: np.ndarray,
                         mode: int) -> tuple:
    """(minor axis, valid) of the sphere outline conic (``ellipse.sphere_conic_xyz``)."""
    e = _ellipse(X * X - q, X * Y, Y * Y - q, X * Z, Y * Z, Z * Z - q, in_front, cam, mode)
    return e[3], e[7]


_FEATURES: list = []


def features() -> Callable[..., None] | None:
    """The compiled per-feature kernel ``_features`` (None without numba)."""
    if not _FEATURES:
        try:
            import numba
        except ImportError:  # pragma: no cover - exercised only without numba
            _FEATURES.append(None)
        else:
            jit = numba.njit(cache=True, nogil=True, error_model="numpy")
            g = globals()
            for name in ("_nmin", "_nmax", "_distort", "_ellipse", "sphere_ellipse_minor"):
                g[name] = jit(g[name])
            _FEATURES.append(jit(_features))
    return _FEATURES[0]
