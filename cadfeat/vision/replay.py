"""Replay a recorded sequence: real images of the part with the robot's reported camera pose per image, through the
closed loop's detection, association and EKF/IEKF/PnP (``closed_loop``'s very functions).

Inputs as a robot cell logs them:

- **poses CSV** (``read_reported_poses``): one line per image, ``time_s`` then either the camera position (mm) and
  a scalar-last quaternion (``x,y,z,qx,qy,qz,qw``: 8 numbers) or a 3x4 pose row by row (13 numbers); a header
  line, blank lines and ``#`` comments are skipped; a line that does not parse is reported by its number and
  skipped (its image then has no pose). The poses are T_task_cam (or T_task_flange with a hand-eye transform
  T_flange_cam, ``read_hand_eye``).
- **images** (``match_images``): ``frame_NNNN.png`` (any name whose last number is NNNN) is the image of the
  CSV's data row NNNN (0-based); PNG/JPEG/TIFF/PGM, 8 or 16 bit, colour or grey (``image_files.read_grey``).

``replay`` predicts each hole's rim at the reported pose, detects (``detectors.detect`` with those rims as the
prior), associates (``detection.associate``), and tracks with each estimator from the first reported pose. The
errors are against the reported poses — a reference with its own accuracy (the robot's, the hand-eye's, the
part's placement), not truth: ``nees`` measures the filter's consistency against it with the reference's assumed
covariance added to the filter's.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cadfeat.camera import Camera
from cadfeat.errors import CadfeatError
from cadfeat.measures import hole_ellipse
from cadfeat.measures.ellipse import Ellipse
from cadfeat.vision.detection import associate
from cadfeat.vision.detectors import detect
from cadfeat.vision.estimate import FilterTuning, estimate_poses
from cadfeat.vision.image_files import IMAGE_SUFFIXES, ImageFileError, read_grey
from cadfeat.vision.metrics import pose_errors
from cadfeat.vision.motion import so3_log

#: Numbers per line of a poses CSV: time + position + quaternion, or time + a 3x4 matrix.
QUATERNION_LINE, MATRIX_LINE = 8, 13
#: A quaternion whose norm is off 1 by more than this is refused (a line mixed up, not a rounding).
QUATERNION_NORM_TOL = 1e-3


@dataclass
class ReportedPoses:
    """The robot's reported poses: ``times_s`` (F,), ``T`` (F, 4, 4) mm, the CSV ``lines`` they came from, their
    data ``rows`` (0-based count of the data lines, bad ones included: frame_NNNN is row NNNN) and the ``problems``
    (one sentence per skipped line)."""

    times_s: np.ndarray
    T: np.ndarray
    lines: list[int]
    rows: list[int]
    problems: list[str] = field(default_factory=list)


def read_reported_poses(path: str | Path) -> ReportedPoses:
    """Parse a poses CSV (module docstring); a bad line is reported and skipped. Raises ``CadfeatError`` when the
    file is missing or no line parses."""
    from scipy.spatial.transform import Rotation

    path = Path(path)
    if not path.is_file():
        raise CadfeatError(f"--poses: {path} not found; allowed: a CSV of time_s,x_mm,y_mm,z_mm,qx,qy,qz,qw per image")
    times, poses, lines, rows, problems = [], [], [], [], []
    row = -1
    for number, raw in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), start=1):
        text = raw.strip()
        if not text or text.startswith("#") or (row < 0 and re.match(r"^[A-Za-z_\"]", text)):
            continue  # blank, comment, header
        row += 1
        values = _numbers(text)
        why = _line_problem(values)
        if why is None:
            T = np.eye(4)
            if len(values) == QUATERNION_LINE:  # type: ignore[arg-type]
                q = np.asarray(values[4:8])  # type: ignore[index]
                T[:3, :3] = Rotation.from_quat(q / np.linalg.norm(q)).as_matrix()
                T[:3, 3] = values[1:4]  # type: ignore[index]
            else:
                T[:3, :] = np.reshape(values[1:], (3, 4))  # type: ignore[index]
                why = _rotation_problem(T[:3, :3])
            if why is None:
                times.append(values[0])  # type: ignore[index]
                poses.append(T)
                lines.append(number)
                rows.append(row)
                continue
        problems.append(f"{path.name} line {number} (pose row {row}): {why}; skipped")
    if not poses:
        raise CadfeatError(f"--poses: {path}: no line parses" + (f" ({problems[0]})" if problems else "") +
                           "; allowed: time_s then x,y,z mm and qx,qy,qz,qw, or time_s and a 3x4 matrix row by row")
    if np.any(np.diff(times) <= 0):
        k = int(np.argmax(np.diff(times) <= 0))
        raise CadfeatError(f"--poses: {path} line {lines[k + 1]}: time {times[k + 1]} s does not increase (line "
                           f"{lines[k]}: {times[k]} s); allowed: strictly increasing times, one line per image")
    return ReportedPoses(np.asarray(times, float), np.stack(poses), lines, rows, problems)


def _numbers(text: str) -> list[float] | str:
    try:
        values = [float(v) for v in re.split(r"[,;\s]+", text) if v]
    except ValueError as exc:
        return f"not numbers ({exc})"
    return values


def _line_problem(values: list[float] | str) -> str | None:
    if isinstance(values, str):
        return values
    if len(values) not in (QUATERNION_LINE, MATRIX_LINE):
        return (f"{len(values)} numbers; allowed: {QUATERNION_LINE} (time_s, x, y, z mm, qx, qy, qz, qw) or "
                f"{MATRIX_LINE} (time_s and a 3x4 pose row by row)")
    if not np.all(np.isfinite(values)):
        return "a number is not finite"
    if len(values) == QUATERNION_LINE and abs(np.linalg.norm(values[4:8]) - 1.0) > QUATERNION_NORM_TOL:
        return f"quaternion norm {np.linalg.norm(values[4:8]):.4g}; allowed: a unit quaternion (qx, qy, qz, qw)"
    return None


def _rotation_problem(R: np.ndarray) -> str | None:
    if np.max(np.abs(R @ R.T - np.eye(3))) > 1e-3 or np.linalg.det(R) < 0:
        return "the 3x3 part is not a rotation (R Rᵀ ≠ I or det < 0)"
    return None


def read_hand_eye(path: str | Path) -> np.ndarray:
    """T_flange_cam (4, 4) mm from an OpenCV FileStorage file: node ``T`` (or ``T_flange_cam``), 4x4 or 3x4."""
    import cv2

    path = Path(path)
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ) if path.is_file() else None
    if fs is None or not fs.isOpened():
        raise CadfeatError(f"--hand-eye: {path} is not a readable OpenCV FileStorage file; allowed: a YAML with a "
                           "4x4 matrix node T (T_flange_cam, mm)")
    try:
        for key in ("T", "T_flange_cam", "hand_eye"):
            node = fs.getNode(key)
            if not node.empty():
                M = np.asarray(node.mat(), float)
                break
        else:
            M = None
    finally:
        fs.release()
    if M is None or M.shape not in ((4, 4), (3, 4)) or _rotation_problem(M[:3, :3]) is not None:
        raise CadfeatError(f"--hand-eye: {path}: needs a 4x4 (or 3x4) rigid transform under node T; allowed: "
                           "T_flange_cam with a rotation block, mm")
    T = np.eye(4)
    T[:3, :] = M[:3, :]
    return T


def match_images(folder: str | Path, rows: Sequence[int]) -> tuple[list[Path | None], list[str]]:
    """Per parsed pose (its data row in ``rows``) its image file in ``folder`` (None when missing) and the problems:
    images whose name has no number or whose row has no parsed pose, a row given twice; poses without an image."""
    folder = Path(folder)
    if not folder.is_dir():
        raise CadfeatError(f"--images: {folder} is not a folder; allowed: a folder of frame_NNNN images")
    index = {row: i for i, row in enumerate(rows)}
    per_pose: list[Path | None] = [None] * len(rows)
    problems = []
    for p in sorted(f for f in folder.iterdir() if f.is_file()):
        if p.suffix.lower() not in IMAGE_SUFFIXES:
            continue
        found = re.findall(r"\d+", p.stem)
        i = index.get(int(found[-1])) if found else None
        if i is None:
            why = f"no parsed pose in row {int(found[-1])}" if found else "no number in the name"
            problems.append(f"{p.name}: unmatched ({why}); skipped")
        elif (other := per_pose[i]) is not None:
            problems.append(f"{p.name}: unmatched (row {rows[i]} already has {other.name}); skipped")
        else:
            per_pose[i] = p
    problems += [f"pose row {rows[i]}: no image (missing frame)" for i in range(len(rows)) if per_pose[i] is None]
    return per_pose, problems


@dataclass
class Replay:
    """A replayed sequence: ``pixels`` (F, N, 2) associated hole centres (NaN = not found), ``expected`` (F, N)
    holes predicted visible, ``used`` (F,) frames with an image, per estimator ``T_est`` (F, 4, 4), ``errors``
    (trans mm (F,), rot deg (F,)) against the reference, ``nees`` (F,) with the reference's assumed covariance added
    and ``nees_filter`` (F,) with the filter's alone (the reference taken as exact), and ``problems``."""

    pixels: np.ndarray
    expected: np.ndarray
    used: np.ndarray
    T_est: dict[str, np.ndarray]
    errors: dict[str, tuple[np.ndarray, np.ndarray]]
    nees: dict[str, np.ndarray]
    nees_filter: dict[str, np.ndarray]
    problems: list[str]

    @property
    def detection_rate(self) -> np.ndarray:
        """(N,) detected / expected over the frames with an image (NaN for a hole never expected)."""
        found = np.all(np.isfinite(self.pixels), axis=-1) & self.expected & self.used[:, None]
        n_exp = (self.expected & self.used[:, None]).sum(axis=0)
        return np.where(n_exp > 0, found.sum(axis=0) / np.maximum(n_exp, 1), np.nan)


def predicted_rims(camera: Camera, T_cam_part: np.ndarray, centres: np.ndarray, normals: np.ndarray,
                   radii: np.ndarray) -> tuple[list[Ellipse], np.ndarray]:
    """Per frame the holes' rim ellipses at the poses (F, 4, 4), and (F, N) which are expected in the image (valid,
    facing the camera, inside with a margin of half the major axis, minor axis >= 3 px, as the closed loop)."""
    c = np.einsum("fij,nj->fni", T_cam_part[:, :3, :3], centres) + T_cam_part[:, None, :3, 3]
    n = np.einsum("fij,nj->fni", T_cam_part[:, :3, :3], normals)
    ell = hole_ellipse(camera, c, n, radii)
    per = [Ellipse(ell.centre_px[k], ell.axes_px[k], ell.angle_rad[k], ell.valid[k]) for k in range(len(c))]
    half = np.asarray(ell.axes_px)[..., 0] / 2
    u, v = np.asarray(ell.centre_px)[..., 0], np.asarray(ell.centre_px)[..., 1]
    inside = (u > half) & (v > half) & (u < camera.width - half) & (v < camera.height - half)
    facing = np.einsum("fni,fni->fn", n, c) < 0
    expected = np.asarray(ell.valid) & inside & facing & (np.asarray(ell.axes_px)[..., 1] >= 3.0)
    return per, expected


def detect_frames(camera: Camera, images: Sequence[Path | None], predicted: Sequence[Ellipse], detector: str,
                  gate_px: float) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Pixels (F, N, 2) of the holes in each image (NaN where none), which frames had a usable image, problems."""
    F_, N = len(images), len(np.asarray(predicted[0].centre_px)) if predicted else 0
    pixels = np.full((F_, N, 2), np.nan)
    used = np.zeros(F_, bool)
    problems = []
    for k, path in enumerate(images):
        if path is None:
            continue
        try:
            grey = read_grey(path)
        except ImageFileError as exc:
            problems.append(f"{path.name}: {exc.reason}; skipped")
            continue
        if grey.shape != (camera.height, camera.width):
            problems.append(f"{path.name}: {grey.shape[1]}x{grey.shape[0]} px, the camera is {camera.width}x"
                            f"{camera.height}; skipped")
            continue
        used[k] = True
        dets = detect(detector, grey, camera=camera, predicted=predicted[k])
        pixels[k] = associate(predicted[k], dets, gate_px)
    return pixels, used, problems


def nees(T_est: np.ndarray, P: np.ndarray, T_ref: np.ndarray, ref_cov: np.ndarray) -> np.ndarray:
    """(F,) normalised estimation error squared of (δp mm, δθ rad) = (p_est − p_ref, log(R_est R_refᵀ)) with the
    filter's pose covariance P (F, 6, 6) plus the reference's ``ref_cov`` (6, 6); NaN where no estimate."""
    dR = np.where(np.isfinite(T_est[:, :3, :3]), T_est[:, :3, :3], np.eye(3)) @ np.swapaxes(T_ref[:, :3, :3], -1, -2)
    e = np.concatenate([T_est[:, :3, 3] - T_ref[:, :3, 3], so3_log(dR)], axis=-1)
    S = P[:, :6, :6] + ref_cov
    ok = np.all(np.isfinite(e), axis=-1) & np.all(np.isfinite(S.reshape(len(S), -1)), axis=-1)
    out = np.full(len(e), np.nan)
    if ok.any():
        out[ok] = np.einsum("fi,fi->f", e[ok], np.linalg.solve(S[ok], e[ok][..., None])[..., 0])
    return out


def replay(camera: Camera, centres: np.ndarray, normals: np.ndarray, radii: np.ndarray, T_ref: np.ndarray,
           times_s: np.ndarray, images: Sequence[Path | None], *, detector: str = "cadfeat", gate_px: float = 8.0,
           estimators: Sequence[str] = ("ekf", "iekf", "pnp"), tuning: FilterTuning | None = None,
           ref_cov: np.ndarray | None = None, rim_model: bool = True, exclude: np.ndarray | None = None) -> Replay:
    """Detect and track a recorded sequence (module docstring). ``T_ref`` (F, 4, 4) the reference T_cam_part from
    the reported poses; ``images`` one path (or None) per frame; ``ref_cov`` (6, 6) the reference's assumed
    covariance (mm², rad²; default 0); ``exclude`` (F, N) holes never associated (as the closed loop: a rim the part
    hides, or one too close to another rim, at the reference pose)."""
    predicted, expected = predicted_rims(camera, T_ref, centres, normals, radii)
    pixels, used, problems = detect_frames(camera, images, predicted, detector, gate_px)
    if exclude is not None:
        pixels[exclude] = np.nan
        expected = expected & ~exclude
    frames = np.flatnonzero(used)
    if len(frames) < 2:
        raise CadfeatError(f"--images: {len(frames)} usable image(s) matched to poses; needs >= 2 "
                           f"({'; '.join(problems)})")
    ref_cov = np.zeros((6, 6)) if ref_cov is None else ref_cov
    T_est, errors, nees_out, nees_filter = {}, {}, {}, {}
    for m in estimators:
        track = estimate_poses(camera, centres, pixels[frames], times_s[frames], m, T_ref[frames[0]],
                               normals_part=normals if rim_model else None, radii_mm=radii if rim_model else None,
                               tuning=tuning)
        T_full = np.full((len(T_ref), 4, 4), np.nan)
        T_full[frames] = track.T_cam_part
        T_est[m] = T_full
        errors[m] = pose_errors(T_full, T_ref)
        cov = np.full((len(T_ref), 6, 6), np.nan)
        cov[frames] = track.pose_covariance
        nees_out[m] = nees(T_full, cov, T_ref, ref_cov)
        nees_filter[m] = nees(T_full, cov, T_ref, np.zeros((6, 6)))
    return Replay(pixels, expected, used, T_est, errors, nees_out, nees_filter, problems)
