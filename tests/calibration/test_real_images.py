"""``cadfeat calibrate`` on real photographs nobody here made: OpenCV's own calibration sample images
(``tests/data/opencv_left``: ``left01``-``left14``, 640x480, a 9x6 chessboard; see ``SOURCES.md`` there).

The reference is independent of cadfeat's board finding: ``cv2.findChessboardCorners`` + ``cv2.cornerSubPix``
(OpenCV's tutorial settings: 11x11 window) and ``cv2.calibrateCamera`` run here directly, as OpenCV's sample
does (it reports a reprojection RMS of about 0.4 px on these images; measured here 0.409 px). cadfeat finds the
corners with ``findChessboardCornersSB`` and a smaller refinement window (measured RMS 0.325 px); its
intrinsics agree with the reference's to 0.31 % (fx), 0.28 % (fy) and 1.1 px (principal point) — within about
2 of their own standard deviations (0.73-0.85 px) — and its lens model reprojects the reference's own corners
with 0.41 px RMS (the reference's model: 0.409 px). The lens settings given to ``cadfeat calibrate`` are read
back into the ``Camera`` by the file's readers and by a study's ``[camera] calibration``.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from study_helpers import BASE, PLATE, write_toml

from cadfeat.calibration import read_camera
from cadfeat.camera import Camera
from cadfeat.cli import main
from cadfeat.study.preflight import optics_assumptions
from cadfeat.study.schema import load_study

IMAGES = sorted((Path(__file__).parents[1] / "data" / "opencv_left").glob("left*.jpg"))
PATTERN = (9, 6)
SQUARE_MM = 25.0  # OpenCV's sample leaves the size at 1 unit; any size gives the same intrinsics
#: The lens settings given to ``cadfeat calibrate`` (written as optics nodes, read back into the ``Camera``).
LENS = ["--focal-length-mm", "6", "--f-number", "2.8", "--focus-mm", "450"]


def _reference() -> tuple[float, np.ndarray, np.ndarray, list[np.ndarray], np.ndarray]:
    """OpenCV's sample calibration done here: (rms px, K, dist, the corners per image, the board points mm)."""
    board = np.zeros((PATTERN[0] * PATTERN[1], 3), np.float32)
    board[:, :2] = np.mgrid[0:PATTERN[0], 0:PATTERN[1]].T.reshape(-1, 2) * SQUARE_MM
    corners = []
    for path in IMAGES:
        grey = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        found, c = cv2.findChessboardCorners(grey, PATTERN)
        assert found, path.name
        criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.001)
        corners.append(cv2.cornerSubPix(grey, c, (11, 11), (-1, -1), criteria))
    rms, K, dist, _, _ = cv2.calibrateCamera([board] * len(corners), corners, (640, 480), None, None)
    return float(rms), K, dist.ravel(), corners, board


def test_opencv_sample_images_calibrate_like_opencv(tmp_path: Path) -> None:
    assert len(IMAGES) == 13
    out = tmp_path / "camera.yaml"
    assert main(["calibrate", *map(str, IMAGES), "--board", "chessboard", "--inner-corners", "9x6",
                 "--square-mm", str(SQUARE_MM), "--out", str(out), *LENS]) == 0
    report = json.loads((tmp_path / "camera_report.json").read_text())
    assert len(report["views"]) == 13 and report["rejected"] == []
    assert report["rms_px"] < 0.5
    cam = read_camera(out)
    ref_rms, K, dist, corners, board = _reference()
    assert ref_rms < 0.5
    assert abs(cam.fx / K[0, 0] - 1) < 0.005 and abs(cam.fy / K[1, 1] - 1) < 0.005
    assert np.hypot(cam.cx - K[0, 2], cam.cy - K[1, 2]) < 2.0
    # cadfeat's model explains the reference's own corners (each board's pose solved with cadfeat's camera)
    sq = []
    for c in corners:
        ok, r, t = cv2.solvePnP(board, c, cam.K, cam.dist_coeffs)
        r, t = cv2.solvePnPRefineLM(board, c, cam.K, cam.dist_coeffs, r, t)
        assert ok
        proj, _ = cv2.projectPoints(board, r, t, cam.K, cam.dist_coeffs)
        sq.append(np.sum((proj.reshape(-1, 2) - c.reshape(-1, 2)) ** 2, axis=1))
    rms = float(np.sqrt(np.mean(np.concatenate(sq))))
    assert rms < 0.5, f"{rms:.3f} px"
    # the file is what a study's [camera] calibration = ... reads, lens settings included
    (tmp_path / PLATE.name).write_text(PLATE.read_text())
    data = {**BASE, "study": {**BASE["study"], "part": PLATE.name}, "camera": {"calibration": "camera.yaml"}}
    config = load_study(write_toml(tmp_path / "s.toml", data))
    study_cam = config.camera.build()
    assert (study_cam.width, study_cam.height) == (640, 480)
    np.testing.assert_allclose(study_cam.K, cam.K, rtol=1e-12)
    np.testing.assert_allclose(study_cam.dist_coeffs, cam.dist_coeffs, rtol=1e-9, atol=1e-15)
    for c in (cam, study_cam, Camera.from_opencv_file(out)):
        assert (c.focal_length_mm, c.f_number, c.focus_distance_mm) == (6.0, 2.8, 450.0)
        assert c.aperture_mm == pytest.approx(6.0 / 2.8)
    assert optics_assumptions(config.camera.table, study_cam) == []  # none assumed: the file gave them
    # a key of the study's [camera] beside the file wins; an aperture alone recomputes the f-number
    data["camera"] = {"calibration": "camera.yaml", "focus_distance_mm": 300.0, "aperture_mm": 1.5}
    over = load_study(write_toml(tmp_path / "s.toml", data)).camera.build()
    assert (over.focus_distance_mm, over.f_number, over.focal_length_mm) == (300.0, 4.0, 6.0)


@pytest.mark.parametrize("name", ["left01.jpg"])
def test_sources_are_recorded(name: str) -> None:
    folder = IMAGES[0].parent
    sources = (folder / "SOURCES.md").read_text()
    assert name in sources and "Apache" in sources and (folder / "LICENSE").is_file()
