"""The report's robust redesign section and verdict rule (issue 18), from a results dict whose ``robustness``
block is written by hand: the page (read back with html.parser) must show exactly these numbers, the box plot
must be a real image (Pillow: pixel variance), and the verdict must follow the stated rule."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from PIL import Image
from report_fixture import shared_case
from report_html import parse_report

from cadfeat.report import write_report
from cadfeat.report.verdict import verdict_json

SOURCES = ("cell", "camera", "placement", "path", "pixel_noise", "manufacturing")


def _stats(nominal: float, p05: float) -> dict:
    one = {"nominal": nominal, "mean": (nominal + p05) / 2, "p05": p05, "p10": (nominal + 3 * p05) / 4, "min": p05 - 1}
    return {s: {"g_FOV": dict(one), "combined": dict(one)} for s in SOURCES}


def _robustness(recommended: str) -> dict:
    rng = np.random.default_rng(0)
    designs = {"original": _stats(-0.66, -1.1), "robust": _stats(0.95, 0.35), "nominal": _stats(0.98, -1.3)}
    block = {"original": designs["original"], "recommended": designs[recommended]}
    block.update({k: v for k, v in designs.items() if k not in ("original", recommended)})
    dists = {k: {"combined": {s: list(rng.normal(v["cell"]["combined"]["nominal"], 0.3, 50)) for s in SOURCES},
                 "objectives_cell": {"g_FOV": list(rng.normal(0.0, 1.0, 50))}} for k, v in designs.items()}
    return {"objective": {"robust": True, "statistic": "percentile", "label": "p10", "draws": 64, "sampling": "sobol",
                          "seed": 1},
            "uncertainty": {"camera_position_mm": [2.0, 2.0, 2.0], "camera_angle_deg": [1.0, 1.0, 1.0]},
            "designs": block, "recommended": recommended, "delivered": "robust", "reason": "stated reason",
            "flagged": ["nominal"] + (["robust"] if recommended == "original" else []),
            "out_of_sample": {"statistic": "p10", "draws_in_sample": 64, "seed_in_sample": 1,
                              "draws_out_of_sample": 200, "seed_out_of_sample": 2,
                              "designs": {"original": {"in_sample": -0.9, "out_of_sample": -0.87},
                                          "robust": {"in_sample": 0.07, "out_of_sample": -0.06},
                                          "nominal": {"in_sample": -0.2, "out_of_sample": -0.36}}},
            "sensitivity": {"words": "most sensitive to the camera mounting error (61 %)"},
            "distributions": dists}


def test_side_by_side_box_plot_out_of_sample_and_rule(tmp_path):
    _, results, _ = shared_case()
    results = copy.deepcopy(results)
    results["robustness"] = _robustness("robust")
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
    results["robustness"] = _robustness("original")
    verdict = verdict_json(results)
    assert verdict["decision"] == "do not adopt"
    rule = [f for f in verdict["findings"] if f["rule"] == "robustness"][0]
    assert rule["outcome"] == "do not adopt" and "robust" in rule["detail"]
