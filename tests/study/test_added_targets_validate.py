"""``cadfeat validate`` pre-flights ``[add_targets]`` (issue 31): an allowed face the part does not have, a keep-in
box that meets no allowed face, a drill that is not a shop size, more holes than can fit, no candidate site at all
— each one ``cadfeat: error:`` line naming the study file, the key and what is allowed, exit status 2, before any
work (validate never optimises; ``cadfeat run`` refuses the same in its set-up, test_added_targets_study.py)."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
from study_helpers import STEP, write_toml

from cadfeat.cli import main

pytest.importorskip("cadquery")

#: A small STEP study on tests/data/plate_holes.step (80 x 60 x 10 mm, top face z = 10) with added targets on top.
BASE: dict[str, Any] = {
    "study": {"name": "plate_add", "part": str(STEP), "seed": 2},
    "camera": {"preset": "realsense-d435-rgb", "focus_distance_mm": 220.0},
    "trajectory": {"kind": "orbit_arc", "centre": [0, 0, 10], "radius_mm": 220.0, "elevation_deg": 55.0,
                   "azimuth_start_deg": -150.0, "azimuth_end_deg": -30.0, "n": 12, "duration_s": 2.0},
    "design": {"holes": [{"select": [-25.0, -15.0, 10.0], "max_offset_mm": 6.0}]},
    "constraints": {"edge_distance_mm": 3.0, "ligament_mm": 2.5},
    "objective": {"measures": ["pose"]},
    "add_targets": {"faces": ["+z"], "diameter_mm": 4.5, "depth_mm": 2.5, "max_added": 2, "pitch_mm": 2.0},
}


def _validate(tmp_path: Path, capsys: pytest.CaptureFixture[str], **add: Any) -> tuple[int, str, str, Path]:
    data = copy.deepcopy(BASE)
    data["add_targets"].update(add)
    path = write_toml(tmp_path / "add.toml", data)
    status = main(["validate", str(path)])
    out = capsys.readouterr()
    return status, out.out, out.err, path


def _one_error(status: int, err: str, path: Path, *needles: str) -> str:
    assert status == 2, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("cadfeat: error: "), err
    assert lines[0].startswith(f"cadfeat: error: {path}: add_targets"), lines[0]  # the file, then the key
    assert "allowed: " in lines[0]
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def test_a_valid_section_passes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, out, err, _ = _validate(tmp_path, capsys)
    assert status == 0, err
    assert "ok" in out and "add_targets: " in out and "candidate sites on face" in out
    assert "a dry-run hole drilled and verified" in out


def test_a_face_the_part_does_not_have(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err, path = _validate(tmp_path, capsys, faces=["host:H42"])
    _one_error(status, err, path, "add_targets.faces: 'host:H42': the part has no hole 'H42'",
               "allowed: host:<one of H1, H2, H3, H4, H5>")


def test_a_keepin_box_off_the_faces(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err, path = _validate(tmp_path, capsys, keepin_boxes=[[-40, -30, 20, 40, 30, 30]])
    _one_error(status, err, path, "add_targets.keepin_boxes: [-40.0, -30.0, 20.0, 40.0, 30.0, 30.0] meets none of "
               "the allowed faces", "z 10", "allowed: boxes [xmin, ymin, zmin, xmax, ymax, zmax]")


def test_a_drill_that_is_not_a_shop_size(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err, path = _validate(tmp_path, capsys, diameter_mm=5.0)
    _one_error(status, err, path, "add_targets.diameter_mm: 5 is not a size of the shop's table (iso273-medium)",
               "allowed: 1.8, 2.4", "5.5")


def test_more_holes_than_can_fit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A 10 x 10 mm keep-in corner (x 30..40, y 20..30) leaves rim centres in a 2 x 2.5 mm patch: one Ø4.5 hole
    (two need 4.5 + 2.5 mm between centres), so 2 is refused with the most that can fit."""
    status, _, err, path = _validate(tmp_path, capsys, keepin_boxes=[[30, 20, 0, 40, 30, 10]], max_added=2,
                                     pitch_mm=0.5)
    _one_error(status, err, path, "add_targets.max_added: 2 holes cannot be placed: at most 1 Ø4.5 mm hole(s) fit "
               "on +z at once (25 candidate sites", "allowed: max_added ≤ 1")
    status, _, err, _ = _validate(tmp_path, capsys, keepin_boxes=[[30, 20, 0, 40, 30, 10]], max_added=1,
                                  pitch_mm=0.5)
    assert status == 0, err


def test_no_candidate_site(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err, path = _validate(tmp_path, capsys, keepout_boxes=[[-45, -35, 5, 45, 35, 15]])
    _one_error(status, err, path, "add_targets: no feasible site on +z: every site breaks a requirement",
               "keepout_boxes: 100 % of the sites", "allowed: other faces")


def test_a_keepin_box_is_a_box() -> None:
    from cadfeat.errors import CadfeatError
    from cadfeat.study.settings.add_targets import AddTargetsSettings

    with pytest.raises(CadfeatError, match=r"add_targets\.keepin_boxes: \[1\.0, 0\.0, 0\.0, 0\.0, 1\.0, 1\.0\] is not "
                                           r"allowed; allowed: a list of boxes"):
        AddTargetsSettings(faces=["+z"], keepin_boxes=[[1, 0, 0, 0, 1, 1]])
