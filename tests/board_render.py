"""An exact renderer of a planar board seen by an OpenCV camera with lens distortion (test reference).

Independent of cadfeat's projection: every sub-pixel of the sensor is traced back to its ray by Newton's method on
OpenCV's distortion model written out here (checked forward with ``cv2.projectPoints`` to 1e-4 px), the ray is cut
with the board plane of the view's pose, and the board's printed image is looked up at the hit (its square edges
fall on texel edges, so the lookup is exact); ``SUB`` x ``SUB`` sub-pixels per pixel are averaged (area
anti-aliasing). Why not Mitsuba: its perspective sensor is a pinhole, so OpenCV's distortion would need this same
per-pixel ray map anyway, and texturing a board there adds nothing to what the test checks. The ray map depends only
on the camera, so it is built once per camera.
"""

from __future__ import annotations

import numpy as np

SUB = 3  # sub-pixels per pixel side
BLACK, WHITE, PAPER, BACKGROUND = 35.0, 215.0, 215.0, 95.0
#: σ of the Gaussian point spread, px: a real lens's; it also helps the corner refinement (0.070 px RMS vs 0.088 sharp).
BLUR_PX = 0.8
#: Where the views put the board's centre, as fractions of the image (corners first: the distortion is largest there).
ANCHORS = ((0.12, 0.12), (0.88, 0.12), (0.12, 0.88), (0.88, 0.88), (0.5, 0.12), (0.5, 0.88), (0.12, 0.5),
           (0.88, 0.5), (0.5, 0.5))


def distort(K: np.ndarray, dist: np.ndarray, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's model (k1, k2, p1, p2, k3) written out: pixels (..., 2) of normalised rays xy (..., 2) and the
    Jacobian (..., 2, 2) d(pixel)/d(xy)."""
    k1, k2, p1, p2, k3 = np.asarray(dist, float).ravel()[:5]
    x, y = xy[..., 0], xy[..., 1]
    r2 = x * x + y * y
    rad = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    drad = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d rad / d r2
    xd = x * rad + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * rad + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    jac = np.empty(xy.shape + (2,))
    jac[..., 0, 0] = K[0, 0] * (rad + 2 * x * x * drad + 2 * p1 * y + 6 * p2 * x)
    jac[..., 0, 1] = K[0, 0] * (2 * x * y * drad + 2 * p1 * x + 2 * p2 * y)
    jac[..., 1, 0] = K[1, 1] * (2 * x * y * drad + 2 * p1 * x + 2 * p2 * y)
    jac[..., 1, 1] = K[1, 1] * (rad + 2 * y * y * drad + 6 * p1 * y + 2 * p2 * x)
    return np.stack([K[0, 0] * xd + K[0, 2], K[1, 1] * yd + K[1, 2]], axis=-1), jac


def ray_map(K: np.ndarray, dist: np.ndarray, size: tuple[int, int], seed: int = 0) -> np.ndarray:
    """(H·SUB, W·SUB, 2) the normalised undistorted ray (x, y) of one point in each sub-pixel (stratified: a random
    point per sub-pixel, so edges' sub-pixel quantisation is noise rather than a bias; pixel centres at integers):
    Newton's method on ``distort`` from the pinhole guess, checked against ``cv2.projectPoints`` to 1e-4 px."""
    import cv2

    w, h = size
    off = (np.arange(SUB) + 0.5) / SUB - 0.5
    u = (np.arange(w)[:, None] + off).ravel()
    v = (np.arange(h)[:, None] + off).ravel()
    px = np.stack(np.meshgrid(u, v), axis=-1)
    px += np.random.default_rng(seed).uniform(-0.5 / SUB, 0.5 / SUB, px.shape)  # stratified: no grid bias
    xy = (px - K[:2, 2]) / [K[0, 0], K[1, 1]]
    for _ in range(8):
        f, jac = distort(K, dist, xy)
        e = f - px
        det = jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0]
        xy = xy - np.stack([jac[..., 1, 1] * e[..., 0] - jac[..., 0, 1] * e[..., 1],
                            jac[..., 0, 0] * e[..., 1] - jac[..., 1, 0] * e[..., 0]], axis=-1) / det[..., None]
    flat = xy.reshape(-1, 2)[::997]
    pts = np.ascontiguousarray(np.column_stack([flat, np.ones(len(flat))]))
    back = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K, np.asarray(dist, float))[0].reshape(-1, 2)
    assert np.max(np.abs(back - px.reshape(-1, 2)[::997])) < 1e-4, "ray map does not invert the lens model"
    return xy


def render(rays: np.ndarray, texture: np.ndarray, square_mm: float, px_per_square: int, rvec: np.ndarray,
           tvec: np.ndarray, margin_squares: float = 1.0, noise: float = 1.0, seed: int = 0,
           blur_px: float = BLUR_PX) -> np.ndarray:
    """(H, W) uint8 image of the board (``texture``: 0/255, board frame origin at its top-left texel corner, x right,
    y down) at pose (rvec, tvec mm: board → camera), on white paper ``margin_squares`` wide, on a grey background,
    blurred by a Gaussian point spread of σ ``blur_px`` and with grey-level noise σ ``noise``."""
    import cv2

    R = cv2.Rodrigues(np.asarray(rvec, float))[0]
    t = np.asarray(tvec, float).ravel()
    d = np.concatenate([rays, np.ones(rays.shape[:2] + (1,))], axis=-1)           # (Hs, Ws, 3) rays, camera frame
    lam = (R[:, 2] @ t) / (d @ R[:, 2])                                           # ray length to the plane z_b = 0
    board = (lam[..., None] * d - t) @ R                                          # R^T (λ d − t): board frame, mm
    scale = px_per_square / square_mm
    iu = np.floor(board[..., 0] * scale).astype(np.int64)
    iv = np.floor(board[..., 1] * scale).astype(np.int64)
    th, tw = texture.shape
    inside = (iu >= 0) & (iv >= 0) & (iu < tw) & (iv < th) & (lam > 0)
    m = margin_squares * px_per_square
    paper = (iu >= -m) & (iv >= -m) & (iu < tw + m) & (iv < th + m) & (lam > 0)
    value = np.where(paper, PAPER, BACKGROUND)
    tex = texture[np.clip(iv, 0, th - 1), np.clip(iu, 0, tw - 1)] / 255.0
    value = np.where(inside, BLACK + (WHITE - BLACK) * tex, value)
    hs, ws = value.shape
    img = value.reshape(hs // SUB, SUB, ws // SUB, SUB).mean(axis=(1, 3))
    if blur_px > 0:  # the lens's point spread
        img = cv2.GaussianBlur(img, (0, 0), blur_px)
    img = img + np.random.default_rng(seed).normal(0.0, noise, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def random_poses(K: np.ndarray, dist: np.ndarray, size: tuple[int, int], board_mm: tuple[float, float], n: int,
                 seed: int, tilt_deg: tuple[float, float] = (15.0, 40.0), distance_mm: tuple[float, float] = (420, 750),
                 margin_px: float = 12.0, spread: float = 1.0) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` board poses (rvec, tvec mm) whose whole board (outer corners) projects inside the image by
    ``margin_px``, tilted between ``tilt_deg`` about random axes and centred near ``ANCHORS`` in turn (a negative
    ``margin_px`` lets the board leave the image: ChArUco views may be partial; ``spread`` > 1 moves the
    anchors further out). ``tilt_deg`` = (0, 0) gives a fronto-parallel set."""
    import cv2

    rng = np.random.default_rng(seed)
    w, h = size
    bw, bh = board_mm
    outline = np.array([[0, 0, 0], [bw, 0, 0], [0, bh, 0], [bw, bh, 0], [bw / 2, 0, 0], [0, bh / 2, 0],
                        [bw, bh / 2, 0], [bw / 2, bh, 0]], float)
    poses: list[tuple[np.ndarray, np.ndarray]] = []
    shrink = 1.0
    while len(poses) < n:
        anchor = np.array(ANCHORS[len(poses) % len(ANCHORS)]) - 0.5
        target = (0.5 + anchor * spread * shrink) * [w, h] + rng.normal(0.0, 0.03 * w, 2)
        shrink *= 0.98  # pulled towards the centre until the board fits
        z = rng.uniform(*distance_mm)
        axis = rng.normal(size=3)
        axis[2] *= 0.3
        tilt = np.radians(rng.uniform(*tilt_deg))
        rot = cv2.Rodrigues(axis / np.linalg.norm(axis) * tilt)[0] @ cv2.Rodrigues(
            np.array([0.0, 0.0, rng.uniform(-0.3, 0.3)]))[0]
        centre = z * np.linalg.solve(K, [*target, 1.0])
        t = centre - rot @ np.array([bw / 2, bh / 2, 0.0])
        rvec = cv2.Rodrigues(rot)[0].ravel()
        px = cv2.projectPoints(outline, rvec, t, K, dist)[0].reshape(-1, 2)
        if np.all((px > margin_px) & (px < np.array([w, h]) - margin_px)):
            poses.append((rvec, t))
            shrink = 1.0
    return poses
