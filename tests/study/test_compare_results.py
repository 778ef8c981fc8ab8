"""``tools/compare_results.py``: the check that a refactoring leaves every study's results.json unchanged.

A STEP study scored by ``evaluate_study`` twice (and, in test_study_run, a script study optimised twice): the
comparator must find them identical apart from the run-dependent keys,
and must name the dotted key of a planted difference (the reference is the planted change itself).
"""

from __future__ import annotations

import copy
import json

from study_helpers import SMALL, STEP, compare_results_tool, no_report

from cadfeat.study import evaluate_study


def test_planted_differences_are_named_by_dotted_key(tmp_path):
    tool = compare_results_tool()
    a = {"created": "x", "timings_s": {"a": 1.0}, "objectives": {"after": {"g_FOV": 0.5}}, "holes": [{"x": 1}]}
    b = copy.deepcopy(a)
    b["created"], b["timings_s"] = "y", {"a": 2.0}
    assert tool.compare(a, b) == []
    b["objectives"]["after"]["g_FOV"] = 0.51
    b["holes"].append({"x": 2})
    b["new"] = 1
    diffs = tool.compare(a, b)
    assert diffs == ["holes: 1 items != 2 items", "new: only in the second", "objectives.after.g_FOV: 0.5 != 0.51"]
    (tmp_path / "a.json").write_text(json.dumps(a))
    (tmp_path / "b.json").write_text(json.dumps(b))
    assert tool.main([str(tmp_path / "a.json"), str(tmp_path / "b.json")]) == 1
    assert tool.main([str(tmp_path / "a.json"), str(tmp_path / "a.json")]) == 0


def test_a_step_study_evaluated_twice_gives_identical_results(tmp_path, monkeypatch):
    no_report(monkeypatch)
    data = copy.deepcopy(SMALL)
    data["study"] = {"name": "step_plate", "part": str(STEP), "seed": 2}
    data["design"] = {"holes": [{"select": [-25.0, -15.0, 10.0], "max_offset_mm": 6.0}]}
    data["trajectory"]["target"] = [0.0, 0.0, 10.0]
    for name in ("a", "b"):
        evaluate_study(copy.deepcopy(data), tmp_path / name)
    assert compare_results_tool().compare_files(tmp_path / "a", tmp_path / "b") == []
