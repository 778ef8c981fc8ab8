"""Report section "Where would new target holes help?" (issue 31): the curve, the recommendation, the holes."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from cadfeat.report.added_targets import added_targets_section


def _block() -> dict[str, Any]:
    hole = {"name": "H10", "centre": [-29.0, 0.0, 52.0], "axis": [0.0, -1.0, 0.0], "diameter_mm": 5.5,
            "depth_mm": 2.0, "chamfer_mm": 0.0, "rim_radius_mm": 2.75, "face": "face 1", "status": "added"}
    return {"faces": ["face 1"], "candidate_sites": 40, "recommended": 1, "reason": "hole 2 would gain only 3 %",
            "curve": {"added": [0, 1, 2], "error_mm": [0.036, 0.028, 0.027], "sites": [[0, 0, 0], [1, 0, 0]]},
            "holes": [hole], "drop_vs_move_only": 0.25,
            "predicted": {k: {"error_mm": e, "translation_mm": e, "rotation_deg": 0.01}
                          for k, e in (("original", 0.04), ("move_only", 0.036), ("added", 0.027))},
            "constraints": [{"name": "edge", "holes": ["H10"], "ok": True, "checked_on": "brep"},
                            {"name": "edge", "holes": ["H10"], "ok": True, "checked_on": "step"}],
            "requirements_hold": True, "step": {"file": "optimised.step", "max_error_mm": 1e-12}}


def test_section_shows_the_curve_and_the_recommendation(tmp_path: Path) -> None:
    html = added_targets_section({"added_targets": _block()}, tmp_path, lambda p: p.name)
    assert (tmp_path / "img" / "added_targets.png").is_file()
    assert "Recommended: 1 added hole(s)" in html and "hole 2 would gain only 3 %" in html
    assert "25 % below the move-only optimum" in html
    assert ">H10<" in html and ">added<" in html and "brep and step" in html
    assert "not run" in html  # no closed loop in these results


def test_no_section_without_added_targets(tmp_path: Path) -> None:
    assert added_targets_section({}, tmp_path, lambda p: p.name) == ""


def test_delivered_design_and_its_closed_loop(tmp_path: Path) -> None:
    """With the added design delivered: the section says so and shows the three paired comparisons, the first
    (the delivered design against the original) being the verdict's."""
    block = _block()
    rms = {"trans_mm_rms": {"mean": 0.04}, "rot_deg_rms": {"mean": 0.03}}
    block.update(delivered={"design": "added", "files": ["optimised.step", "optimised.stl"],
                            "move_only_file": "move_only.step"},
                 move_only={"step": {"file": "move_only.step", "max_error_mm": 0.0}},
                 tracking={"mode": "fast", "runs": 8,
                           "verdicts": {"added_vs_original": {"pnp": "better"},
                                        "move_only_vs_original": {"pnp": "no significant difference"},
                                        "added_vs_move_only": {"pnp": "better"}},
                           "designs": {d: {"pnp": rms} for d in ("original", "move_only", "added")}})
    html = added_targets_section({"added_targets": block}, tmp_path, lambda p: p.name)
    assert "This is the delivered design" in html and "move_only.step" in html
    for what in ("the delivered design (added holes) vs the original", "the move-only optimum vs the original",
                 "the delivered design vs the move-only optimum"):
        assert what in html
    assert html.count(">better<") == 2 and ">no significant difference<" in html


def test_verdict_of_a_delivered_added_design_uses_its_own_combined_value() -> None:
    """A robust study whose delivered design has added holes: the combined rule reads the delivered design's
    (nominal) value — the robust draws hold the move-only optimum, said beside it — and the tracking rule names
    the delivered design."""
    from cadfeat.report.verdict import decide

    results = {
        "objectives": {"names": ["g_POSE"], "before": {"g_POSE": -0.143}, "after": {"g_POSE": -0.0875},
                       "combined_before": 0.70, "combined_after": 5.9, "combine": "maxmin", "aggregate": "sum"},
        "robustness": {"delivered": "robust", "out_of_sample": {
            "statistic": "p10", "designs": {"original": {"out_of_sample": 0.38}, "robust": {"out_of_sample": 0.3801}}}},
        "added_targets": {**_block(), "delivered": {"design": "added"}},
        "tracking": {"verdicts": {"pnp": {"verdict": "better"}}},
    }
    v = decide(results)
    found = {f.rule: f for f in v.findings}
    assert found["combined"].outcome == "adopt"  # the robust statistic alone (+0.03 %) would say "do not adopt"
    assert found["combined"].detail.startswith("combined objective 0.7 → 5.9")
    assert "of the move-only optimum 0.38 → 0.3801 (the added holes are not in the robust draws)" in \
        found["combined"].detail
    assert "the delivered design (with 1 added target holes) vs the original" in found["tracking"].detail
