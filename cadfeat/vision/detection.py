"""Hole detection in grey images (OpenCV) and association of detections to the model's holes.

Why threshold + contours + ``cv2.fitEllipse`` (and not ``cv2.SimpleBlobDetector`` or Hough circles):
a hole's rim is a dark ellipse inside the bright part face; the quantity the filters need is that ellipse's
centre (``cadfeat.vision.measurement``). Contours of the thresholded image give the whole rim boundary,
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


def detect_holes(image: np.ndarray, *, min_points: int = 10, max_residual_px: float = 1.5,
                 min_minor_px: float = 2.5, smooth_sigma_px: float = 0.8) -> Detections:
    """Dark elliptic regions enclosed by the bright part in a grey uint8 image (H, W) (module docstring).

    ``smooth_sigma_px`` Gaussian pre-smoothing against pixel noise (0 = none); ``min_minor_px`` smallest
    minor axis kept; ``max_residual_px`` ellipse-fit acceptance.
    """
    import cv2

    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    if smooth_sigma_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), smooth_sigma_px)
    _, binary = cv2.threshold(img, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
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
        (cx, cy), (d1, d2), angle_deg = cv2.fitEllipse(pts.astype(np.float32))
        if not (np.isfinite(cx) and np.isfinite(cy)) or min(d1, d2) < min_minor_px:
            continue
        # cv2 angle: of the first axis (width d1) from +u towards +v; make the major axis first
        angle = np.radians(angle_deg) if d1 >= d2 else np.radians(angle_deg + 90.0)
        axes = np.array([max(d1, d2), min(d1, d2)])
        residual = _boundary_residual_px(pts, np.array([cx, cy]), axes, angle)
        if residual > max_residual_px:
            continue
        angle = (angle + np.pi / 2) % np.pi - np.pi / 2
        rows.append((cx, cy, axes[0], axes[1], angle, residual))
    if not rows:
        return _empty()
    a = np.array(rows)
    return Detections(a[:, :2], a[:, 2:4], a[:, 4], a[:, 5])


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
