"""A study on a real third-party STEP export (``../shared/real_step``, issue 16 item 3): it runs end to end.

poseidon's Fusion 360 pump carriage: a camera approaching from above and the +x side; the long vertical Ø5 hole
may move by up to 0.5 mm. Two things broke such a study before issue 16: the occlusion mesh ("a face could not
be triangulated": BRepMesh leaves the 45° rim-chamfer cones empty) and the CAD rebuild check ("match_holes:
reference hole H3 ... has no candidate": the rebuilt part's holes were extracted without the camera's entrance
side, so a lug hole came back from its other end).
Reference: ``truth.json`` (holes found with OCP alone) against the holes
re-extracted from the written optimised.step: the fixed holes where the truth has them, the moved one on its
face within its offset bound with its own diameter and axis. Kept cheap: 6 poses, one start, few iterations.
"""

from __future__ import annotations

import copy
import os

import numpy as np
import pytest
import real_step_truth as rs

FOLDER = rs.real_step_dir()
if FOLDER is None:
    if os.environ.get("CI"):
        raise RuntimeError("tests/study/test_real_step_study.py: no shared/real_step beside the repository")
    pytest.skip("no shared/real_step beside the repository (CADFEAT_REAL_STEP unset)", allow_module_level=True)

PART = "poseidon_pump_carriage.step"
MOVED = [-91.5, 38.5, 26.5]  # the top of the 53 mm long Ø5 vertical hole (0.5 x 45° rim chamfers)
LIMIT_MM = 0.5
STUDY = {
    "study": {"name": "real_pump_carriage", "part": str(FOLDER / PART), "seed": 1},
    "camera": {"preset": "realsense-d435-rgb", "focus_distance_mm": 200.0},
    "trajectory": {"kind": "straight_approach", "start": [0.0, 250.0, 200.0], "end": [-60.0, 180.0, 150.0],
                   "target": MOVED, "n": 6, "duration_s": 2.0},
    "design": {"holes": [{"select": MOVED, "max_offset_mm": LIMIT_MM}]},
    "constraints": {"edge_distance_mm": 0.5, "ligament_mm": 0.5},
    "objective": {"measures": ["fov", "resolution", "resolvability"], "aggregate": "sum", "combine": "maxmin",
                  "rotation_length_mm": 50.0},
    "optimizer": {"method": "multistart", "starts": 1, "maxiter": 10},
    "robustness": {"robust": False},
}


def test_a_study_on_a_real_export_runs_and_writes_the_true_holes(tmp_path, monkeypatch):
    import cadfeat.study.run as study_mod
    from cadfeat.cad.export import import_step
    from cadfeat.cad.features import extract_holes
    from cadfeat.study.run import run_study
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import check_step_study

    monkeypatch.setattr(study_mod, "_report", lambda *a, **k: None)  # the report is tested elsewhere
    data = copy.deepcopy(STUDY)
    assert "dry run re-drilled" in check_step_study(load_study(data))  # what validate adds for a STEP study
    result = run_study(data, tmp_path / "out", quiet=True)
    assert result.results["study"]["part_kind"] == "step"
    assert result.results["verification"]["brep_valid"] is True
    truth = rs.truth()[PART]["holes"]
    final = extract_holes(import_step(tmp_path / "out" / "optimised.step"))
    assert len(final) == len(truth)
    for t in truth:
        ends = [np.array(t["centre"])] + ([np.array(t["other_end_centre"])] if t.get("entrance_either_end") else [])
        gaps = [float(np.linalg.norm(h.centre - e)) for h in final for e in ends
                if np.linalg.norm(np.cross(h.axis, t["axis"])) < 1e-6
                and abs(2 * h.bore_radius_mm - t["bore_diameter"]) < 1e-3
                and abs(float(np.dot(h.centre - e, t["axis"]))) < 1e-3]  # on the same face plane
        # max_offset_mm bounds each of the two in-plane offsets: the moved hole is within √2 of it
        limit = LIMIT_MM * np.sqrt(2) + 1e-6 if any(np.allclose(e, MOVED, atol=1e-3) for e in ends) else 1e-4
        assert gaps and min(gaps) <= limit, (t["id"], gaps)
