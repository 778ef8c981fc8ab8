"""cadfeat's rim detector for physically lit images: the rim's outermost step edge along rays of a prior ellipse.

Why not a dark region (``detection.detect_holes``): under a ring light near the lens a bore's far wall is lit
mid-grey, a flat blind-hole floor in machined metal mirrors the light (a bright bore), a chamfer gives two
edges (the bore's and the chamfer's outer one) and grey plastic gives little contrast. What stays true in all
of these is that the part's **face** — flat, one material, uniformly lit — ends at the rim: going from the
face towards the hole's centre, the rim is the *first* strong step away from the face's grey level, whatever
lies inside (a lit wall, a chamfer band, a dark or a mirror-bright floor). The rim of a chamfered hole is the
chamfer's outer edge, where the face ends; that is the edge found here.

Method (``detect_rims``), per hole with a prior ellipse (the closed loop's predicted rim ellipse):

1. ``rays`` rays along the normals of the prior ellipse, sampled every ``STEP_PX`` from ``inner`` (at most
   ``INNER_FRACTION`` of the prior's semi-minor axis inwards, never across the centre) to ``reach_px`` outwards,
   bilinearly in the image smoothed by a Gaussian of ``smooth_sigma_px``; all holes and rays in one array.
2. The profile's derivative along the ray (grey levels per px, outwards positive). Edge candidates are its
   local maxima of |derivative| above a threshold: ``min_gradient`` grey/px, ``noise_factor`` × the robust
   spread of the image's derivative (``gradient_noise``: mostly flat face), and ``rel_gradient`` × the median
   over the hole's rays of their strongest edge. A candidate must have the **face** outside it: the level
   ``FACE_OFFSET_PX`` outside within ``face_tolerance`` × its step (+ 2 × noise) of the face's grey (the
   median of all samples ≥ ``FACE_OFFSET_PX`` outside the prior rim) — an edge between the face and a
   neighbouring face, shadow or silhouette within the reach is not the rim. On each ray the **outermost**
   remaining candidate is the rim point,
   refined to sub-pixel by a parabola through the |derivative| samples around its peak (the gradient maximum
   of a blurred step).
3. A robust ellipse fit: the first inliers are the points within ``SEED_INLIER_PX`` of the prior's shape moved
   and scaled by an M-estimate (Cauchy loss, ``_m_estimate``); then ``cv2.fitEllipse`` on them and
   ``FIT_ROUNDS`` rounds keeping the points (all of them, re-admitted or not) within
   max(``MAD_FACTOR`` × MAD, ``min_inlier_px``) of the fit, measured as |ρ − 1| × semi-minor with ρ the
   normalised elliptic radius), accepted when the inliers cover ≥ ``min_coverage`` of the rays, their largest
   deviation is ≤ ``max_residual_px``, the fitted axes are within ``size_ratio`` of the prior's and its centre
   moved less than ``reach_px``.
4. The fit is repeated once on rays of the first fit with the short reach ``refine_reach_px`` (rays normal to
   the true rim; neighbouring edges outside the reach are no longer seen); its seed keeps the prior's shape.
   It reads the image smoothed by only ``fine_sigma_px``: a shallow blind hole in machined metal seen
   obliquely shows its far wall as a dark crescent about a pixel wide between the face and the mirror floor,
   and smoothed by ``smooth_sigma_px`` the face-to-wall step merges into the stronger wall-to-floor one, so the
   fit is pulled inwards on that arc (0.38 px on ``tests/vision/test_detectors.py``'s ``mirror_thin``, 0.17 px
   at 0.5). Where the sharper fit is not accepted (too few edges: a wall lit to nearly the face's grey, a step
   the coarse smoothing lifts out of the noise; or a fit that fails step 3's and 5's tests, as the low-contrast
   rims under a dome light), the refinement reads the coarse image, as the first fit (on the flagship's frames
   under a dome: 31 of the rims found without that fallback, 70 with it, 66 single-scale). On the
   raster renderer's point-sampled images, whose edges no lens or pixel area has blurred, the closed loop and
   its calibration keep the coarse image (``detectors.POINT_SAMPLED``).
5. The **surround test** (as ``detection``'s, sign-free): the grey levels on the ellipse grown by
   ``ring_gap_px`` (the face just outside the rim) must be one homogeneous face — the spread (98th − 2nd
   percentile) of the levels minus their first harmonic (the light's smooth fall-off across the hole,
   ``surround_spread``) at most max(``max_surround`` × the rim's contrast (median over inlier rays of
   |face − inside| just across the edge), ``surround_noise`` × the ring's pixel noise (``ring_noise``)). A
   rim crossed by another edge, the silhouette, a shadow or another hole fails.
6. With a distorting ``camera`` the centre is ``detection.undistorted_centre`` of the inlier edge points (the
   quantity ``measures.rim_centre`` predicts); axes and angle stay those of the fit in the distorted image.

Coordinates: ``image`` may be a region of interest whose top-left pixel is ``origin_px`` in the full frame; the
prior is in full-frame pixels, the returned ``Detections`` in the image's own pixels (as ``detect_holes``:
the caller adds ``origin_px``). Pixel centres are at integer coordinates. Without a prior (``predicted=None``)
the detector is ``detection.detect_holes``.

Measured on the flagship (studies/nema17_mount.toml, 40 frames of its orbit, 218 expected rims, prior = the
rim ellipses at the true pose; centre errors against them): raster frames (closed loop's renderer, 2 grey
levels of noise) 218/218 found, RMS 0.068 px (threshold detector 218/218, 0.071 px). Mitsuba frames (branch
``pbr`` 4526401: ring light, 16 spp, auto exposure, shot + read noise, 8 bit), found / RMS px:

=================================== ============= ============= ============ =========
material (target chamfer)           cadfeat       EDCircles     blob         threshold
=================================== ============= ============= ============ =========
machined aluminium                  197 / 0.23    92 / 0.48     44 / 0.19    0
machined aluminium (0.5 mm chamfer) 196 / 0.18    96 / 0.44     40 / 0.35    0
grey plastic                        206 / 0.11    182 / 0.47    57 / 0.11    0
grey plastic (0.5 mm chamfer)       208 / 0.09    179 / 0.87    57 / 0.11    0
=================================== ============= ============= ============ =========

With the prior shifted by (2, −1.5) or (−3, 2) px: aluminium 199 / 0.24 and 206 / 0.22, plastic 206 / 0.11
both. The largest errors were the blind targets' mirror floors on aluminium (RMS 0.36 px): their far wall, a
dark crescent about a pixel wide, merged into the wall/floor edge in the smoothed image and pulled the fit
inwards. That table is of the single-scale detector (every step at ``smooth_sigma_px`` 0.8); with step 4 at
``fine_sigma_px`` 0.5, on 20 frames of the flagship's original (fast check poses, 16 spp, nominal placement)
aluminium 100 → 108 of the rims found, RMS per hole 0.14–0.30 → 0.11–0.21 px (the shallow target 0.30 →
0.21), plastic 124 → 124, 0.06–0.15 → 0.04–0.13 px; in the flagship's 16-run physical check (docs/results.md)
aluminium 93 → 96 % of the expected rims, the shallow target 0.38 → 0.28 px RMS.

Limits (measured, tests/vision/test_detectors.py): a prior off by more than ``reach_px`` or whose axes are off
by more than ``size_ratio`` finds nothing (never another hole); a wall lit to exactly the face's grey hides
the rim on those rays (accepted while ≥ ``min_coverage`` of the rim still shows an edge).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import Camera
from cadfeat.measures.ellipse import Ellipse
from cadfeat.vision.detection import Detections, _empty, _ring_levels, detect_holes, undistorted_centre

#: Sample spacing along a ray, px.
STEP_PX = 0.25
#: A ray reaches at most this fraction of the prior's semi-minor axis inwards.
INNER_FRACTION = 0.7
#: Rounds of the iterated fit with outlier rejection.
FIT_ROUNDS = 4
#: The face's and the inside's grey levels are read this far outside / inside an edge candidate, px.
FACE_OFFSET_PX = 1.5
#: Scale (px) of the Cauchy loss of the robust seed fit, and the seed's inlier distance (px).
CAUCHY_SCALE_PX = 0.25
SEED_INLIER_PX = 0.75
#: Outlier threshold in units of the residuals' median absolute deviation.
MAD_FACTOR = 3.5


@dataclass(frozen=True)
class RimSettings:
    """Parameters of ``detect_rims`` (module docstring): lengths in px, gradients in grey levels per px;
    ``smooth_sigma_px`` the Gaussian of steps 1–3, ``fine_sigma_px`` that of the refinement (step 4)."""

    rays: int = 96
    reach_px: float = 6.0
    refine_reach_px: float = 2.5
    smooth_sigma_px: float = 0.8
    fine_sigma_px: float = 0.5
    min_gradient: float = 3.0
    noise_factor: float = 6.0
    rel_gradient: float = 0.2
    face_tolerance: float = 0.3
    min_coverage: float = 0.65
    min_inlier_px: float = 0.35
    max_residual_px: float = 1.0
    size_ratio: float = 1.4
    min_minor_px: float = 4.0
    ring_gap_px: float = 2.0
    max_surround: float = 0.35
    surround_noise: float = 6.0


@dataclass(frozen=True)
class _Rays:
    """Rays of K holes: ``origin`` (K, R, 2) points on the prior ellipses, ``normal`` (K, R, 2) unit outward
    normals, ``s`` (S,) signed distances along them (px), ``inner`` (K,) the innermost distance allowed."""

    origin: np.ndarray
    normal: np.ndarray
    s: np.ndarray
    inner: np.ndarray


def _rays(centre: np.ndarray, axes: np.ndarray, angle: np.ndarray, n_rays: int, reach_px: float) -> _Rays:
    """Rays along the outward normals of ellipses ``centre`` (K, 2), full ``axes`` (K, 2), ``angle`` (K,) rad."""
    t = 2 * np.pi * (np.arange(n_rays) + 0.5) / n_rays
    a, b = axes[:, 0:1] / 2, axes[:, 1:2] / 2                                    # (K, 1)
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    x, y = a * np.cos(t), b * np.sin(t)                                           # (K, R) ellipse frame
    nx, ny = b * np.cos(t), a * np.sin(t)                                         # gradient of the implicit form
    norm = np.hypot(nx, ny)
    origin = np.stack([centre[:, 0:1] + x * c - y * s, centre[:, 1:2] + x * s + y * c], axis=-1)
    normal = np.stack([(nx * c - ny * s) / norm, (nx * s + ny * c) / norm], axis=-1)
    inner = np.minimum(INNER_FRACTION * b[:, 0], reach_px)
    return _Rays(origin, normal, np.arange(-reach_px, reach_px + 1e-9, STEP_PX), inner)


def _bilinear(img: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Grey levels of the float image (H, W) at points ``xy`` (..., 2) px; NaN outside the image."""
    h, w = img.shape
    x, y = xy[..., 0], xy[..., 1]
    ok = (x >= 0) & (y >= 0) & (x <= w - 1.001) & (y <= h - 1.001)
    x, y = np.where(ok, x, 0.0), np.where(ok, y, 0.0)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    v = (img[y0, x0] * (1 - fx) * (1 - fy) + img[y0, x0 + 1] * fx * (1 - fy) + img[y0 + 1, x0] * (1 - fx) * fy
         + img[y0 + 1, x0 + 1] * fx * fy)
    return np.where(ok, v, np.nan)


@dataclass(frozen=True)
class _Edges:
    """Outermost edge per ray: ``point`` (K, R, 2) px (NaN where none), ``step`` (K, R) |grey step| across it."""

    point: np.ndarray
    step: np.ndarray


def gradient_noise(img: np.ndarray) -> float:
    """Robust standard deviation (grey/px) of the image's horizontal and vertical central differences: the
    derivative noise on the flat faces that fill most of a part's image (MAD / 0.6745 of zero-mean noise)."""
    gy, gx = np.gradient(img)
    return float(np.median(np.abs(np.concatenate([gx.ravel(), gy.ravel()]))) / 0.6745)


def _outermost_edges(img: np.ndarray, rays: _Rays, noise: float, cfg: RimSettings) -> _Edges:
    """Step 2 of the module docstring, batched over holes, rays and samples; ``noise`` from ``gradient_noise``."""
    xy = rays.origin[:, :, None, :] + rays.s[None, None, :, None] * rays.normal[:, :, None, :]   # (K, R, S, 2)
    prof = _bilinear(img, xy)
    g = np.abs(np.gradient(prof, STEP_PX, axis=-1))
    g = np.where(np.isfinite(g) & (rays.s[None, None, :] >= -rays.inner[:, None, None]), g, 0.0)
    strongest = np.median(g.max(axis=-1), axis=-1)                                         # (K,)
    level = np.maximum(max(cfg.min_gradient, cfg.noise_factor * noise), cfg.rel_gradient * strongest)
    peak = np.zeros_like(g, dtype=bool)
    peak[..., 1:-1] = (g[..., 1:-1] >= g[..., :-2]) & (g[..., 1:-1] > g[..., 2:])
    peak &= g >= level[:, None, None]
    S = len(rays.s)
    off = int(round(FACE_OFFSET_PX / STEP_PX))
    out_v = np.concatenate([prof[..., off:], np.repeat(prof[..., -1:], off, axis=-1)], axis=-1)   # at s + offset
    in_v = np.concatenate([np.repeat(prof[..., :1], off, axis=-1), prof[..., :-off]], axis=-1)    # at s − offset
    outside = rays.s[None, None, :] >= FACE_OFFSET_PX
    face = np.nanmedian(np.where(outside, prof, np.nan).reshape(len(prof), -1), axis=-1)         # (K,)
    peak &= np.abs(out_v - face[:, None, None]) <= cfg.face_tolerance * np.abs(out_v - in_v) + 2 * noise
    last = S - 1 - np.argmax(peak[..., ::-1], axis=-1)                                     # outermost peak
    found = peak.any(axis=-1) & (last > 0) & (last < S - 1)
    k = np.clip(last, 1, S - 2)
    gm, g0, gp = (np.take_along_axis(g, (k + d)[..., None], axis=-1)[..., 0] for d in (-1, 0, 1))
    den = gm - 2 * g0 + gp
    frac = np.where(den < 0, 0.5 * (gm - gp) / np.where(den < 0, den, -1.0), 0.0)
    dist = rays.s[k] + np.clip(frac, -0.5, 0.5) * STEP_PX
    point = rays.origin + dist[..., None] * rays.normal
    step = np.abs(np.take_along_axis(out_v - in_v, k[..., None], axis=-1)[..., 0])
    return _Edges(np.where(found[..., None], point, np.nan), np.where(found, step, np.nan))


def _fit(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """cv2.fitEllipse of points (M, 2) → centre (2,), full axes (major, minor), angle rad of the major axis."""
    import cv2

    (cx, cy), (d1, d2), deg = cv2.fitEllipse(pts.astype(np.float32))
    angle = np.radians(deg) if d1 >= d2 else np.radians(deg + 90.0)
    return np.array([cx, cy]), np.array([max(d1, d2), min(d1, d2)]), float((angle + np.pi / 2) % np.pi - np.pi / 2)


def _deviation_px(pts: np.ndarray, centre: np.ndarray, axes: np.ndarray, angle: float) -> np.ndarray:
    """|ρ − 1| × semi-minor of points (M, 2) for an ellipse (ρ the normalised elliptic radius), px."""
    c, s = np.cos(angle), np.sin(angle)
    d = pts - centre
    x, y = d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c
    rho = np.hypot(x / (axes[0] / 2), y / (axes[1] / 2))
    return np.abs(rho - 1.0) * axes[1] / 2


def _m_estimate(pts: np.ndarray, centre: np.ndarray, axes: np.ndarray, angle: float) -> np.ndarray:
    """Deviations (M,) px of points (M, 2) from the prior's ellipse (full ``axes``, ``angle``) moved to the
    centre and scaled by the factor that fit them robustly: ``scipy.optimize.least_squares`` on
    (ρ − scale) × semi-minor with a Cauchy loss of scale ``CAUCHY_SCALE_PX``. The shape stays the prior's (3
    parameters, not 5), so a contiguous arc of wrong edges (a lit wall's inner boundary, a thin far wall of the
    face's grey) cannot be absorbed by the shape and weighs little."""
    from scipy.optimize import least_squares

    c, s = np.cos(angle), np.sin(angle)
    a, b = axes[0] / 2, axes[1] / 2

    def resid(q: np.ndarray) -> np.ndarray:
        d = pts - q[:2]
        x, y = d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c
        return (np.hypot(x / a, y / b) - q[2]) * b

    q = least_squares(resid, np.array([centre[0], centre[1], 1.0]), loss="cauchy", f_scale=CAUCHY_SCALE_PX,
                      max_nfev=50).x
    return np.abs(resid(q))


def robust_ellipse(pts: np.ndarray, min_inlier_px: float, start: tuple[np.ndarray, np.ndarray, float] | None = None
                   ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Iterated ``cv2.fitEllipse`` with outlier rejection (module docstring, step 3) of points (M, 2) px:
    centre (2,), full axes (2,) major first, angle rad in [−π/2, π/2), inlier mask (M,). ``start`` (centre,
    full axes, angle): the first inliers are the points within ``SEED_INLIER_PX`` of a robust (Cauchy) fit
    from there (``_m_estimate``); None: all points."""
    inl = np.ones(len(pts), dtype=bool)
    if start is not None:
        seed = _m_estimate(pts, *start) <= SEED_INLIER_PX
        inl = seed if seed.sum() >= 6 else inl
    centre, axes, angle = _fit(pts[inl])
    for _ in range(FIT_ROUNDS):
        dev = _deviation_px(pts, centre, axes, angle)
        mad = 1.4826 * np.median(np.abs(dev[inl] - np.median(dev[inl])))
        new = dev <= max(MAD_FACTOR * mad + np.median(dev[inl]), min_inlier_px)
        if new.sum() < 6 or np.array_equal(new, inl):
            break
        inl = new
        centre, axes, angle = _fit(pts[inl])
    return centre, axes, angle, inl


@dataclass(frozen=True)
class _Rim:
    """One hole's fitted rim: centre (2,), axes (2,), angle rad, inlier edge points (M, 2), coverage, residual
    px, contrast (grey)."""

    centre: np.ndarray
    axes: np.ndarray
    angle: float
    points: np.ndarray
    coverage: float
    residual_px: float
    contrast: float


def _fit_rims(img: np.ndarray, noise: float, centre: np.ndarray, axes: np.ndarray, angle: np.ndarray,
              reach_px: float, cfg: RimSettings, shape: tuple[np.ndarray, np.ndarray] | None = None
              ) -> list[_Rim | None]:
    """Steps 1–3 for K ellipses (rays around them); ``shape`` (full axes (K, 2), angles (K,)): the shape the
    robust seed fit keeps (None: these ellipses'); None where a hole has too few edge points."""
    seed_axes, seed_angle = (axes, angle) if shape is None else shape
    rays = _rays(centre, axes, angle, cfg.rays, reach_px)
    edges = _outermost_edges(img, rays, noise, cfg)
    out: list[_Rim | None] = []
    for j in range(len(centre)):
        ok = np.isfinite(edges.point[j, :, 0])
        if ok.sum() < max(6, cfg.min_coverage * cfg.rays):
            out.append(None)
            continue
        pts = edges.point[j, ok]
        c, ax, ang, inl = robust_ellipse(pts, cfg.min_inlier_px, (centre[j], seed_axes[j], float(seed_angle[j])))
        res = float(_deviation_px(pts[inl], c, ax, ang).max())
        out.append(_Rim(c, ax, ang, pts[inl], inl.sum() / cfg.rays, res,
                        float(np.median(edges.step[j, ok][inl]))))
    return out


def _accepted(rim: _Rim | None, prior_centre: np.ndarray, prior_axes: np.ndarray, img: np.ndarray,
              cfg: RimSettings) -> bool:
    """Step 3's acceptance and step 5's surround test."""
    if rim is None or not np.all(np.isfinite(rim.centre)) or rim.axes[1] < cfg.min_minor_px:
        return False
    ratio = rim.axes / prior_axes
    if not (rim.coverage >= cfg.min_coverage and rim.residual_px <= cfg.max_residual_px
            and np.all(ratio < cfg.size_ratio) and np.all(ratio > 1 / cfg.size_ratio)
            and np.linalg.norm(rim.centre - prior_centre) < cfg.reach_px):
        return False
    ring = _ring_levels(img, rim.centre, rim.axes, rim.angle, cfg.ring_gap_px)
    if np.isnan(ring).any() or not rim.contrast > 0:
        return False
    return surround_spread(ring) <= max(cfg.max_surround * rim.contrast, cfg.surround_noise * ring_noise(ring))


def _detrended(ring: np.ndarray) -> np.ndarray:
    """Ring grey levels (T,) (equal steps of the ellipse parameter) minus their least-squares a + b cos t +
    c sin t: the face's smooth illumination gradient across the hole removed."""
    t = 2 * np.pi * np.arange(len(ring)) / len(ring)
    A = np.stack([np.ones_like(t), np.cos(t), np.sin(t)], axis=-1)
    return ring - A @ np.linalg.lstsq(A, ring, rcond=None)[0]


def surround_spread(ring: np.ndarray) -> float:
    """98th − 2nd percentile (grey) of the detrended ring levels: an edge crossing the ring shows as a step."""
    lo, hi = np.percentile(_detrended(ring), [2, 98])
    return float(hi - lo)


def ring_noise(ring: np.ndarray) -> float:
    """Robust σ (grey) of the ring's pixel noise from successive differences (MAD / 0.6745 / √2): one step
    where an edge crosses the ring does not move it."""
    d = np.diff(ring)
    return float(np.median(np.abs(d - np.median(d))) / 0.6745 / np.sqrt(2.0))


def _prior(predicted: Ellipse, origin_px: np.ndarray, cfg: RimSettings) -> tuple[np.ndarray, ...]:
    """Indices, centres (image px), axes and angles of the usable prior ellipses."""
    c = np.asarray(predicted.centre_px, float).reshape(-1, 2) - origin_px
    ax = np.asarray(predicted.axes_px, float).reshape(-1, 2)
    ang = np.asarray(predicted.angle_rad, float).reshape(-1)
    ok = (np.asarray(predicted.valid, bool).reshape(-1) & np.all(np.isfinite(c), axis=1)
          & np.all(np.isfinite(ax), axis=1) & (ax[:, 1] >= cfg.min_minor_px))
    idx = np.flatnonzero(ok)
    return idx, c[idx], ax[idx], ang[idx]


def _grey(image: np.ndarray, sigma_px: float) -> np.ndarray:
    """The image as float32 grey, Gaussian-smoothed by ``sigma_px`` (0 = not)."""
    import cv2

    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    img = img.astype(np.float32)
    return cv2.GaussianBlur(img, (0, 0), sigma_px) if sigma_px > 0 else img


def _refined(image: np.ndarray, img: np.ndarray, noise: float, start: tuple[np.ndarray, np.ndarray, np.ndarray],
             shape: tuple[np.ndarray, np.ndarray], cfg: RimSettings,
             accept: Callable[[int, _Rim | None], bool]) -> list[_Rim | None]:
    """Step 4: the fit repeated on rays of the first fits ``start`` (centres, axes, angles) with the short reach,
    in the image smoothed by ``fine_sigma_px`` (a thin dark wall between the face and a mirror floor stays
    resolved); a hole whose sharper fit is not accepted (``accept(i, rim)``: too few edges — a rim lit to nearly
    the face's grey, a step the coarse smoothing lifts out of the noise — or a fit that fails the acceptance
    tests, as low-contrast rims under a dome) is refitted in ``img`` smoothed by ``smooth_sigma_px`` (``noise``
    its gradient noise), as the first fit. Returns the accepted rims, None where neither fit is (each rim's
    acceptance tested once)."""
    rims: list[_Rim | None] = [None] * len(start[0])
    if cfg.fine_sigma_px != cfg.smooth_sigma_px:
        sharp = _grey(image, cfg.fine_sigma_px)
        fits = _fit_rims(sharp, gradient_noise(sharp), *start, cfg.refine_reach_px, cfg, shape=shape)
        rims = [rim if accept(i, rim) else None for i, rim in enumerate(fits)]
    redo = [i for i, rim in enumerate(rims) if rim is None]
    if redo:
        again = _fit_rims(img, noise, *(a[redo] for a in start), cfg.refine_reach_px, cfg,
                          shape=(shape[0][redo], shape[1][redo]))
        for i, rim in zip(redo, again, strict=True):
            rims[i] = rim if accept(i, rim) else None
    return rims


def detect_rims(image: np.ndarray, predicted: Ellipse | None, *, camera: Camera | None = None,
                origin_px: ArrayLike = (0.0, 0.0), settings: RimSettings | None = None) -> Detections:
    """Rims found as the outermost step edge around each prior ellipse (module docstring) in a grey (H, W)
    image; one detection per prior hole whose rim is accepted, in the image's own pixels. ``predicted``: the
    holes' prior ellipses in full-frame px (None: ``detection.detect_holes``); ``residual_px`` is the largest
    inlier deviation from the fit."""
    if predicted is None:
        return detect_holes(image, camera=camera, origin_px=origin_px)
    cfg = settings or RimSettings()
    origin = np.asarray(origin_px, float)
    img = _grey(image, cfg.smooth_sigma_px)
    _, c, ax, ang = _prior(predicted, origin, cfg)
    if len(c) == 0:
        return _empty()
    noise = gradient_noise(img)
    first = _fit_rims(img, noise, c, ax, ang, cfg.reach_px, cfg)
    keep = [j for j, rim in enumerate(first) if rim is not None and np.all(np.isfinite(rim.centre))
            and rim.axes[1] >= cfg.min_minor_px]
    if not keep:
        return _empty()
    coarse = [r for r in (first[j] for j in keep) if r is not None]
    start = (np.array([r.centre for r in coarse]), np.array([r.axes for r in coarse]),
             np.array([r.angle for r in coarse]))

    def accept(i: int, rim: _Rim | None) -> bool:
        return rim is not None and _accepted(rim, c[keep[i]], ax[keep[i]], img, cfg)

    fine = _refined(image, img, noise, start, (ax[keep], ang[keep]), cfg, accept)
    rows = []
    for rim in fine:
        if rim is None:
            continue
        centre = rim.centre
        if camera is not None and camera.has_distortion:
            centre = undistorted_centre(camera, rim.points + origin) - origin
        rows.append((*centre, *rim.axes, rim.angle, rim.residual_px))
    if not rows:
        return _empty()
    a = np.array(rows)
    return Detections(a[:, :2], a[:, 2:4], a[:, 4], a[:, 5])
