"""``cadfeat detect IMAGES…`` on real recordings (``tests/data/visp_images``: ViSP's dot targets, GPL-2, see
``SOURCES.md`` there): one line per image as it goes, a missing or unreadable file reported by name while the rest go
on, the CSV and JSON equal to the detectors' own results, one annotated picture per detected image, and a
calibration applied to cadfeat's centres only (tests/vision/test_real_dot_targets.py checks the detections
themselves against OpenCV)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from cadfeat.camera import Camera, write_opencv_calibration
from cadfeat.cli import main
from cadfeat.cli.detect import picture_names
from cadfeat.vision.detectors import DETECTORS
from cadfeat.vision.image_detection import CSV_COLUMNS, ImageResult, detect_file
from cadfeat.vision.image_files import read_grey

DATA = Path(__file__).parents[1] / "data" / "visp_images"
TARGET = sorted((DATA / "mire-2").glob("image.*.pgm"))
GRID = sorted((DATA / "calibration").glob("grid36-*.pgm"))


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f))


def test_detect_reports_each_image_and_writes_what_it_found(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                           ) -> None:
    garbage = tmp_path / "broken.png"
    garbage.write_bytes(b"not an image")
    missing = tmp_path / "frame_0999.png"
    out = tmp_path / "found"
    assert main(["detect", str(DATA / "mire-2"), str(garbage), str(missing), "--detector", "all", "--holes", "bright",
                 "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    progress = [line for line in lines if line.startswith("  [")]
    assert [line.split("]")[0] for line in progress] == [f"  [{i}/8" for i in range(1, 9)]  # in order, as it goes
    assert "image.0201.pgm (384x288): cadfeat 4, edcircles 6, blob 6 ellipse(s)" in progress[2]
    assert f"{garbage}: not detected: not a readable image" in progress[6]
    assert f"{missing}: not detected: image file not found" in progress[7]
    assert "detect: 6 of 8 images detected" in lines
    assert "  cadfeat: 29 ellipses in 6 images; per image 4-5 (median 5)" in lines

    report = json.loads((out / "detections.json").read_text(encoding="utf-8"))
    assert report["settings"]["holes"] == "bright" and report["settings"]["detectors"] == list(DETECTORS)
    assert [p["image"] for p in report["summary"]["not_detected"]] == [str(garbage), str(missing)]
    rows = _rows(out / "detections.csv")
    assert tuple(rows[0]) == CSV_COLUMNS
    assert len(rows) == sum(sum(img["counts"].values()) for img in report["images"])
    for path, entry in zip(TARGET, report["images"], strict=False):
        truth = detect_file(path, list(DETECTORS), holes="bright").found
        for name in DETECTORS:
            mine = np.array([[float(r[k]) for k in ("u_px", "v_px", "major_px", "minor_px")]
                             for r in rows if r["image"] == str(path) and r["detector"] == name]).reshape(-1, 4)
            want = np.column_stack([truth[name].centre_px, truth[name].axes_px])
            np.testing.assert_allclose(mine, want, atol=6e-5)  # written with 4 decimals
            assert entry["counts"][name] == len(want)
    pictures = sorted(p.name for p in (out / "annotated").iterdir())
    assert pictures == [p.stem + ".png" for p in TARGET]  # none for the files not detected
    picture = cv2.imread(str(out / "annotated" / "image.0101.png"))
    grey = read_grey(TARGET[1])
    assert picture.shape == (*grey.shape, 3)
    untouched = np.all(picture == grey[..., None], axis=-1)
    assert 0.8 < untouched.mean() < 1.0  # the image, with ellipses and labels drawn over it


def test_detect_with_nothing_readable_is_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "gone.png"
    assert main(["detect", str(missing), "--out", str(tmp_path / "out")]) == 2
    assert f"no image could be detected: {missing}: image file not found" in capsys.readouterr().err
    (tmp_path / "empty").mkdir()
    assert main(["detect", str(tmp_path / "empty")]) == 2
    assert "no image files in" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
    (tmp_path / "taken").write_text("")
    assert main(["detect", str(TARGET[0]), "--out", str(tmp_path / "taken")]) == 2
    assert f"--out: {tmp_path / 'taken'} is a file" in capsys.readouterr().err


def test_pictures_of_images_with_one_name_do_not_overwrite_each_other() -> None:
    results = [ImageResult(Path(p)) for p in ("a/frame.png", "b/frame.png", "c/other.pgm", "d/frame.tif")]
    assert picture_names(results) == ["frame.png", "frame_2.png", "other.png", "frame_3.png"]


def test_detect_calibration_moves_cadfeats_centres_only(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """With a lens, cadfeat's centre is the undistorted rim's (a fraction of a px for these 45 px dots), EDCircles'
    and blob's stay their fit in the image; an image of another size than the calibration's is reported."""
    calibration = tmp_path / "camera.yaml"
    write_opencv_calibration(Camera(fx=800, fy=800, cx=320, cy=240, width=640, height=480,
                                    dist=(-0.3, 0.1, 0.0, 0.0, 0.0)), calibration)
    images = [str(GRID[0]), str(TARGET[0])]
    assert main(["detect", *images, "--detector", "all", "--out", str(tmp_path / "plain"), "--no-pictures"]) == 0
    assert main(["detect", *images, "--detector", "all", "--calibration", str(calibration),
                 "--out", str(tmp_path / "lens"), "--no-pictures"]) == 0
    out = capsys.readouterr().out
    assert f"{TARGET[0]}: not detected: the image is 384x288 px, the calibration's camera 640x480 px" in out
    assert not (tmp_path / "lens" / "annotated").exists()
    plain, lens = (_rows(tmp_path / name / "detections.csv") for name in ("plain", "lens"))
    for name in DETECTORS:
        a, b = (np.array([[float(r["u_px"]), float(r["v_px"])] for r in rows
                          if r["detector"] == name and r["image"] == str(GRID[0])]) for rows in (plain, lens))
        shift = np.linalg.norm(a - b, axis=1)
        if name == "cadfeat":
            assert len(a) == 35 and 0.01 < shift.max() < 0.5  # measured 0.19 px at most
        else:
            assert shift.max() == 0.0
