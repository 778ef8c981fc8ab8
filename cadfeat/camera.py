"""The camera: OpenCV intrinsics, lens distortion, thin-lens optics and named presets.

Frames and units follow docs/design.md "Conventions": the OpenCV camera frame (x right, y down, z forward),
millimetres in 3-D, pixels in the image. Projection is the OpenCV model (the same numbers as
``cv2.projectPoints``) with the distortion vector ``(k1, k2, p1, p2, k3)``; the thesis writes the
same pinhole model as eq. A.1-A.7 and uses Bouguet's ``kc`` for the distortion (Table A.1).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict, Unpack

import numpy as np

from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    import cv2

#: Depth (mm) below which a point counts as at or behind the camera centre; projection clamps to it.
MIN_DEPTH_MM = 1e-6


class CameraError(CadfeatError):
    """A camera definition or calibration file is invalid. ``key`` (the ``Camera`` field at fault, or
    ``"calibration"``) and ``allowed`` (what it may be) let a study file's check name them."""

    def __init__(self, message: str, key: str = "", allowed: str = "") -> None:
        super().__init__(message)
        self.key = key
        self.allowed = allowed


_POSITIVE_FIELDS = ("fx", "fy", "focal_length_mm", "focus_distance_mm")
_OPTIONAL_POSITIVE_FIELDS = ("f_number", "aperture_mm", "blur_circle_mm")


class CameraFields(TypedDict, total=False):
    """``Camera``'s fields as keyword arguments (a preset, a calibration file, a study's overrides, ``to_dict``)."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    dist: tuple[float, ...] | list[float]
    focal_length_mm: float
    f_number: float | None
    aperture_mm: float | None
    focus_distance_mm: float
    blur_circle_mm: float | None
    name: str
    source: str


class Optics(TypedDict, total=False):
    """The lens's optics a calibration may be given with (``Camera.from_opencv_file``, ``OPTICS_NODES``)."""

    focal_length_mm: float
    f_number: float
    focus_distance_mm: float


def _is_real(value: object) -> bool:
    """A real number (int, float, numpy scalar) and not a bool."""
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool | np.bool_)


@dataclass(frozen=True)
class Camera:
    """A calibrated camera with optics for depth of field.

    Intrinsics are in pixels (``fx, fy, cx, cy``; ``width x height`` image), ``dist`` is OpenCV's
    ``(k1, k2, p1, p2, k3)``. The optics are those of the thin-lens depth-of-field model (eq. 3.4-3.6):
    ``focal_length_mm`` (f_C), ``f_number`` N (or ``aperture_mm``, the entrance-pupil diameter
    a_C = f_C / N), ``focus_distance_mm`` (object distance in exact focus, measured along the optical
    axis) and ``blur_circle_mm`` c, the largest acceptable blur-circle diameter on the sensor. When
    ``blur_circle_mm`` is not given it defaults to two pixel pitches, ``2 * focal_length_mm / fx``.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    dist: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    focal_length_mm: float = 8.0
    f_number: float | None = None
    aperture_mm: float | None = None
    focus_distance_mm: float = 300.0
    blur_circle_mm: float | None = None
    name: str = "custom"
    source: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        self._check_numbers()
        dist = self.dist
        if isinstance(dist, str) or not hasattr(dist, "__len__") or len(dist) not in (4, 5) or \
                not all(_is_real(d) and math.isfinite(d) for d in dist):
            raise CameraError(f"camera '{self.name}': dist must be 4 or 5 finite numbers (k1, k2, p1, p2[, k3]), "
                              f"got {dist!r}", "dist", "4 or 5 finite numbers [k1, k2, p1, p2(, k3)]")
        dist = tuple(float(d) for d in dist)
        object.__setattr__(self, "dist", dist if len(dist) == 5 else (*dist, 0.0))
        if not (0.0 <= self.cx <= self.width and 0.0 <= self.cy <= self.height):
            raise CameraError(f"camera '{self.name}': principal point (cx, cy) = ({self.cx}, {self.cy}) must lie "
                              f"inside the {self.width}x{self.height} image", "cx",
                              "0 ≤ cx ≤ width and 0 ≤ cy ≤ height (px)")
        self._resolve_aperture()
        if self.blur_circle_mm is None:
            object.__setattr__(self, "blur_circle_mm", 2.0 * self.pixel_pitch_mm)
        if self.focus_distance_mm <= self.focal_length_mm:
            raise CameraError(
                f"camera '{self.name}': focus_distance_mm ({self.focus_distance_mm}) must exceed "
                f"focal_length_mm ({self.focal_length_mm})", "focus_distance_mm", "a distance > focal_length_mm (mm)"
            )

    def _check_numbers(self) -> None:
        """Every numeric field is a finite real number (positive where it must be); sizes are integers."""
        for key in _POSITIVE_FIELDS + _OPTIONAL_POSITIVE_FIELDS + ("cx", "cy"):
            value = getattr(self, key)
            if value is None and key in _OPTIONAL_POSITIVE_FIELDS:
                continue
            if not _is_real(value) or not math.isfinite(value):
                raise CameraError(f"camera '{self.name}': {key} must be a finite number, got {value!r}", key,
                                  "a finite number")
            if key not in ("cx", "cy") and value <= 0:
                raise CameraError(f"camera '{self.name}': {key} must be a positive number, got {value!r}", key,
                                  "a number > 0")
            object.__setattr__(self, key, float(value))
        for key in ("width", "height"):
            value = getattr(self, key)
            if not _is_real(value) or not float(value).is_integer() or value < 1:
                raise CameraError(f"camera '{self.name}': {key} must be a positive integer (pixels), got {value!r}",
                                  key, "an integer ≥ 1 (px)")
            object.__setattr__(self, key, int(value))

    def _resolve_aperture(self) -> None:
        """Fill ``f_number`` / ``aperture_mm`` from each other (a_C = f_C / N, eq. 3.4); default f/4."""
        if self.f_number is None and self.aperture_mm is None:
            object.__setattr__(self, "f_number", 4.0)
        if self.f_number is not None and self.aperture_mm is not None:
            expected = self.focal_length_mm / self.f_number
            if not np.isclose(expected, self.aperture_mm, rtol=1e-6):
                raise CameraError(
                    f"camera '{self.name}': give f_number or aperture_mm, not both inconsistent "
                    f"(f/{self.f_number} means aperture {expected:.4g} mm, got {self.aperture_mm})", "aperture_mm",
                    "one of f_number or aperture_mm (or both with aperture_mm = focal_length_mm / f_number)"
                )
        if self.aperture_mm is None:
            object.__setattr__(self, "aperture_mm", self.focal_length_mm / float(self.f_number))
        if self.f_number is None:
            object.__setattr__(self, "f_number", self.focal_length_mm / float(self.aperture_mm))

    # ------------------------------------------------------------------ intrinsics
    @property
    def K(self) -> np.ndarray:
        """The 3x3 OpenCV camera matrix (pixels), eq. A.3 with f_C/s_x = fx."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def dist_coeffs(self) -> np.ndarray:
        """Distortion as the (5,) array ``cv2.projectPoints`` takes."""
        return np.asarray(self.dist, dtype=float)

    @property
    def has_distortion(self) -> bool:
        return bool(np.any(self.dist_coeffs != 0.0))

    @property
    def pixel_pitch_mm(self) -> float:
        """Horizontal pixel pitch s_x in mm (focal length over fx)."""
        return self.focal_length_mm / self.fx

    @property
    def fov_rad(self) -> float:
        """Field-of-view angle α of the smaller sensor dimension (eq. 3.1), radians.

        For a principal point off centre the half-angle to the nearer border is used, so the cone
        stays inside the sensor.
        """
        half_x = min(self.cx, self.width - self.cx) / self.fx
        half_y = min(self.cy, self.height - self.cy) / self.fy
        return 2.0 * float(np.arctan(min(half_x, half_y)))

    # ------------------------------------------------------------------ lens fold-over
    @property
    def fold_radius(self) -> float:
        """Largest normalised radius r = ‖(X/Z, Y/Z)‖ up to which the radial distortion r_d = r (1 + k1 r² +
        k2 r⁴ + k3 r⁶) grows with r (``inf`` if it always does): the smallest positive root s = r² of
        d r_d / d r = 1 + 3 k1 s + 5 k2 s² + 7 k3 s³. Past it rays fold back into the image (several
        directions map to one pixel), so points there count as outside the image in every measure."""
        k1, k2, _, _, k3 = self.dist
        roots = np.roots([7.0 * k3, 5.0 * k2, 3.0 * k1, 1.0]) if (k1 or k2 or k3) else np.zeros(0)
        s = [float(r.real) for r in np.atleast_1d(roots) if abs(r.imag) < 1e-12 and r.real > 0]
        return float(np.sqrt(min(s))) if s else float("inf")

    @property
    def valid_field_deg(self) -> float:
        """Half-angle off the optical axis (degrees) of the lens model's valid (monotonic) field: atan of
        ``fold_radius`` (90 for a lens without fold)."""
        return float(np.degrees(np.arctan(self.fold_radius)))

    @property
    def fold_radius_distorted(self) -> float:
        """The distorted normalised radius r_d(fold) of the fold circle (``fold_radius``; ``inf`` without fold):
        the image of the lens model's valid field is the ellipse ((u − cx)/fx)² + ((v − cy)/fy)² < r_d²."""
        r = self.fold_radius
        if not np.isfinite(r):
            return float("inf")
        k1, k2, _, _, k3 = self.dist
        s = r * r
        return float(r * (1 + k1 * s + k2 * s * s + k3 * s ** 3))

    @property
    def fold_inside_image(self) -> bool:
        """True when the image of the fold circle (radius fx·r_d(fold) px about the principal point) does not
        contain the whole image: parts of the image are then reachable only by folded rays — the
        calibration is not valid over the image (a warning)."""
        rd = self.fold_radius_distorted
        if not np.isfinite(rd):
            return False
        corners = np.array([[0, 0], [self.width, 0], [0, self.height], [self.width, self.height]], float)
        reach = np.hypot((corners[:, 0] - self.cx) / self.fx, (corners[:, 1] - self.cy) / self.fy)
        return bool(reach.max() > rd)

    def folded(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """(…) bool: normalised image points (x, y) past ``fold_radius``."""
        r = self.fold_radius
        if not np.isfinite(r):
            return np.zeros(np.broadcast(x, y).shape, dtype=bool)
        return np.asarray(x) ** 2 + np.asarray(y) ** 2 > r * r

    # ------------------------------------------------------------------ optics (eq. 3.4-3.6)
    @property
    def image_distance_mm(self) -> float:
        """d_C: back nodal point to image plane (thin lens focused at ``focus_distance_mm``), mm."""
        f, s = self.focal_length_mm, self.focus_distance_mm
        return f * s / (s - f)

    @property
    def hyperfocal_distance_mm(self) -> float:
        """Focus distance beyond which the far plane D1 is at infinity, mm (f²/(N c) + f)."""
        f = self.focal_length_mm
        return f * f / (self.f_number * self.blur_circle_mm) + f

    @property
    def depth_of_field_mm(self) -> tuple[float, float]:
        """(D2, D1): near and far planes of acceptable focus (eq. 3.5, 3.4), mm; D1 may be ``inf``."""
        a, f, d, c = self.aperture_mm, self.focal_length_mm, self.image_distance_mm, self.blur_circle_mm
        near = a * f * d / (a * (d - f) + c * f)
        denom = a * (d - f) - c * f
        far = a * f * d / denom if denom > 0 else float("inf")
        return float(near), float(far)

    # ------------------------------------------------------------------ projection
    def project(self, points_cam: np.ndarray) -> np.ndarray:
        """Project camera-frame points (..., 3) in mm to pixels (..., 2), as ``cv2.projectPoints``.

        Points at or behind the camera (Z ≤ ``MIN_DEPTH_MM``) are clamped to that depth so the result
        stays finite; measures flag them separately.
        """
        return self.distort_normalized(self.normalize(points_cam))

    @staticmethod
    def normalize(points_cam: np.ndarray) -> np.ndarray:
        """Pinhole normalised coordinates (X/Z, Y/Z), (..., 2), with the depth clamp of ``project``."""
        p = np.asarray(points_cam, dtype=float)
        z = np.maximum(p[..., 2], MIN_DEPTH_MM)
        return p[..., :2] / z[..., None]

    def distort_normalized(self, xy: np.ndarray) -> np.ndarray:
        """Apply OpenCV distortion and the camera matrix to normalised coordinates (..., 2) → px."""
        x, y = xy[..., 0], xy[..., 1]
        xd, yd = self._distort(x, y)
        return np.stack([self.fx * xd + self.cx, self.fy * yd + self.cy], axis=-1)

    def _distort(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        k1, k2, p1, p2, k3 = self.dist
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        return xd, yd

    def distortion_jacobian(self, xy: np.ndarray) -> np.ndarray:
        """∂(u, v)/∂(x, y): pixels per unit normalised coordinate, (..., 2, 2), distortion included."""
        x, y = xy[..., 0], xy[..., 1]
        k1, k2, p1, p2, k3 = self.dist
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dradial_dr2 = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)
        dxd_dx = radial + 2.0 * x * x * dradial_dr2 + 2.0 * p1 * y + 6.0 * p2 * x
        dxd_dy = 2.0 * x * y * dradial_dr2 + 2.0 * p1 * x + 2.0 * p2 * y
        dyd_dx = 2.0 * x * y * dradial_dr2 + 2.0 * p1 * x + 2.0 * p2 * y
        dyd_dy = radial + 2.0 * y * y * dradial_dr2 + 6.0 * p1 * y + 2.0 * p2 * x
        jac = np.empty(x.shape + (2, 2))
        jac[..., 0, 0] = self.fx * dxd_dx
        jac[..., 0, 1] = self.fx * dxd_dy
        jac[..., 1, 0] = self.fy * dyd_dx
        jac[..., 1, 1] = self.fy * dyd_dy
        return jac

    def in_image(self, pixels: np.ndarray, margin_px: float = 0.0) -> np.ndarray:
        """Boolean mask of pixels inside the image by at least ``margin_px``."""
        u, v = pixels[..., 0], pixels[..., 1]
        return (u >= margin_px) & (v >= margin_px) & (u <= self.width - margin_px) & (
            v <= self.height - margin_px
        )

    # ------------------------------------------------------------------ construction
    def replace(self, **changes: Unpack[CameraFields]) -> Camera:
        """A copy with some fields changed (validated again)."""
        if "f_number" in changes and "aperture_mm" not in changes:
            changes["aperture_mm"] = None
        if "aperture_mm" in changes and "f_number" not in changes:
            changes["f_number"] = None
        return dataclasses.replace(self, **changes)

    def without_distortion(self) -> Camera:
        """The same camera as an ideal pinhole (the thesis simulations, chapter 5)."""
        return self.replace(dist=(0.0, 0.0, 0.0, 0.0, 0.0), name=f"{self.name} (pinhole)")

    def to_dict(self) -> CameraFields:
        """Plain-data form (JSON/TOML friendly)."""
        d = CameraFields(**dataclasses.asdict(self))
        d["dist"] = list(self.dist)
        return d

    @classmethod
    def preset(cls, name: str) -> Camera:
        """A named camera from ``PRESETS`` (see ``cadfeat.camera.PRESETS`` for sources)."""
        key = name.strip().lower()
        if key not in PRESETS:
            raise CameraError(f"unknown camera preset {name!r}; allowed: {', '.join(sorted(PRESETS))}")
        return cls(**PRESETS[key])

    @classmethod
    def from_opencv_file(cls, path: str | Path, **optics: Unpack[Optics]) -> Camera:
        """Load an OpenCV calibration (``cv2.FileStorage`` YAML/XML/JSON) with camera matrix and distortion.

        Reads ``camera_matrix`` (or ``K``/``cameraMatrix``), ``distortion_coefficients`` (or ``D``/
        ``dist_coeffs``/``distCoeffs``) and ``image_width``/``image_height`` (or ``width``/``height``,
        or an ``image_size`` pair), and the optics nodes ``focal_length_mm``, ``f_number``, ``focus_distance_mm``
        when present (``cadfeat calibrate`` writes them); optics given as keyword arguments win.
        """
        return cls(**{**read_opencv_calibration(path), **optics})


_MATRIX_KEYS = ("camera_matrix", "K", "cameraMatrix", "intrinsics")
_DIST_KEYS = ("distortion_coefficients", "D", "dist_coeffs", "distCoeffs", "distortion")


def read_opencv_calibration(path: str | Path) -> CameraFields:
    """Parse a calibration file into ``Camera`` keyword arguments.

    Reads what ``cv2.FileStorage`` reads (YAML, XML, JSON): matrices stored by OpenCV
    (``!!opencv-matrix``), ROS ``camera_calibration`` files (``{rows, cols, data}`` maps) or plain
    (nested) lists; the optics nodes (``OPTICS_NODES``) when present. Raises ``CameraError`` naming the file and
    the expected keys.
    """
    import cv2

    path = Path(path)
    if not path.is_file():
        raise CameraError(f"{path}: calibration file not found")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:  # the parser's error surfaces as SystemError in some builds
        raise CameraError(f"{path}: not a readable OpenCV FileStorage file ({exc})") from exc
    if not fs.isOpened():
        raise CameraError(f"{path}: not a readable OpenCV FileStorage file")
    try:
        K = _first_matrix(fs, _MATRIX_KEYS, path)
        if K is not None and K.size == 9:
            K = K.reshape(3, 3)
        if K is None or K.shape != (3, 3):
            raise CameraError(f"{path}: needs a 3x3 camera matrix under one of {', '.join(_MATRIX_KEYS)}")
        dist = _first_matrix(fs, _DIST_KEYS, path)
        dist = np.zeros(5) if dist is None else dist.ravel()
        if dist.size not in (4, 5):
            raise CameraError(f"{path}: distortion must have 4 or 5 values (k1, k2, p1, p2[, k3]); "
                              f"got {dist.size}")
        width, height = _image_size(fs, path)
        optics = _optics_nodes(fs, path)
    finally:
        fs.release()
    return CameraFields(fx=float(K[0, 0]), fy=float(K[1, 1]), cx=float(K[0, 2]), cy=float(K[1, 2]),
                        width=width, height=height, dist=tuple(float(v) for v in dist), name=path.stem,
                        source=str(path), **optics)


#: The lens's optics a calibration file may carry as extra scalar nodes (``cadfeat calibrate --focal-length-mm
#: --f-number --focus-mm`` writes them): ``Camera`` fields of the focus measure (eq. 3.4-3.6).
OPTICS_NODES = ("focal_length_mm", "f_number", "focus_distance_mm")


def _optics_nodes(fs: cv2.FileStorage, path: Path) -> Optics:
    """The ``OPTICS_NODES`` present in the file, each a positive number (else ``CameraError`` naming it)."""
    out: dict[str, float] = {}
    for key in OPTICS_NODES:
        node = fs.getNode(key)
        if node.empty():
            continue
        value = float(node.real()) if (node.isReal() or node.isInt()) else float("nan")
        if not (np.isfinite(value) and value > 0):
            raise CameraError(f"{path}: {key}: not a positive number", key, "a number > 0")
        out[key] = value
    return Optics(**out)


def _first_matrix(fs: cv2.FileStorage, keys: tuple[str, ...], path: Path) -> np.ndarray | None:
    import cv2

    for key in keys:
        node = fs.getNode(key)
        if node.empty():
            continue
        try:
            mat = _node_array(node)
        except (ValueError, cv2.error) as exc:  # ragged lists, rows x cols not matching data, odd nodes
            raise CameraError(f"{path}: {key}: not a numeric matrix ({exc})") from exc
        if mat is None:
            raise CameraError(f"{path}: {key}: not a numeric matrix")
        return mat
    return None


def _node_array(node: cv2.FileNode) -> np.ndarray | None:
    """Numbers of a FileStorage node: an OpenCV matrix, a ``{rows, cols, data}`` map or a (nested) list."""
    if node.isMap():
        if not node.getNode("dt").empty():
            return np.asarray(node.mat(), dtype=float)
        data = node.getNode("data")
        values = None if data.empty() else _node_array(data)
        rows, cols = node.getNode("rows"), node.getNode("cols")
        if values is not None and not rows.empty() and not cols.empty():
            values = values.reshape(int(rows.real()), int(cols.real()))
        return values
    if node.isSeq():
        items = [_node_array(node.at(i)) for i in range(node.size())]
        return None if any(item is None for item in items) else np.array(items, dtype=float)
    if node.isInt() or node.isReal():
        return np.array(node.real())
    return None


def _image_size(fs: cv2.FileStorage, path: Path) -> tuple[int, int]:
    w, h = fs.getNode("image_width"), fs.getNode("image_height")
    if w.empty() or h.empty():
        w, h = fs.getNode("width"), fs.getNode("height")
    if not (w.empty() or h.empty()):
        return int(w.real()), int(h.real())
    size = fs.getNode("image_size")
    if not size.empty():
        vals = _first_matrix(fs, ("image_size",), path)
        if vals is not None and vals.size == 2:
            return int(vals.ravel()[0]), int(vals.ravel()[1])
    raise CameraError(f"{path}: needs image_width and image_height (or image_size = [width, height])")


def write_opencv_calibration(camera: Camera, path: str | Path) -> None:
    """Write ``camera`` as an OpenCV FileStorage calibration (YAML, XML or JSON by extension)."""
    import cv2

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", int(camera.width))
    fs.write("image_height", int(camera.height))
    fs.write("camera_matrix", camera.K)
    fs.write("distortion_coefficients", camera.dist_coeffs.reshape(1, 5))
    fs.release()


# Each preset documents its source. Optics not given by a source are stated as assumptions.
PRESETS: dict[str, CameraFields] = {
    "dalsa-cad1-128a": dict(
        name="dalsa-cad1-128a",
        fx=231.4119, fy=231.25, cx=64.2, cy=61.5, width=128, height=128,
        dist=(-1.4487, -1.3175, 0.0006845, 0.0006845, 0.0),
        focal_length_mm=3.5, f_number=5.6, focus_distance_mm=45.0,
        source="Shademan 2005, Table A.2 (Bouguet calibration: fc, cc, kc(1..4)) and §6.2 "
               "(DALSA CA-D1-0128A, 128x128 px at 16 µm, Rodenstock 3.5 mm lens). f/5.6 and a 45 mm "
               "focus distance are assumptions: depth of field ≈ 28.6-106 mm covers the thesis's "
               "28-60 mm working distances (§5.2).",
    ),
    "basler-aca1300-200um-8mm": dict(
        name="basler-aca1300-200um-8mm",
        fx=1666.67, fy=1666.67, cx=640.0, cy=512.0, width=1280, height=1024,
        focal_length_mm=8.0, f_number=4.0, focus_distance_mm=300.0,
        source="Basler ace acA1300-200um datasheet: 1280x1024 px, 4.8 µm pixels (e2v EV76C560); "
               "with an 8 mm C-mount lens fx = 8 / 0.0048 px. Ideal principal point, no distortion.",
    ),
    "flir-bfs-u3-51s5m-12mm": dict(
        name="flir-bfs-u3-51s5m-12mm",
        fx=3472.22, fy=3472.22, cx=1224.0, cy=1024.0, width=2448, height=2048,
        focal_length_mm=12.0, f_number=5.6, focus_distance_mm=500.0,
        source="FLIR Blackfly S BFS-U3-51S5M datasheet: 2448x2048 px, 3.45 µm pixels (Sony IMX250); "
               "with a 12 mm lens fx = 12 / 0.00345 px. Ideal principal point, no distortion.",
    ),
    "realsense-d435-rgb": dict(
        name="realsense-d435-rgb",
        fx=615.0, fy=615.0, cx=320.0, cy=240.0, width=640, height=480,
        focal_length_mm=1.93, f_number=2.0, focus_distance_mm=300.0,
        source="Intel RealSense D435 datasheet, colour stream at 640x480 (69°x42° FOV, 1.4 µm pixels "
               "binned x2); typical factory intrinsics fx≈fy≈615 px. Fixed focus; f/2 assumed.",
    ),
}


def build_camera(overrides: Mapping[str, object], preset: str | None = None, calibration: str | Path | None = None
                 ) -> Camera:
    """A camera from a preset name or an OpenCV calibration file (or neither) and ``overrides`` (``Camera``
    fields; an override of ``f_number`` or ``aperture_mm`` alone recomputes the other). The checks are
    ``Camera``'s; a study file's ``[camera]`` is checked first by ``cadfeat.study.settings.CameraSettings``."""
    if preset is not None:
        base = Camera.preset(preset).to_dict()
    elif calibration is not None:
        base = read_opencv_calibration(calibration)
    else:
        base = {}
    merged = {**base, **overrides}
    if "f_number" in overrides and "aperture_mm" not in overrides:
        merged["aperture_mm"] = None
    if "aperture_mm" in overrides and "f_number" not in overrides:
        merged["f_number"] = None
    if "dist" in merged:
        merged["dist"] = tuple(merged["dist"])
    return Camera(**merged)


def dumps(camera: Camera) -> str:
    """JSON text of a camera (for results files)."""
    return json.dumps(camera.to_dict(), indent=2)
