"""Issue 32.2: a through hole keeps its identity and its entrance (the end the camera sees) in set-up, rebuild,
verification, ``score_design`` and the re-imported STEP.

tests/data/cqgi/dowel_plate.py is a user's cq-editor script: a 6 mm plate (top edges broken by a 0.5 mm
chamfer, so the bottom face is the larger one) with two functional dowel through holes and a blind target hole
that moves; dowel_study.toml looks from above. References: the script's own constants (the dowel holes at
(-30, ±15) on the top face z = thickness / 2 = 3 mm, axis +z towards the camera; the target hole at
(target_x, target_y, 3)).
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest

from cadfeat.cad.features import Hole, extract_holes
from cadfeat.cad.features.identity import pair_holes
from cadfeat.errors import CadfeatError

DATA = Path(__file__).parents[1] / "data" / "cqgi"
STUDY = DATA / "dowel_study.toml"
TOP = 3.0                               # thickness / 2: the top face, the side the camera sees
DOWELS = {(-30.0, -15.0), (-30.0, 15.0)}  # pushPoints of the dowel holes


def _dowels(holes: list[dict] | list[Hole]) -> list[tuple[np.ndarray, np.ndarray]]:
    """(centre, axis) of the two 2.75 mm dowel holes among ``holes`` (Hole objects or results.json entries)."""
    out = []
    for h in holes:
        c, a, r = (np.asarray(h.centre), np.asarray(h.axis), h.radius_mm) if isinstance(h, Hole) else \
            (np.asarray(h["centre_mm"]), np.asarray(h["axis"]), h["radius_mm"])
        if abs(r - 2.75) < 1e-6:
            out.append((c, a))
    assert len(out) == 2
    return out


def _on_top(holes: list[dict] | list[Hole]) -> None:
    dowels = _dowels(holes)
    assert {(round(float(c[0]), 6), round(float(c[1]), 6)) for c, _ in dowels} == DOWELS
    for c, a in dowels:
        assert c[2] == pytest.approx(TOP, abs=1e-9)
        np.testing.assert_allclose(a, [0.0, 0.0, 1.0], atol=1e-9)


def test_the_plain_rule_would_enter_from_below():
    """The premise: without a view, extraction calls the larger (bottom) face the dowel holes' entrance."""
    from cadfeat.cad.parts import load_part

    shape = load_part(DATA / "dowel_plate.py").build()
    assert all(c[2] == pytest.approx(-TOP) for c, _ in _dowels(extract_holes(shape)))
    _on_top(extract_holes(shape, prefer_direction=(0.0, 0.0, 1.0)))


def test_set_up_and_score_design_enter_on_the_camera_side():
    """Set-up, the rebuild at the study's start and at a moved design: the dowel holes enter at the top, and
    every kept requirement holds (fixed holes unmoved)."""
    from cadfeat.study.designs import score_design
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_study

    setup = setup_study(load_study(STUDY))
    _on_top(setup.holes0)
    assert setup.view_direction is not None and setup.view_direction[2] > 0.9
    start = score_design(STUDY)
    assert start["requirements_hold"], [c for c in start["requirements"] if not c["ok"]]
    _on_top(start["holes"])
    moved = score_design(STUDY, {"target_x": 22.0, "target_y": -6.0})
    assert moved["requirements_hold"]
    _on_top(moved["holes"])
    target = [h for h in moved["holes"] if abs(h["radius_mm"] - 4.0) < 1e-6]
    np.testing.assert_allclose(target[0]["centre_mm"], [22.0, -6.0, TOP], atol=1e-6)


def test_a_run_keeps_the_fixed_holes_and_their_entrance(tmp_path, monkeypatch):
    """``cadfeat run``: no kept requirement violated (B-rep and re-imported STEP), the dowel holes at the top
    before and after."""
    from cadfeat.study import run as study_mod

    monkeypatch.setattr(study_mod, "_report", lambda *a, **k: None)  # the report is tested elsewhere
    config = tmp_path / "s.toml"
    config.write_text(STUDY.read_text().replace('part = "', f'part = "{DATA}/'))
    with contextlib.redirect_stdout(io.StringIO()):
        study_mod.run_study(config, tmp_path / "out", quiet=True, progress=False)
    results = json.loads((tmp_path / "out" / "results.json").read_text())
    fixed = [c for c in results["constraints"] if c["name"] == "fixed"]
    assert len(fixed) == 4 and all(c["ok"] and c["value"] <= 1e-6 for c in fixed)
    _on_top(results["holes"]["before"])
    _on_top(results["holes"]["after"])


def _hole(centre, axis, radius=2.75) -> Hole:
    return Hole(centre=np.asarray(centre, float), axis=np.asarray(axis, float), radius_mm=radius,
                bore_radius_mm=radius, depth_mm=6.0, through=True, kind="plain", host_face=0, outline=None)


def test_pairing_by_axis_line_and_radius():
    """A through hole reported from its other end pairs with itself (axis line, radius), never with another
    hole on another line or of another radius."""
    ref = [_hole((-30, 15, 3), (0, 0, 1)), _hole((-30, -15, 3), (0, 0, 1))]
    flipped = [_hole((-30, -15, -3), (0, 0, -1)), _hole((-30, 15, -3), (0, 0, -1))]
    assert pair_holes(ref, flipped, 0.5, along_axis=True).tolist() == [1, 0]
    with pytest.raises(CadfeatError, match="axis line and radius"):
        pair_holes(ref, [_hole((-30, 15, -3), (0, 0, -1), 3.5), flipped[0]], 0.5, along_axis=True)
    with pytest.raises(CadfeatError, match="axis line and radius"):
        pair_holes(ref, [_hole((-29, 15, -3), (0, 0, -1)), flipped[0]], 0.5, along_axis=True)


def test_parts_listing_enters_on_the_given_view(capsys):
    """``cadfeat parts SCRIPT --holes --view 0,0,1`` lists the holes as a study seen from above extracts them."""
    from cadfeat.cli import main

    assert main(["parts", str(DATA / "dowel_plate.py"), "--holes", "--view", "0,0,1"]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if "r 2.750 mm" in ln]
    assert len(lines) == 2 and all("3.000) mm, axis (0.000, 0.000, 1.000)" in ln for ln in lines)
    assert {ln.split("centre (")[1].split(", 3.000")[0] for ln in lines} == {"-30.000, -15.000", "-30.000, 15.000"}
