"""Stable hole names: a part script's own names, else names tied to the physical hole (matched to the default
build by geometry), the same in the listing, results.json and the per-feature tables."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
from study_helpers import write_toml

from cadfeat.cad.parts import load_part
from cadfeat.study.run import evaluate_study

ROOT = Path(__file__).resolve().parents[2]
TWO_HOLES = '''
PARAMETERS = {"a_x": {"default": -10.0, "bounds": (-20.0, 20.0), "unit": "mm", "description": "x of hole A"}}
VIEW_DIRECTION = (0.0, 0.0, 1.0)


def build(a_x=-10.0):
    import cadquery as cq

    plate = cq.Workplane("XY").box(60.0, 40.0, 5.0, centered=(True, True, False))
    return plate.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0)) \\
        .pushPoints([(a_x, 0.0), (0.0, 10.0)]).hole(3.0)
'''
NAMED = TWO_HOLES + '''

def expected_holes(a_x):
    return [{"centre": (0.0, 10.0, 5.0), "axis": (0, 0, 1), "radius_mm": 1.5, "name": "fiducial", "fixed": True},
            {"centre": (a_x, 0.0, 5.0), "axis": (0, 0, 1), "radius_mm": 1.5, "name": "window"}]
'''


def _part(tmp_path: Path, text: str, name: str) -> Path:
    path = tmp_path / f"{name}.py"
    path.write_text(text)
    return path


def test_a_hole_keeps_its_name_when_a_parameter_reorders_the_extraction(tmp_path):
    part = load_part(_part(tmp_path, TWO_HOLES, "two"))
    before = {h.name: np.asarray(h.centre) for h in part.holes()}
    after = {h.name: np.asarray(h.centre) for h in part.holes(a_x=10.0)}  # hole A now right of hole B
    assert set(before) == set(after) == {"H1", "H2"}
    a = next(n for n, c in before.items() if c[1] == 0.0)  # hole A: the one on y = 0
    b = next(n for n in before if n != a)
    np.testing.assert_allclose(after[a], [10.0, 0.0, 5.0], atol=1e-9)
    np.testing.assert_allclose(after[b], before[b], atol=1e-9)


def test_the_scripts_own_names_are_used_everywhere(tmp_path):
    path = _part(tmp_path, NAMED, "named")
    part = load_part(path)
    for a_x in (-10.0, 10.0):
        names = {h.name: tuple(np.round(h.centre, 6)) for h in part.holes(a_x=a_x)}
        assert names == {"fiducial": (0.0, 10.0, 5.0), "window": (a_x, 0.0, 5.0)}
    study = write_toml(tmp_path / "named.toml", {
        "study": {"name": "named", "part": str(path), "seed": 0},
        "camera": {"preset": "basler-aca1300-200um-8mm", "focus_distance_mm": 200.0},
        "trajectory": {"kind": "straight_approach", "start": [0, 0, 260], "end": [0, 0, 160], "target": [0, 0, 0],
                       "n": 6},
        "design": {"parameters": {"a_x": {}}},
        "objective": {"measures": ["fov", "resolution"], "combine": "maxmin"}})
    results = evaluate_study(study)
    holes = [h["name"] for h in results["holes"]["before"]]
    assert sorted(holes) == ["fiducial", "window"]
    assert [f["name"] for f in results["measures"]["before"]["per_feature"]] == holes
    assert results["objectives"]["score"] == "objective.score = movable: window"
    listing = subprocess.run([sys.executable, "-m", "cadfeat", "parts", str(path), "--holes"], capture_output=True,
                             text=True, cwd=ROOT, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"}, timeout=120)
    assert listing.returncode == 0, listing.stderr
    assert "    fiducial: centre" in listing.stdout and "    window: centre" in listing.stdout
