"""``cadfeat render``: part scripts and STEP files to a PNG, with clear errors for bad input."""

from __future__ import annotations

import textwrap

import cv2
import pytest

cq = pytest.importorskip("cadquery")

from cadfeat.cad.export import export_step  # noqa: E402
from cadfeat.cli import main  # noqa: E402

SCRIPT = textwrap.dedent('''
    import cadquery as cq

    PARAMETERS = {
        "diameter": {"default": 8.0, "bounds": (2.0, 20.0), "unit": "mm", "description": "hole diameter"},
        "n_holes": {"default": 2, "bounds": (1, 4), "unit": "", "description": "holes along x"},
    }
    VIEW_DIRECTION = (0.3, -0.4, 1.0)


    def build(diameter=8.0, n_holes=2):
        pts = [(-30.0 + 60.0 * i / max(n_holes - 1, 1), 0.0) for i in range(n_holes)]
        return cq.Workplane("XY").box(80, 40, 5).faces(">Z").workplane().pushPoints(pts).hole(diameter)
''')


def _dark_blobs(path) -> int:
    grey = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    n, _, stats, _ = cv2.connectedComponentsWithStats((grey < 60).astype("uint8"))
    return int((stats[1:, cv2.CC_STAT_AREA] > 30).sum())


def test_render_part_script_with_params(tmp_path, capsys):
    script = tmp_path / "plate.py"
    script.write_text(SCRIPT)
    out = tmp_path / "pic.png"
    assert main(["render", str(script), "--param", "n_holes=3", "--param", "diameter=10",
                 "--out", str(out), "--size", "400x300"]) == 0
    assert capsys.readouterr().out.strip() == str(out)
    img = cv2.imread(str(out))
    assert img.shape == (300, 400, 3) and img.std() > 10
    assert _dark_blobs(out) == 3  # three holes, seen from VIEW_DIRECTION: the dark far walls


def test_render_step_file(tmp_path, capsys):
    step = export_step(cq.Workplane("XY").box(50, 50, 8).faces(">Z").workplane().hole(12).val(), tmp_path / "p.step")
    out = tmp_path / "step.png"
    assert main(["render", str(step), "--out", str(out), "--view", "0.3,-0.4,1", "--size", "320x240"]) == 0
    assert capsys.readouterr().out.strip() == str(out)
    assert _dark_blobs(out) == 1


@pytest.mark.parametrize("args, message", [
    (["--param", "width=3"], "width"),
    (["--param", "diameter"], "NAME=VALUE"),
    (["--view", "1,2"], "--view"),
    (["--out", "x.jpg"], ".png"),
])
def test_render_bad_input(tmp_path, capsys, args, message):
    script = tmp_path / "plate.py"
    script.write_text(SCRIPT)
    assert main(["render", str(script), *args]) == 2
    assert message in capsys.readouterr().err


def test_render_missing_file(tmp_path, capsys):
    assert main(["render", str(tmp_path / "nope.py")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_render_library_part_by_name(tmp_path, capsys):
    # `cadfeat render thesis_hub` finds parts/thesis_hub.py; 1 centre hole + 4 bolt-circle holes show dark
    out = tmp_path / "hub.png"
    assert main(["render", "thesis_hub", "--param", "hole_count=4", "--out", str(out), "--size", "400x300",
                 "--view", "0,0,1"]) == 0
    assert capsys.readouterr().out.strip() == str(out)
    assert _dark_blobs(out) >= 5
