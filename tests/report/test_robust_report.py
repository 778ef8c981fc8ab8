"""The report's robust redesign section and verdict rule (issue 18), from a results dict whose ``robustness``
block is written by hand: the page (read back with html.parser) must show exactly these numbers, the box plot
must be a real image (Pillow: pixel variance), and the verdict must follow the stated rule."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from PIL import Image
from report_fixture import robustness_block, shared_case
from report_html import parse_report

from cadfeat.report import write_report
from cadfeat.report.verdict import verdict_json


def test_side_by_side_box_plot_out_of_sample_and_rule(tmp_path):
    _, results, _ = shared_case()
    results = copy.deepcopy(results)
    results["robustness"] = robustness_block("robust")
    page = parse_report(write_report(tmp_path, results, None))
    rows = {r.cells[0].text.split(" ")[0]: r.cells for r in page.tables["robust-designs"]}
    assert set(rows) == {"original", "nominal", "robust"}
    assert rows["robust"][1].value == pytest.approx(0.95) and rows["original"][1].value == pytest.approx(-0.66)
    assert rows["nominal"][3].value == pytest.approx(-1.3)  # whole cell: mean, p05
    assert "(flagged)" in rows["nominal"][0].text and "(recommended)" in rows["robust"][0].text
    oos = {r.cells[0].text: r.cells for r in page.tables["robust-out-of-sample"]}
    assert oos["robust"][2].value == pytest.approx(-0.06) and oos["robust"][3].value == pytest.approx(-0.13)
    assert "most sensitive to the camera mounting error" in "".join(page.text)
    img = np.asarray(Image.open(tmp_path / "img" / "robust_designs.png").convert("L"), float)
    assert img.std() > 5.0
    rules = {r.cells[0].text.split(" ")[2]: r.cells[1].text for r in page.tables["verdict-rules"]
             if r.cells[0].text.startswith("When the robustness")}
    assert rules == {"robustness": "adopt"}
    combined = [r.cells[2].text for r in page.tables["verdict-rules"] if r.cells[0].text.startswith("The combined")]
    assert "robust p10 (held-out draws)" in combined[0] and "-0.87" in combined[0]


def test_a_design_more_fragile_than_the_original_is_not_adopted():
    _, results, _ = shared_case()
    results = copy.deepcopy(results)
    results["robustness"] = robustness_block("original")
    verdict = verdict_json(results)
    assert verdict["decision"] == "do not adopt"
    rule = [f for f in verdict["findings"] if f["rule"] == "robustness"][0]
    assert rule["outcome"] == "do not adopt" and "robust" in rule["detail"]
