"""The recording's inputs (``vision.replay``): the poses CSV in both forms, its bad lines, the hand-eye file, and
image matching by the number in the name; grey conversion of 16-bit and colour images (``vision.image_files``)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cadfeat.errors import CadfeatError
from cadfeat.vision.image_files import expand_image_paths, image_files, read_grey
from cadfeat.vision.replay import match_images, read_hand_eye, read_reported_poses


def test_quaternion_and_matrix_lines_give_the_same_pose(tmp_path: Path) -> None:
    R = Rotation.from_rotvec([0.1, -0.4, 0.3])
    q, M = R.as_quat(), R.as_matrix()
    t = [10.0, -20.5, 300.25]
    csv = tmp_path / "p.csv"
    csv.write_text("time_s,x_mm,y_mm,z_mm,qx,qy,qz,qw\n# a comment\n\n"
                   f"0.0,{t[0]},{t[1]},{t[2]},{q[0]},{q[1]},{q[2]},{q[3]}\n"
                   "0.1 " + " ".join(f"{v:.17g}" for v in np.column_stack([M, t]).ravel()) + "\n"
                   "0.2,1,2,3,0,0,0,2\n0.3,1,2\n")
    poses = read_reported_poses(csv)
    np.testing.assert_allclose(poses.T[0], poses.T[1], atol=1e-12)
    np.testing.assert_allclose(poses.T[0][:3, 3], t)
    assert poses.rows == [0, 1] and poses.lines == [4, 5]
    assert "p.csv line 6 (pose row 2): quaternion norm 2" in poses.problems[0]
    assert "p.csv line 7 (pose row 3): 3 numbers; allowed: 8" in poses.problems[1]
    csv.write_text("0.2,1,2,3,0,0,0,1\n0.1,1,2,3,0,0,0,1\n")
    with pytest.raises(CadfeatError, match="line 2: time 0.1 s does not increase"):
        read_reported_poses(csv)
    with pytest.raises(CadfeatError, match="not found"):
        read_reported_poses(tmp_path / "none.csv")


def test_hand_eye_file(tmp_path: Path) -> None:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec([0.0, 0.0, np.pi / 2]).as_matrix()
    T[:3, 3] = [0.0, 50.0, 80.0]
    fs = cv2.FileStorage(str(tmp_path / "T.yaml"), cv2.FILE_STORAGE_WRITE)
    fs.write("T", T)
    fs.release()
    np.testing.assert_allclose(read_hand_eye(tmp_path / "T.yaml"), T)
    fs = cv2.FileStorage(str(tmp_path / "bad.yaml"), cv2.FILE_STORAGE_WRITE)
    fs.write("T", 2 * T)
    fs.release()
    with pytest.raises(CadfeatError, match="--hand-eye: .*bad.yaml: needs a 4x4"):
        read_hand_eye(tmp_path / "bad.yaml")


def test_images_match_rows_by_the_number_in_their_name(tmp_path: Path) -> None:
    for name in ("cam_0000.png", "cam_0002.tif", "cam_0003.jpg", "cam_0009.png", "notes.txt"):
        (tmp_path / name).write_bytes(b"")
    files, problems = match_images(tmp_path, [0, 1, 3])
    assert [f.name if f else None for f in files] == ["cam_0000.png", None, "cam_0003.jpg"]
    assert any("cam_0002.tif: unmatched (no parsed pose in row 2)" in p for p in problems)
    assert any("cam_0009.png: unmatched" in p for p in problems)
    assert "pose row 1: no image (missing frame)" in problems


def test_sixteen_bit_and_colour_images_read_as_grey(tmp_path: Path) -> None:
    grey = np.random.default_rng(0).integers(0, 256, (20, 30)).astype(np.uint8)
    cv2.imwrite(str(tmp_path / "a.png"), grey.astype(np.uint16) * 257)
    cv2.imwrite(str(tmp_path / "b.tiff"), cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR))
    cv2.imwrite(str(tmp_path / "c.pgm"), grey)                        # netpbm, as ViSP and many grabbers record
    cv2.imwrite(str(tmp_path / "d.pgm"), grey.astype(np.uint16) * 257)
    for name in ("a.png", "b.tiff", "c.pgm", "d.pgm"):
        np.testing.assert_array_equal(read_grey(tmp_path / name), grey)
    assert [p.name for p in image_files(tmp_path)] == ["a.png", "b.tiff", "c.pgm", "d.pgm"]


def test_command_line_images_expand_folders_and_keep_missing_names(tmp_path: Path) -> None:
    """A folder stands for its images sorted by name; a missing name is kept (the command reports it)."""
    for name in ("b.pgm", "a.png", "notes.txt"):
        (tmp_path / name).write_bytes(b"")
    missing = tmp_path / "gone.png"
    assert expand_image_paths([missing, tmp_path]) == [missing, tmp_path / "a.png", tmp_path / "b.pgm"]
