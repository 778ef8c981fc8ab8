"""Hole detection in grey images (OpenCV) and association of detections to the model's holes.

Why threshold + contours + ``cv2.fitEllipse`` (and not ``cv2.SimpleBlobDetector`` or Hough circles):
a hole's rim is a dark ellipse inside the bright part face; the quantity the filters need is that ellipse's
centre (``cadfeat.measures.rim_centre``). Contours of the thresholded image give the whole rim boundary,
and a least-squares ellipse fit through its points has a sub-pixel centre (errors average over the
boundary), plus axes and angle that let us reject what is not one whole hole. The blob detector reports
region centroids with no shape model and filters by circularity (rejecting the oblique holes we want);
Hough circles assume circles, not ellipses. The threshold is Otsu's (between the dark hole/background
and the lit part), which for symmetric blur sits near the mid-grey of an edge, where a blurred edge stays
unbiased.

Holes are the *inner* contours of the bright part region (``cv2.RETR_CCOMP``, second level): a dark blob
enclosed by the part. A candidate is kept only if it has enough boundary points, does not touch the image
border, and its boundary lies within ``max_residual_px`` of the fitted ellipse — two holes merged into
one region, a rim cut by an occluding edge or a noise speckle fail that test and are dropped, not
fitted.

A rim that is partly hidden by another part of the object, or crossed by another edge, can still give a dark
region that passes the ellipse test with a shifted centre (measured on the flagship: base holes half behind
the motor plate, up to 9 px). Such a candidate is rejected by the **surround test**: the grey levels on a
ring just outside the fitted ellipse (``ring_gap_px`` beyond the boundary) must be homogeneous — a whole rim
on one face is surrounded by that face only, so the spread (98th − 2nd percentile) of the ring must stay
below ``max_surround`` × the hole's contrast (ring median − interior median). A ring that crosses another
face, the part's silhouette or another hole fails. A cut by an edge of the *same* grey (a wall's top face
parallel to the hole's face) is invisible to it: the calibration (``tools/calibrate_detection.py``) measured
such rims accepted up to ~30 % hidden with offsets up to ~1 px — hence the association below.
The detector fits the rim's **sub-pixel edge** (``refine_edges``: each contour pixel moved along the grey-level
gradient to where the smoothed image crosses the threshold), not the thresholded region's boundary pixels,
whose pixel quantisation made runs with 2 grey levels of noise identical and left offsets of a few tenths of a
pixel; the dark region's edge is the rim where the bore's walls and bottom are dark (as the renderer paints
them); where something lit shows through the bore (a wide through hole over another
face) the region is a crescent, which the residual test rejects. The closed loop additionally drops a hole
whose rim the part hides according to the predicted pose (``closed_loop``: association with the predicted
occlusion), so a cut rim is never measured as if whole.

Association (``associate``): the model holes' predicted ellipses (from a predicted pose) are matched to
detections by ``scipy.optimize.linear_sum_assignment`` on the centre distance, with a gate per hole:
min(``gate_px``, half the distance to the nearest other predicted hole) (strict: a blob midway between
two holes belongs to neither), and detected axes within a factor
``size_ratio`` of the predicted ones. Anything outside the gate stays unmatched: a missed, merged or hidden
hole is NaN in that frame, never matched to another hole's detection.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import Camera
from cadfeat.measures.ellipse import Ellipse


@dataclass(frozen=True)
class Detections:
    """Ellipses found in one image: ``centre_px`` (M, 2), ``axes_px`` (M, 2) full (major, minor),
    ``angle_rad`` (M,), ``residual_px`` (M,) the largest boundary deviation from the fit."""

    centre_px: np.ndarray
    axes_px: np.ndarray
    angle_rad: np.ndarray
    residual_px: np.ndarray

    def __len__(self) -> int:
        return len(self.centre_px)


def _empty() -> Detections:
    return Detections(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0))


def _boundary_residual_px(pts: np.ndarray, centre: np.ndarray, axes: np.ndarray, angle_rad: float) -> float:
    """Largest |ρ − 1| · semi-minor of the boundary points (ρ the normalised elliptic radius), px."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    d = pts - centre
    x = d[:, 0] * c + d[:, 1] * s
    y = -d[:, 0] * s + d[:, 1] * c
    a, b = axes[0] / 2.0, axes[1] / 2.0
    rho = np.sqrt((x / a) ** 2 + (y / b) ** 2)
    return float(np.max(np.abs(rho - 1.0)) * min(a, b)) if len(rho) else np.inf


def _ring_levels(img: np.ndarray, centre: np.ndarray, axes: np.ndarray, angle_rad: float, grow_px: float,
                 samples: int = 72) -> np.ndarray:
    """Grey levels (bilinear) at ``samples`` points of the ellipse grown by ``grow_px`` on each semi-axis
    (negative = shrunk); points outside the image give NaN."""
    a, b = max(axes[0] / 2 + grow_px, 0.5), max(axes[1] / 2 + grow_px, 0.5)
    t = 2 * np.pi * np.arange(samples) / samples
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    x = centre[0] + a * np.cos(t) * c - b * np.sin(t) * s
    y = centre[1] + a * np.cos(t) * s + b * np.sin(t) * c
    h, w = img.shape
    ok = (x >= 0) & (y >= 0) & (x <= w - 1.001) & (y <= h - 1.001)
    x0, y0 = np.floor(np.where(ok, x, 0)).astype(int), np.floor(np.where(ok, y, 0)).astype(int)
    fx, fy = np.where(ok, x, 0) - x0, np.where(ok, y, 0) - y0
    im = img.astype(np.float64)
    v = (im[y0, x0] * (1 - fx) * (1 - fy) + im[y0, x0 + 1] * fx * (1 - fy) + im[y0 + 1, x0] * (1 - fx) * fy
         + im[y0 + 1, x0 + 1] * fx * fy)
    return np.where(ok, v, np.nan)


def surround_ok(img: np.ndarray, centre: np.ndarray, axes: np.ndarray, angle_rad: float, gap_px: float,
                max_surround: float) -> bool:
    """The surround test of the module docstring: the ring ``gap_px`` outside the ellipse is one face."""
    outer = _ring_levels(img, centre, axes, angle_rad, gap_px)
    inner = _ring_levels(img, centre, axes, angle_rad, -min(gap_px, 0.3 * axes[1]))
    if np.isnan(outer).any():
        return False
    contrast = float(np.median(outer) - np.nanmedian(inner))
    if not contrast > 0:
        return False
    lo, hi = np.percentile(outer, [2, 98])
    return bool(hi - lo <= max_surround * contrast)


def refine_edges(img: np.ndarray, pts: np.ndarray, level: float, reach_px: float = 2.0) -> np.ndarray:
    """Sub-pixel edge points (M, 2): each contour pixel moved along the local grey-level gradient to where the
    (smoothed, float) image crosses ``level`` (linear interpolation between samples 0.25 px apart within
    ±``reach_px``; the crossing nearest the pixel). Points without a crossing keep their pixel position."""
    gy, gx = np.gradient(img)
    ix, iy = pts[:, 0].astype(int), pts[:, 1].astype(int)
    g = np.stack([gx[iy, ix], gy[iy, ix]], axis=-1)
    norm = np.linalg.norm(g, axis=-1, keepdims=True)
    d = np.where(norm > 1e-9, g / np.where(norm > 1e-9, norm, 1.0), 0.0)
    t = np.arange(-reach_px, reach_px + 1e-9, 0.25)
    xy = pts[:, None, :] + t[None, :, None] * d[:, None, :]                          # (M, T, 2)
    h, w = img.shape
    x = np.clip(xy[..., 0], 0, w - 1.001)
    y = np.clip(xy[..., 1], 0, h - 1.001)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    prof = (img[y0, x0] * (1 - fx) * (1 - fy) + img[y0, x0 + 1] * fx * (1 - fy) + img[y0 + 1, x0] * (1 - fx) * fy
            + img[y0 + 1, x0 + 1] * fx * fy) - level                                  # (M, T)
    cross = (prof[:, :-1] <= 0) & (prof[:, 1:] > 0) | (prof[:, :-1] > 0) & (prof[:, 1:] <= 0)
    mid = 0.5 * (t[:-1] + t[1:])
    dist = np.where(cross, np.abs(mid)[None], np.inf)
    k = np.argmin(dist, axis=1)
    rows = np.arange(len(pts))
    a, b = prof[rows, k], prof[rows, k + 1]
    frac = np.where(np.abs(b - a) > 1e-12, a / np.where(np.abs(b - a) > 1e-12, a - b, 1.0), 0.5)
    step = t[k] + frac * (t[k + 1] - t[k])
    ok = np.isfinite(dist[rows, k])
    return np.where(ok[:, None], pts + step[:, None] * d, pts)


def detect_holes(image: np.ndarray, *, min_points: int = 10, max_residual_px: float = 1.5,
                 min_minor_px: float = 2.5, smooth_sigma_px: float = 0.8, ring_gap_px: float = 2.5,
                 max_surround: float = 0.15, subpixel: bool = True, camera: Camera | None = None,
                 origin_px: ArrayLike = (0.0, 0.0)) -> Detections:
    """Dark elliptic regions enclosed by the bright part in a grey uint8 image (H, W) (module docstring).

    ``smooth_sigma_px`` Gaussian pre-smoothing against pixel noise (0 = none); ``min_minor_px`` smallest
    minor axis kept; ``max_residual_px`` ellipse-fit acceptance; ``ring_gap_px`` / ``max_surround`` the
    surround test (partly hidden or crossed rims; ``max_surround`` = inf switches it off); ``subpixel``: fit
    the rim's sub-pixel edge (``refine_edges``) instead of the region's boundary pixels. ``camera`` with lens
    distortion: each centre is ``undistorted_centre`` of the rim's edge points (``origin_px``: the image's
    top-left pixel in the full frame, for a region of interest); axes, angle and the tests stay those of the
    fit in the distorted image.
    """
    import cv2

    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    img = img.astype(np.float32)
    if smooth_sigma_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), smooth_sigma_px)
    level, binary = cv2.threshold(np.clip(np.rint(img), 0, 255).astype(np.uint8), 0, 255,
                                  cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    level = float(level) + 0.5  # Otsu keeps grey levels > level: the edge lies between level and level + 1
    contours, hierarchy = cv2.findContours(binary, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if hierarchy is None:
        return _empty()
    h, w = img.shape[:2]
    rows = []
    for contour, link in zip(contours, hierarchy[0], strict=True):
        if link[3] < 0 or len(contour) < min_points:  # not an inner contour (no parent), or too short
            continue
        pts = contour[:, 0, :].astype(np.float64)
        if pts[:, 0].min() <= 0 or pts[:, 1].min() <= 0 or pts[:, 0].max() >= w - 1 or pts[:, 1].max() >= h - 1:
            continue
        if subpixel:
            pts = refine_edges(img, pts, level)
        (cx, cy), (d1, d2), angle_deg = cv2.fitEllipse(pts.astype(np.float32))
        if not (np.isfinite(cx) and np.isfinite(cy)) or min(d1, d2) < min_minor_px:
            continue
        # cv2 angle: of the first axis (width d1) from +u towards +v; make the major axis first
        angle = np.radians(angle_deg) if d1 >= d2 else np.radians(angle_deg + 90.0)
        axes = np.array([max(d1, d2), min(d1, d2)])
        residual = _boundary_residual_px(pts, np.array([cx, cy]), axes, angle)
        if residual > max_residual_px:
            continue
        if np.isfinite(max_surround) and not surround_ok(img, np.array([cx, cy]), axes, angle, ring_gap_px,
                                                         max_surround):
            continue
        angle = (angle + np.pi / 2) % np.pi - np.pi / 2
        if camera is not None and camera.has_distortion:
            cx, cy = undistorted_centre(camera, pts + np.asarray(origin_px, float)) - np.asarray(origin_px, float)
        rows.append((cx, cy, axes[0], axes[1], angle, residual))
    if not rows:
        return _empty()
    a = np.array(rows)
    return Detections(a[:, :2], a[:, 2:4], a[:, 4], a[:, 5])


def undistorted_centre(camera: Camera, edge_px: np.ndarray) -> np.ndarray:
    """The rim-ellipse centre (px, distorted image) of a rim's edge points ``edge_px`` (K, 2) seen through a
    distorting lens: the points are undistorted (``cv2.undistortPoints``, then Newton steps on
    ``Camera.distort_normalized`` with its ``distortion_jacobian`` to 1e-9 px), the ellipse is fitted in the
    pinhole image — where a circle's image *is* an ellipse — and its centre x₀ is distorted back. This is the
    quantity ``measures.rim_centre`` predicts (distort(x₀)); an ellipse fitted to the distorted rim directly is
    off by a second-order term, ≈ 2 k₁ ρ² x in normalised coordinates for a rim of normalised radius ρ at x
    (0.1–0.3 px for the thesis's k₁ = −1.45 lens and 8 px rims, up to 2 px near its corners:
    ``measures.ellipse``)."""
    import cv2

    target = np.asarray(edge_px, np.float64).reshape(-1, 2)
    xy = cv2.undistortPoints(target.reshape(-1, 1, 2), camera.K, camera.dist_coeffs).reshape(-1, 2)
    for _ in range(20):
        r = target - camera.distort_normalized(xy)
        if np.max(np.abs(r)) < 1e-9:
            break
        xy = xy + np.linalg.solve(camera.distortion_jacobian(xy), r[..., None])[..., 0]
    f = np.array([camera.fx, camera.fy])
    (cu, cv_), _, _ = cv2.fitEllipse((xy * f).astype(np.float32))     # pinhole pixels about the principal point
    return camera.distort_normalized(np.array([cu, cv_]) / f)


def associate(predicted: Ellipse, detections: Detections, gate_px: float = 8.0,
              size_ratio: float = 1.6) -> np.ndarray:
    """Measured pixels (N, 2) of the N model holes (NaN where none is matched) (module docstring).

    ``predicted``: the holes' predicted ellipses (``hole_ellipse`` at a predicted pose), N entries; invalid
    ones (rim not in front of the camera) are never matched.
    """
    from scipy.optimize import linear_sum_assignment

    pc = np.asarray(predicted.centre_px, dtype=float).reshape(-1, 2)
    N = len(pc)
    out = np.full((N, 2), np.nan)
    if N == 0 or len(detections) == 0:
        return out
    valid = np.asarray(predicted.valid, dtype=bool).reshape(N) & np.all(np.isfinite(pc), axis=1)
    gap = np.linalg.norm(pc[:, None] - pc[None], axis=-1)
    gap[np.eye(N, dtype=bool) | ~valid[None, :]] = np.inf
    gate = np.minimum(gate_px, 0.5 * gap.min(axis=1))                                     # (N,)
    dist = np.linalg.norm(pc[:, None] - detections.centre_px[None], axis=-1)            # (N, M)
    pa = np.asarray(predicted.axes_px, dtype=float).reshape(N, 2)
    ratio = detections.axes_px[None, :, 1] / np.maximum(pa[:, None, 1], 1e-9)
    ok = valid[:, None] & (dist < gate[:, None]) & (ratio < size_ratio) & (ratio > 1.0 / size_ratio)
    big = 1e9
    cost = np.where(ok, dist, big)
    rows, cols = linear_sum_assignment(cost)
    keep = ok[rows, cols]
    out[rows[keep]] = detections.centre_px[cols[keep]]
    return out
