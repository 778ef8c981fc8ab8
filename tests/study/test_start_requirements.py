"""``cadfeat validate`` checks a STEP study's kept requirements at the start design (issue 32 item 9): a start that
breaks one is named before any optimisation; refused if no design within the bounds meets them, else noted (the
optimiser has to move the hole). The part: a plate with one Ø3.4 hole 0.5 mm from a rectangular opening.

Reference: the construction values (the hole's gap to the opening, the ligament asked for).
"""

from __future__ import annotations

import pytest

GAP_MM = 0.5  # from the hole's rim to the opening
LIGAMENT_MM = 1.5
R = 1.7


def plate_step(tmp_path):
    import cadquery as cq

    from cadfeat.cad.export import export_step

    plate = cq.Workplane("XY").box(40, 40, 4, centered=(True, True, False))
    hole = cq.Workplane("XY").center(0, 0).circle(R).extrude(6).translate((0, 0, -1))
    opening = cq.Workplane("XY").center(R + GAP_MM + 3, 0).rect(6, 8).extrude(6).translate((0, 0, -1))
    path = tmp_path / "plate.step"
    export_step(plate.cut(hole).cut(opening).val(), path)
    return path


def study(path, max_offset_mm: float) -> dict:
    return {
        "study": {"name": "start_check", "part": str(path), "seed": 1},
        "camera": {"preset": "realsense-d435-rgb", "focus_distance_mm": 200.0},
        "trajectory": {"kind": "straight_approach", "start": [0.0, 0.0, 260.0], "end": [10.0, 0.0, 200.0],
                       "target": [0.0, 0.0, 4.0], "n": 4, "duration_s": 1.0},
        "design": {"holes": [{"select": [0.0, 0.0, 4.0], "max_offset_mm": max_offset_mm}]},
        "constraints": {"edge_distance_mm": 1.0, "ligament_mm": LIGAMENT_MM},
        "objective": {"measures": ["fov", "resolution"], "aggregate": "sum", "combine": "maxmin"},
    }


def test_a_start_that_breaks_a_requirement_the_bounds_can_meet_is_noted(tmp_path):
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import check_step_study

    note = check_step_study(load_study(study(plate_step(tmp_path), max_offset_mm=3.0)))
    assert f"the start breaks keepout (H1) by {LIGAMENT_MM - GAP_MM:.4g} mm" in note
    assert "the optimiser has to move" in note


def test_a_start_that_breaks_a_requirement_no_design_in_the_bounds_meets_is_refused(tmp_path):
    from cadfeat.study.schema import StudyError, load_study
    from cadfeat.study.setup import check_step_study

    with pytest.raises(StudyError, match=r"the start design already breaks the kept requirements: keepout \(H1\) "
                                         r"by 1 mm; no design within the bounds") as err:
        check_step_study(load_study(study(plate_step(tmp_path), max_offset_mm=0.3)))
    assert "cannot move" not in str(err.value)  # it may move, only not far enough
