"""Report section "How well will the robot know the part's pose?" (``cadfeat.report.pose``) on the plate case of
tests/report_fixture.py with a ``pose_accuracy`` block computed by ``cadfeat.study.pose_accuracy`` on its real
re-extracted holes. Independent references: the page read back with html.parser against the results dict; the PNG
decoded with Pillow (pixel variance); the closed-loop ratio recomputed from the numbers put in."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from PIL import Image
from report_fixture import shared_case
from report_html import parse_report

from cadfeat.poses import invert_T
from cadfeat.report import build_report
from cadfeat.report.pose import pose_section
from cadfeat.study.pose_accuracy import PHASES, design_pose_accuracy
from cadfeat.vision import FilterTuning


@pytest.fixture(scope="module")
def results():
    _, res, ctx = shared_case()
    res = copy.deepcopy(res)
    T = invert_T(np.asarray(ctx.trajectory.T_task_cam)) @ ctx.T_task_part
    movable = [h.name for h, f in zip(ctx.holes_before, ctx.fixed_mask, strict=True) if not f]
    res["pose_accuracy"] = {"times_s": np.asarray(ctx.trajectory.times_s).tolist(), "phases": list(PHASES)}
    for key, holes in (("before", ctx.holes_before), ("after", ctx.holes_after)):
        res["pose_accuracy"][key] = design_pose_accuracy(ctx.camera, T, np.asarray(ctx.trajectory.times_s), holes,
                                                         [h.name for h in holes], movable, None, FilterTuning(), 50.0)
    return res


def test_section_renders_table_plot_shares_words(results, tmp_path):
    built = build_report(tmp_path, copy.deepcopy(results), None)
    page = parse_report(built.path)
    raw = built.path.read_text(encoding="utf-8")
    assert '<section id="pose"><h2>How well will the robot know the part&#x27;s pose?</h2>' in raw
    rows = page.tables["pose-accuracy"]
    pa = results["pose_accuracy"]
    for row, name in zip(rows, ("before", "after"), strict=True):
        assert row.cells[0].text == name
        assert row.cells[1].value == pytest.approx(pa[name]["rms"]["error_translation_mm"], rel=1e-12)
        assert row.cells[5].value == pytest.approx(pa[name]["rms"]["error_rotation_deg"], rel=1e-12)
        assert row.cells[9].value == pytest.approx(pa[name]["rms"]["iekf_translation_mm"], rel=1e-12)
    shares = {r.cells[0].text: r.cells[1].value for r in page.tables["pose-shares"]}
    assert shares == pytest.approx({h: 100 * v for h, v in pa["before"]["share"].items()}, rel=1e-12)
    png = tmp_path / "img" / "pose_accuracy.png"
    assert float(np.asarray(Image.open(png).convert("L"), dtype=float).std()) > 5.0
    text = " ".join(page.text)
    assert pa["before"]["weakest"][0]["weakest"] in text
    assert pa["after"]["help_most"]["best"]["sentence"].split(":")[0] in text


def test_closed_loop_beside_the_prediction(results, tmp_path):
    res = copy.deepcopy(results)
    sim = {"before": 0.04, "after": 0.03}
    res["tracking"] = {"designs": {d: {"estimators": {
        "pnp": {"trans_mm_rms": {"mean": sim[d]}, "rot_deg_rms": {"mean": 0.02}},
        "iekf": {"trans_mm_rms": {"mean": sim[d] / 2}, "rot_deg_rms": {"mean": 0.01}}}} for d in sim}}
    html = pose_section(res, tmp_path, lambda p: str(p))
    path = tmp_path / "r.html"
    path.write_text(f"<html><body>{html}</body></html>", encoding="utf-8")
    rows = parse_report(path).tables["pose-closed-loop"]
    assert len(rows) == 8
    pa = res["pose_accuracy"]
    first = rows[0]  # before, PnP, translation
    assert first.cells[3].value == pytest.approx(pa["before"]["rms"]["error_translation_mm"], rel=1e-12)
    assert first.cells[5].value == pytest.approx(0.04 / pa["before"]["rms"]["error_translation_mm"], rel=1e-12)
    iekf = rows[2]
    assert iekf.cells[5].value == pytest.approx(0.02 / pa["before"]["rms"]["iekf_translation_mm"], rel=1e-12)


def test_no_pose_accuracy_no_section(tmp_path):
    assert pose_section({}, tmp_path, str) == ""
