"""Hole patterns (cadfeat.design.patterns) on the flange and hub parts, against the dimensions their scripts
state (EN 1092-1 DN50 PN16: 4 × Ø18 on the 125 mm bolt circle; 5 × 100 wheel studs; the hub's targets on a
61 mm circle), and a STEP study that keeps a bolt circle by pinning the one movable bolt."""

from __future__ import annotations

import copy
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from cadfeat.cad.parts import load_part
from cadfeat.design.patterns import check_patterns, find_patterns

PARTS = Path(__file__).resolve().parents[2] / "parts"


def _holes(name: str, **params):
    part = load_part(PARTS / name)
    return part.holes(**params) if params else part.holes()


def _rotate_z(holes, idx, angle):
    R = np.array([[math.cos(angle), -math.sin(angle), 0], [math.sin(angle), math.cos(angle), 0], [0, 0, 1]])
    return [dataclasses.replace(h, centre=R @ h.centre) if i in idx else h for i, h in enumerate(holes)]


def test_flange_bolt_circle_and_target_pair():
    holes = _holes("pipe_flange_dn50.py")
    pats = find_patterns(holes)
    circles = [p for p in pats if p.kind == "bolt_circle"]
    assert len(circles) == 1
    bc = circles[0]
    assert bc.params["radius_mm"] == pytest.approx(125.0 / 2, abs=1e-6) and bc.params["count"] == 4
    assert all(holes[i].radius_mm == pytest.approx(9.0) for i in bc.holes)  # Ø18 bolt holes
    angles = sorted(math.degrees(math.atan2(holes[i].centre[1], holes[i].centre[0])) % 360 for i in bc.holes)
    assert angles == pytest.approx([45, 135, 225, 315], abs=1e-6)
    (pair,) = [p for p in pats if p.kind == "opposite"]  # the two targets, diametrically opposite
    assert all(holes[i].radius_mm == pytest.approx(3.0) for i in pair.holes)
    # the case: one bolt 6 mm off the circle is a broken pattern; the circle turned as a whole is kept
    bolt = bc.holes[0]
    moved = [dataclasses.replace(h, centre=h.centre + [6.0, 0, 0]) if i == bolt else h for i, h in enumerate(holes)]
    (res,) = [r for r in check_patterns(pats, moved) if r["kind"] == "bolt_circle"]
    assert res["broken"] and "off the circle" in res["why"]
    turned = _rotate_z(holes, set(bc.holes), math.radians(10))
    assert not any(r["broken"] for r in check_patterns(pats, turned))


def test_hub_stud_circle_and_targets_follow_the_parameters():
    holes = _holes("brake_disc_hub.py")
    circles = sorted((p for p in find_patterns(holes) if p.kind == "bolt_circle"), key=lambda p: p.params["radius_mm"])
    assert [p.params["count"] for p in circles] == [5, 3]
    assert circles[0].params["radius_mm"] == pytest.approx(50.0, abs=1e-6)  # 5 × 100 wheel pattern
    assert all(2 * holes[i].radius_mm == pytest.approx(13.0) for i in circles[0].holes)
    assert circles[1].params["radius_mm"] == pytest.approx(61.0, abs=1e-6)  # target_circle_radius_mm default
    # the hub rebuilt with the target circle turned and enlarged: same hole order, patterns kept
    other = _holes("brake_disc_hub.py", target_phase_rad=0.3, target_circle_radius_mm=63.0)
    assert len(other) == len(holes)
    from cadfeat.cad.features import match_holes

    studs = [holes[i] for i in circles[0].holes]
    idx = match_holes(studs, other, tol_mm=1e-6)  # the fixed studs did not move
    assert len(set(idx)) == 5
    pats = find_patterns(other)
    assert sorted(p.params["radius_mm"] for p in pats if p.kind == "bolt_circle") == pytest.approx([50.0, 63.0])


def test_step_study_keeps_a_bolt_circle(tmp_path):
    """A STEP flange where only one bolt is movable: with keep_patterns (default) the bolt is pinned (±1 µm),
    with keep_patterns = false it may move its max_offset_mm."""
    from cadfeat.cad.export import export_step
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_step

    part = load_part(PARTS / "pipe_flange_dn50.py")
    step = export_step(part.build(), tmp_path / "flange.step")
    holes = part.holes()
    bolt = next(h for h in holes if h.radius_mm == pytest.approx(9.0))
    data = {"study": {"name": "flange_step", "part": str(step), "seed": 1},
            "camera": {"preset": "realsense-d435-rgb"},
            "trajectory": {"kind": "straight_approach", "start": [0, -100, 400], "end": [0, 100, 400],
                           "target": [0, 0, 18], "n": 6},
            "design": {"holes": [{"select": [float(v) for v in bolt.centre], "max_offset_mm": 6.0}]},
            "objective": {"measures": ["fov", "resolvability"]}}
    kept = setup_step(load_study(copy.deepcopy(data)))
    bounds = [(v.lower, v.upper) for v in kept.space.variables]
    assert bounds and all(lo >= -1e-3 - 1e-12 and hi <= 1e-3 + 1e-12 for lo, hi in bounds)
    data["shop"] = {"keep_patterns": False}
    free = setup_step(load_study(data))
    assert all(lo == pytest.approx(-6.0) and hi == pytest.approx(6.0) for lo, hi in
               ((v.lower, v.upper) for v in free.space.variables))
