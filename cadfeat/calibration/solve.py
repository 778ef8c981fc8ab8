"""Camera calibration from board images with the thesis's error analysis (Appendix A).

``calibrate(paths, board)`` reads every image (a missing or unreadable one is rejected by name and the rest go
on), finds the board, and solves Zhang's calibration with ``cv2.calibrateCameraExtended`` (the OpenCV model:
fx, fy, cx, cy, k1, k2, p1, p2, k3). The error analysis: the overall and per-image reprojection RMS (px), each
parameter's standard deviation (OpenCV's, from the Jacobian at the solution and the residual variance), the
images rejected and why (unreadable, other size, board not found, reprojection outlier), and how well the board
corners cover the image (``coverage``): where no corner was seen the distortion is extrapolated, so a corner of
the image left uncovered is a warning. A set whose boards all face the camera the same way (fronto-parallel)
does not determine the focal length (Zhang 2000, §3.3): it is refused by the spread of the board normals.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypedDict

import numpy as np

from cadfeat.calibration.boards import BoardSpec
from cadfeat.camera import Camera, CameraError
from cadfeat.errors import CadfeatError
from cadfeat.vision.image_files import ImageFileError, read_grey

#: Fewest images with the board found that a calibration accepts (5 intrinsics + 5 distortion terms need several
#: views at different tilts; OpenCV's own sample asks for more).
MIN_VIEWS = 5
#: Smallest largest-angle between two board normals (deg) that is not a degenerate (fronto-parallel) set.
MIN_NORMAL_SPREAD_DEG = 10.0
#: A view whose reprojection RMS exceeds this many times the median of the views (and 1 px) is rejected.
OUTLIER_FACTOR = 3.0
OUTLIER_MIN_PX = 1.0
#: The image's corner regions checked for coverage: this fraction of the width and height at each corner.
CORNER_REGION = 1.0 / 6.0
#: With k3 estimated, the corner radius fraction the boards must reach for k3 not to count as extrapolated.
K3_REACH = 0.95
#: The coverage grid (cells across, down).
COVERAGE_GRID = (8, 6)
#: The calibrated parameters, in the order of ``cv2.calibrateCameraExtended``'s standard deviations.
PARAMETERS = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
_CORNER_NAMES = ("top-left", "top-right", "bottom-left", "bottom-right")


class CalibrationError(CadfeatError):
    """The images do not give a calibration (too few boards found, a degenerate set, OpenCV failed)."""


@dataclass(frozen=True)
class View:
    """One image used: ``path``, image points (n, 2) px, board points (n, 3) mm, the board pose (rvec, tvec mm:
    board → camera) and the residuals (n, 2) px = detected − reprojected."""

    path: Path
    image_px: np.ndarray
    board_mm: np.ndarray
    rvec: np.ndarray
    tvec_mm: np.ndarray
    residuals_px: np.ndarray

    @property
    def rms_px(self) -> float:
        """Reprojection RMS of this view (px, over the corners' 2-D residuals)."""
        return float(np.sqrt(np.mean(np.sum(self.residuals_px ** 2, axis=1))))

    @property
    def normal(self) -> np.ndarray:
        """(3,) the board's z axis (normal) in the camera frame."""
        import cv2

        return cv2.Rodrigues(self.rvec)[0][:, 2]

    @property
    def tilt_deg(self) -> float:
        """Angle between the board normal and the optical axis, degrees (0 = fronto-parallel)."""
        return float(np.degrees(np.arccos(min(1.0, abs(float(self.normal[2]))))))


@dataclass(frozen=True)
class Rejected:
    """An image not used and why (a sentence)."""

    path: Path
    reason: str


@dataclass(frozen=True)
class Coverage:
    """How the board corners of all views cover the image: ``grid_fraction`` of the ``COVERAGE_GRID`` cells with a
    corner, ``uncovered_corners`` the image corners (top-left, ...) whose ``CORNER_REGION`` region has none,
    ``radius_fraction`` the largest corner distance from the principal point over the image corner's (1 = the
    distortion model is fitted out to the image corners)."""

    grid_fraction: float
    uncovered_corners: tuple[str, ...]
    radius_fraction: float


class CoverageData(TypedDict):
    """The report's ``coverage``: the share of the image grid the corners cover, the image corners they miss, how
    far out (fraction of the corner radius) they reach."""

    grid_fraction: float
    uncovered_corners: list[str]
    radius_fraction: float


class ViewData(TypedDict):
    """One image used (the report's ``views``): its path, reprojection RMS (px), corners found, board tilt (deg)."""

    image: str
    rms_px: float
    corners: int
    tilt_deg: float


class CalibrationReport(TypedDict):
    """A calibration's ``<stem>_report.json`` (``CalibrationResult.to_json``)."""

    board: str
    image_size: list[int]
    rms_px: float
    parameters: dict[str, dict[str, float]]
    """Per parameter (fx, fy, cx, cy, k1 …) its value and 1-sigma standard deviation."""
    edge_distortion_px: float
    views: list[ViewData]
    rejected: list[dict[str, str]]
    coverage: CoverageData
    normal_spread_deg: float
    warnings: list[str]
    fixed_k3: bool


@dataclass
class CalibrationResult:
    """A calibration: the ``camera``, overall ``rms_px``, per-parameter standard deviations ``std`` (``PARAMETERS``;
    px for fx..cy, unitless for the distortion), the ``views`` used, the ``rejected`` images, ``coverage``, the
    board normals' largest pairwise angle ``normal_spread_deg``, ``warnings`` (sentences) and ``fixed_k3`` (k3 held
    at 0)."""

    camera: Camera
    rms_px: float
    std: dict[str, float]
    views: list[View]
    rejected: list[Rejected]
    board: BoardSpec
    coverage: Coverage
    normal_spread_deg: float
    warnings: list[str] = field(default_factory=list)
    fixed_k3: bool = False

    def to_json(self) -> CalibrationReport:
        """Plain-data form (the ``<stem>_report.json`` beside the calibration file)."""
        cam = self.camera
        return {
            "board": self.board.describe(),
            "image_size": [cam.width, cam.height],
            "rms_px": self.rms_px,
            "parameters": {p: {"value": v, "std": self.std[p]} for p, v in zip(
                PARAMETERS, (cam.fx, cam.fy, cam.cx, cam.cy, *cam.dist), strict=True)},
            "edge_distortion_px": float(np.max(np.linalg.norm(edge_displacement_px(cam), axis=-1))),
            "views": [{"image": str(v.path), "rms_px": v.rms_px, "corners": len(v.image_px),
                       "tilt_deg": v.tilt_deg} for v in self.views],
            "rejected": [{"image": str(r.path), "reason": r.reason} for r in self.rejected],
            "coverage": {"grid_fraction": self.coverage.grid_fraction,
                         "uncovered_corners": list(self.coverage.uncovered_corners),
                         "radius_fraction": self.coverage.radius_fraction},
            "normal_spread_deg": self.normal_spread_deg,
            "warnings": list(self.warnings),
            "fixed_k3": self.fixed_k3,
        }


def calibrate(paths: Sequence[str | Path], board: BoardSpec, fix_k3: bool = False,
              optics: dict[str, float] | None = None) -> CalibrationResult:
    """Calibrate from the board images at ``paths`` (module docstring). ``fix_k3`` keeps k3 = 0 (Bouguet's
    default, as the thesis's Table A.1); ``optics`` are ``Camera`` optics fields (``focal_length_mm``,
    ``f_number``, ``focus_distance_mm``) passed to the result's camera. Raises ``CalibrationError``."""
    found, rejected, size = _detect_all(paths, board)
    _require_views(found, rejected, board, len(paths))
    views, K, dist, std = _solve(found, size, fix_k3)
    spread = normal_spread_deg(np.stack([v.normal for v in views]))
    if spread < MIN_NORMAL_SPREAD_DEG:
        raise CalibrationError(
            f"degenerate image set: the {len(views)} boards found all face the camera the same way (the largest "
            f"angle between two board normals is {spread:.1f} deg, needs >= {MIN_NORMAL_SPREAD_DEG:g} deg), so the "
            "focal length is not determined; add views with the board tilted 20-45 deg about different axes")
    outliers = _outliers(views)
    if outliers and len(views) - len(outliers) >= MIN_VIEWS:
        median = float(np.median([v.rms_px for v in views]))
        rejected += [Rejected(v.path, f"reprojection RMS {v.rms_px:.2f} px is more than {OUTLIER_FACTOR:g}x the "
                              f"median {median:.2f} px (board misdetected, blurred or moved)") for v in outliers]
        kept = [(v.path, v.image_px, v.board_mm) for v in views if v not in outliers]
        views, K, dist, std = _solve(kept, size, fix_k3)
    camera = _camera(K, dist, size, optics or {})
    coverage = image_coverage(np.concatenate([v.image_px for v in views]), camera)
    rms = float(np.sqrt(np.mean(np.concatenate([np.sum(v.residuals_px ** 2, axis=1) for v in views]))))
    result = CalibrationResult(camera, rms, std, views, rejected, board, coverage, spread, fixed_k3=fix_k3)
    result.warnings = _warnings(result)
    return result


def _detect_all(paths: Sequence[str | Path], board: BoardSpec
                ) -> tuple[list[tuple[Path, np.ndarray, np.ndarray]], list[Rejected], tuple[int, int]]:
    """Read and detect every image: the (path, image points, board points) found, the rejected, (W, H) px."""
    found: list[tuple[Path, np.ndarray, np.ndarray]] = []
    rejected: list[Rejected] = []
    size: tuple[int, int] | None = None
    for p in map(Path, paths):
        try:
            grey = read_grey(p)
        except ImageFileError as exc:
            rejected.append(Rejected(p, exc.reason))
            continue
        shape = (grey.shape[1], grey.shape[0])
        size = size or shape
        if shape != size:
            rejected.append(Rejected(p, f"image size {shape[0]}x{shape[1]} differs from the first image's "
                                        f"{size[0]}x{size[1]}"))
            continue
        detection = board.detect(grey)
        if isinstance(detection, str):
            rejected.append(Rejected(p, detection))
        else:
            found.append((p, *detection))
    return found, rejected, size or (0, 0)


def _require_views(found: Sequence[object], rejected: list[Rejected], board: BoardSpec, n: int) -> None:
    if len(found) >= MIN_VIEWS:
        return
    why = "; ".join(f"{r.path.name}: {r.reason}" for r in rejected[:6]) + (" ..." if len(rejected) > 6 else "")
    raise CalibrationError(f"needs >= {MIN_VIEWS} images with the board ({board.describe()}) found; found it in "
                           f"{len(found)} of {n}" + (f" ({why})" if why else ""))


def _solve(found: list[tuple[Path, np.ndarray, np.ndarray]], size: tuple[int, int], fix_k3: bool
           ) -> tuple[list[View], np.ndarray, np.ndarray, dict[str, float]]:
    """``cv2.calibrateCameraExtended`` on the views found: views with residuals, K, dist (5,), std devs."""
    import cv2

    obj = [f[2].astype(np.float32) for f in found]
    img = [f[1].astype(np.float32).reshape(-1, 1, 2) for f in found]
    flags = cv2.CALIB_FIX_K3 if fix_k3 else 0
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    try:
        out = cv2.calibrateCameraExtended(obj, img, size, np.eye(3), np.zeros(5), flags=flags, criteria=criteria)
    except cv2.error as exc:
        raise CalibrationError(f"OpenCV could not calibrate from these {len(found)} views "
                               f"({str(exc).strip().splitlines()[-1]}); add views with the board tilted") from None
    _, K, dist, rvecs, tvecs, std_int = out[:6]
    dist = np.asarray(dist, float).ravel()[:5]
    if not (np.all(np.isfinite(K)) and np.all(np.isfinite(dist))):
        raise CalibrationError("OpenCV's calibration did not converge (non-finite parameters); add views with the "
                               "board tilted 20-45 deg and covering the image")
    views = []
    for (path, px, mm), r, t in zip(found, rvecs, tvecs, strict=True):
        proj = cv2.projectPoints(mm, r, t, K, dist)[0].reshape(-1, 2)
        views.append(View(path, px, mm, np.asarray(r, float).ravel(), np.asarray(t, float).ravel(), px - proj))
    std = {p: float(s) for p, s in zip(PARAMETERS, np.asarray(std_int, float).ravel()[:9], strict=True)}
    return views, np.asarray(K, float), dist, std


def _outliers(views: list[View]) -> list[View]:
    rms = np.array([v.rms_px for v in views])
    limit = max(OUTLIER_FACTOR * float(np.median(rms)), OUTLIER_MIN_PX)
    return [v for v, e in zip(views, rms, strict=True) if e > limit]


def _camera(K: np.ndarray, dist: np.ndarray, size: tuple[int, int], optics: dict[str, float]) -> Camera:
    try:
        return Camera(fx=float(K[0, 0]), fy=float(K[1, 1]), cx=float(K[0, 2]), cy=float(K[1, 2]), width=size[0],
                      height=size[1], dist=tuple(float(d) for d in dist), name="calibrated", **optics)
    except CameraError as exc:
        raise CalibrationError(f"the calibration gives an invalid camera ({exc}); add views covering the image "
                               "with the board tilted") from None


def normal_spread_deg(normals: np.ndarray) -> float:
    """Largest angle (deg) between two of the unit normals (V, 3) — 0 for a fronto-parallel set."""
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    cos = np.clip(np.abs(n @ n.T), 0.0, 1.0)  # a board seen from behind has the same plane
    return float(np.degrees(np.arccos(cos.min())))


def image_coverage(corners_px: np.ndarray, camera: Camera) -> Coverage:
    """``Coverage`` of the image by the corners (M, 2) px of all views."""
    w, h = camera.width, camera.height
    gx, gy = COVERAGE_GRID
    cells = np.unique(np.clip((corners_px / [w / gx, h / gy]).astype(int), 0, [gx - 1, gy - 1]), axis=0)
    rx, ry = CORNER_REGION * w, CORNER_REGION * h
    boxes = ((0, 0), (w - rx, 0), (0, h - ry), (w - rx, h - ry))
    uncovered = tuple(name for name, (x0, y0) in zip(_CORNER_NAMES, boxes, strict=True) if not np.any(
        (corners_px[:, 0] >= x0) & (corners_px[:, 0] <= x0 + rx) & (corners_px[:, 1] >= y0)
        & (corners_px[:, 1] <= y0 + ry)))
    far = np.hypot(np.maximum(camera.cx, w - camera.cx), np.maximum(camera.cy, h - camera.cy))
    reach = float(np.max(np.hypot(corners_px[:, 0] - camera.cx, corners_px[:, 1] - camera.cy)))
    return Coverage(len(cells) / (gx * gy), uncovered, reach / float(far))


def edge_displacement_px(camera: Camera, per_side: int = 32) -> np.ndarray:
    """(4·per_side, 2) the lens distortion's displacement (px) at points along the image border: the pixel minus
    where an ideal pinhole with the same K would put the same ray (``cv2.undistortPoints``, iterated to 1e-12)."""
    import cv2

    w, h = camera.width - 1.0, camera.height - 1.0
    s = np.linspace(0.0, 1.0, per_side, endpoint=False)
    border = np.concatenate([np.column_stack([s * w, 0 * s]), np.column_stack([w + 0 * s, s * h]),
                             np.column_stack([w - s * w, h + 0 * s]), np.column_stack([0 * s, h - s * h])])
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    xy = cv2.undistortPoints(border.reshape(-1, 1, 2), camera.K, camera.dist_coeffs,
                             criteria=criteria).reshape(-1, 2)
    ideal = xy * [camera.fx, camera.fy] + [camera.cx, camera.cy]
    return border - ideal


def _warnings(result: CalibrationResult) -> list[str]:
    out = []
    cov = result.coverage
    if cov.uncovered_corners:
        out.append(f"no board corner in the image's {', '.join(cov.uncovered_corners)} corner region"
                   f"{'s' if len(cov.uncovered_corners) > 1 else ''} (outer {CORNER_REGION:.0%} of width and height): "
                   "the distortion is extrapolated there; add views with the board in those corners")
    if cov.radius_fraction < K3_REACH and not result.fixed_k3:
        out.append(f"the board corners reach {cov.radius_fraction:.0%} of the way to the image corners: k3 (the "
                   "highest distortion term) is extrapolated there; add views with the board in the image corners, or "
                   "use --fix-k3 (Bouguet's model, as the thesis)")
    if result.camera.fold_inside_image:
        out.append(f"the distortion model folds back inside the image (valid field {result.camera.valid_field_deg:.0f}"
                   " deg off axis): its higher terms are not determined; cover the image corners or use --fix-k3")
    rel = [(p, result.std[p] / abs(v)) for p, v in (("fx", result.camera.fx), ("fy", result.camera.fy))
           if math.isfinite(result.std[p])]
    for p, r in rel:
        if r > 0.01:
            out.append(f"{p} is uncertain to {100 * r:.1f} % (1 sigma): add tilted views")
    return out
