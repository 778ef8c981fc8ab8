"""``cadfeat plan-recording``: the poses re-read to the study's trajectory within the printed precision, the board
PDF's page and square size at scale (read from the PDF's own drawing operators), the checklist's steps."""

from __future__ import annotations

import re
import zlib
from pathlib import Path

import numpy as np
import pytest

from cadfeat.cli import main
from cadfeat.study.schema import load_study
from cadfeat.trajectory import read_csv

ROOT = Path(__file__).resolve().parents[2]
STUDY = ROOT / "studies" / "industrial_plate.toml"
PT_PER_MM = 72.0 / 25.4


@pytest.fixture(scope="module")
def plan(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("plan")
    assert main(["plan-recording", str(STUDY), "--out", str(out), "--board", "chessboard", "--inner-corners", "9x6",
                 "--square-mm", "25"]) == 0
    return out


def test_poses_reread_to_the_study(plan: Path) -> None:
    truth = load_study(STUDY).trajectory.build()
    back = read_csv(plan / "poses.csv")
    np.testing.assert_allclose(back.times_s, truth.times_s, atol=5e-7)
    np.testing.assert_allclose(back.T_task_cam[:, :3, 3], truth.T_task_cam[:, :3, 3], atol=5e-7)
    np.testing.assert_allclose(back.T_task_cam[:, :3, :3], truth.T_task_cam[:, :3, :3], atol=5e-6)
    four = np.loadtxt(plan / "poses_4x4.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(four[:, 1:].reshape(-1, 4, 4), truth.T_task_cam, atol=5e-7)


def _pdf_streams(data: bytes) -> list[bytes]:
    out = []
    for m in re.finditer(rb"stream\r?\n(.*?)\r?\nendstream", data, re.S):
        try:
            out.append(zlib.decompress(m.group(1)))
        except zlib.error:
            out.append(m.group(1))
    return out


def test_board_pdf_is_at_scale(plan: Path) -> None:
    data = (plan / "board.pdf").read_bytes()
    box = [float(v) for v in re.search(rb"/MediaBox \[\s*([\d.\s]+)\]", data).group(1).split()]  # type: ignore[union-attr]
    # 10x7 squares of 25 mm (250 x 175 mm) with margins and the footer: not on A4, so A3 portrait
    assert box[2] / PT_PER_MM == pytest.approx(297.0, abs=0.1) and box[3] / PT_PER_MM == pytest.approx(420.0, abs=0.1)
    # the board image is drawn by "w 0 0 ±h x y cm /I.. Do" (unit square scaled to w x h pt): its width over the 10
    # squares is the square size
    placed = [m for s in _pdf_streams(data) for m in re.finditer(
        rb"([-\d.]+)\s+0\s+0\s+([-\d.]+)\s+([-\d.]+)\s+([-\d.]+)\s+cm\s*/I\w+ Do", s)]
    assert len(placed) == 1
    width_mm, height_mm = (abs(float(placed[0].group(i))) / PT_PER_MM for i in (1, 2))
    assert width_mm / 10 == pytest.approx(25.0, abs=0.01) and height_mm / 7 == pytest.approx(25.0, abs=0.01)
    # the 100 mm check line: a horizontal path "x y m X y l" with X - x = 100 mm
    lines = [float(m.group(3)) - float(m.group(1)) for s in _pdf_streams(data) for m in re.finditer(
        rb"([\d.]+) ([\d.]+) m\s+([\d.]+) \2 l", s)]
    assert any(abs(length / PT_PER_MM - 100.0) < 0.01 for length in lines)


def test_checklist_names_each_step(plan: Path) -> None:
    text = (plan / "checklist.md").read_text()
    for step in ("Calibrate the camera", "Hand-eye", "Lighting", "Record", "Replay", "cadfeat calibrate",
                 "--square-mm 25", "cadfeat track", "--images"):
        assert step in text
