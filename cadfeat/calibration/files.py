"""Calibration files: OpenCV FileStorage YAML (the OpenCV samples' convention) and ROS ``camera_info`` YAML.

``write_opencv`` writes the nodes OpenCV's calibration sample writes — ``image_width``, ``image_height``,
``camera_matrix``, ``distortion_coefficients`` — which ``Camera.from_opencv_file`` (and so a study's
``[camera] calibration = "camera.yaml"``) reads back to the same camera, plus extra nodes: the error analysis
(``avg_reprojection_error`` px, ``per_view_reprojection_errors`` px, ``std_deviations`` in the order of
``solve.PARAMETERS``, ``nr_of_frames``, the board; ignored by the readers) and, when given, the lens's optics
(``focal_length_mm``, ``f_number``, ``focus_distance_mm``), which ``Camera.from_opencv_file`` and a study's
``[camera] calibration`` read into the ``Camera`` (a key of the study's ``[camera]`` beside ``calibration``
wins).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from cadfeat.calibration.solve import PARAMETERS, CalibrationResult
from cadfeat.camera import OPTICS_NODES, Camera, CameraError


def write_opencv(result: CalibrationResult, path: str | Path, optics: dict[str, float] | None = None) -> None:
    """Write the calibration as OpenCV FileStorage (YAML, or XML/JSON by the extension) with the error analysis."""
    import cv2

    cam = result.camera
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    try:
        fs.write("calibration_time", time.strftime("%Y-%m-%d %H:%M:%S"))
        fs.write("image_width", int(cam.width))
        fs.write("image_height", int(cam.height))
        fs.write("camera_matrix", cam.K)
        fs.write("distortion_coefficients", cam.dist_coeffs.reshape(1, 5))
        fs.write("avg_reprojection_error", float(result.rms_px))
        fs.write("nr_of_frames", len(result.views))
        fs.write("per_view_reprojection_errors", np.array([[v.rms_px] for v in result.views]))
        fs.writeComment("std_deviations: 1 sigma of " + ", ".join(PARAMETERS))
        fs.write("std_deviations", np.array([[result.std[p] for p in PARAMETERS]]))
        fs.write("board", result.board.describe())
        fs.write("board_width", int(result.board.cols))
        fs.write("board_height", int(result.board.rows))
        fs.write("square_size", float(result.board.square_mm))
        for key in OPTICS_NODES:
            if (optics or {}).get(key) is not None:
                fs.write(key, float((optics or {})[key]))
    finally:
        fs.release()


def read_camera(path: str | Path, **overrides: Any) -> Camera:
    """A ``Camera`` from an OpenCV or ROS calibration file, with the optics nodes ``write_opencv`` adds (when
    present) and ``overrides`` (``Camera`` fields) over them: ``Camera.from_opencv_file``."""
    return Camera.from_opencv_file(path, **overrides)


def write_ros(camera: Camera, path: str | Path, camera_name: str = "camera") -> None:
    """Write ``camera`` as a ROS ``camera_info`` YAML (``camera_calibration_parsers``' format, plumb_bob model,
    identity rectification, projection P = [K | 0])."""
    P = np.hstack([camera.K, np.zeros((3, 1))])

    def block(name: str, rows: int, cols: int, data: np.ndarray) -> str:
        values = ", ".join(f"{v:.17g}" for v in np.asarray(data, float).ravel())
        return f"{name}:\n  rows: {rows}\n  cols: {cols}\n  data: [{values}]\n"

    text = (f"image_width: {camera.width}\nimage_height: {camera.height}\ncamera_name: {camera_name}\n"
            + block("camera_matrix", 3, 3, camera.K) + "distortion_model: plumb_bob\n"
            + block("distortion_coefficients", 1, 5, camera.dist_coeffs)
            + block("rectification_matrix", 3, 3, np.eye(3)) + block("projection_matrix", 3, 4, P))
    Path(path).write_text(text, encoding="utf-8")


def read_ros(path: str | Path, **overrides: Any) -> Camera:
    """A ``Camera`` from a ROS ``camera_info`` YAML; refuses a distortion model other than plumb_bob by name."""
    import yaml

    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as exc:
        raise CameraError(f"{path}: not a readable ROS camera_info YAML ({exc})", "calibration") from None
    model = (data or {}).get("distortion_model", "plumb_bob") if isinstance(data, dict) else None
    if model != "plumb_bob":
        raise CameraError(f"{path}: distortion_model {model!r} is not allowed; allowed: plumb_bob",
                          "distortion_model", "plumb_bob")
    return Camera.from_opencv_file(path, **overrides)
