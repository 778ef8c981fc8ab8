"""The recommended added-hole design is the study's answer (issue 31, ``study.added_design``), on a small STEP study
(tests/data/plate_holes.step, two holes moved, up to two Ø4.5 targets with a 0.3 mm chamfer on the top face) run
once with the fast closed-loop check:

- ``optimised.step`` holds the added holes: re-imported, cadfeat's extraction finds every hole of
  ``move_only.step`` unchanged and each added hole where results.json puts it, AND an independent reading of the
  STEP with OCP alone (its cylindrical faces: radius, axis line, extent along the axis) finds each added bore;
- ``holes.csv`` and results.json ``holes.after`` list every hole, the added ones "added", named after the part's;
- the verdict judges the delivered design (its objectives, its requirements on the B-rep and the STEP, its closed
  loop against the original: paired Wilcoxon runs), with the move-only optimum's comparisons beside it.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from study_helpers import STEP

pytest.importorskip("cadquery")
pytestmark = pytest.mark.slow

STUDY: dict[str, Any] = {
    "study": {"name": "step_add", "part": str(STEP), "seed": 2},
    "camera": {"preset": "realsense-d435-rgb", "focus_distance_mm": 220.0},
    "trajectory": {"kind": "orbit_arc", "centre": [0, 0, 10], "radius_mm": 220.0, "elevation_deg": 55.0,
                   "azimuth_start_deg": -150.0, "azimuth_end_deg": -30.0, "n": 12, "duration_s": 2.0},
    "design": {"holes": [{"select": [-25.0, -15.0, 10.0], "max_offset_mm": 6.0},
                         {"select": [-25.0, 15.0, 10.0], "max_offset_mm": 6.0}]},
    "constraints": {"edge_distance_mm": 3.0, "ligament_mm": 2.5},
    "objective": {"measures": ["pose"]},
    "optimizer": {"method": "multistart", "starts": 2, "maxiter": 20},
    "robustness": {"robust": False},
    "add_targets": {"faces": ["+z"], "diameter_mm": 4.5, "depth_mm": 2.5, "chamfer_mm": 0.3, "max_added": 2,
                    "min_gain_percent": 0.0, "pitch_mm": 6.0},
}
VIEW = (0.0, 0.0, 1.0)


@pytest.fixture(scope="module")
def out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from cadfeat.study.run import run_study

    folder = tmp_path_factory.mktemp("delivered") / "out"
    run_study(STUDY, folder, quiet=True, track="fast")
    return folder


@pytest.fixture(scope="module")
def results(out: Path) -> dict[str, Any]:
    return json.loads((out / "results.json").read_text())


def test_outputs_name_the_delivered_design(out: Path, results: dict[str, Any]) -> None:
    block = results["added_targets"]
    assert block["recommended"] == 2 and block["delivered"]["design"] == "added"
    files = {f["name"] for f in results["files"]}
    assert {"optimised.step", "optimised.stl", "move_only.step"} <= files, files
    assert not (out / "added_targets.step").exists()
    assert block["step"]["file"] == "optimised.step" and block["step"]["max_error_mm"] < 1e-6
    assert block["move_only"]["step"]["file"] == "move_only.step" and block["move_only"]["step"]["max_error_mm"] < 1e-6


def test_optimised_step_holds_every_added_hole(out: Path, results: dict[str, Any]) -> None:
    """cadfeat's extraction on the re-imported optimised.step: every hole of move_only.step unchanged, each added
    hole at its centre, axis, rim radius and depth."""
    from cadfeat.cad.export import import_step
    from cadfeat.cad.features import extract_holes, match_holes

    block = results["added_targets"]
    move_only = extract_holes(import_step(out / "move_only.step"), prefer_direction=VIEW)
    delivered = extract_holes(import_step(out / "optimised.step"), prefer_direction=VIEW)
    assert len(delivered) == len(move_only) + 2
    idx = match_holes(move_only, delivered, tol_mm=1e-6)
    for i, h in zip(idx, move_only, strict=True):
        assert np.linalg.norm(delivered[i].centre - h.centre) < 1e-6
        assert abs(delivered[i].radius_mm - h.radius_mm) < 1e-6 and abs(delivered[i].depth_mm - h.depth_mm) < 1e-6
    rest = [h for i, h in enumerate(delivered) if i not in set(idx)]
    for h in block["holes"]:
        d = [float(np.linalg.norm(x.centre - np.asarray(h["centre"]))) for x in rest]
        k = int(np.argmin(d))
        assert d[k] < 1e-6 and float(np.asarray(rest[k].axis) @ np.asarray(h["axis"])) > 1 - 1e-9
        assert rest[k].radius_mm == pytest.approx(h["rim_radius_mm"], abs=1e-6)
        assert rest[k].depth_mm == pytest.approx(h["depth_mm"], abs=1e-6) and not rest[k].through


def _cylinders(path: Path) -> list[tuple[float, np.ndarray, np.ndarray, float, float]]:
    """Every cylindrical face of a STEP file read with OCP alone: (radius, a point of the axis, the axis direction,
    the face's extent along the axis from that point: lowest, highest), mm."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepTools import BRepTools
    from OCP.GeomAbs import GeomAbs_Cylinder
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    reader = STEPControl_Reader()
    assert reader.ReadFile(str(path)) == IFSelect_RetDone
    reader.TransferRoots()
    shape = reader.OneShape()
    out = []
    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face_s(explorer.Current())
        surface = BRepAdaptor_Surface(face)
        if surface.GetType() == GeomAbs_Cylinder:
            cylinder = surface.Cylinder()
            axis = cylinder.Axis()
            p, d = axis.Location(), axis.Direction()
            _, _, v0, v1 = BRepTools.UVBounds_s(face)  # v: the length along the axis from its location
            out.append((cylinder.Radius(), np.array([p.X(), p.Y(), p.Z()]), np.array([d.X(), d.Y(), d.Z()]),
                        min(v0, v1), max(v0, v1)))
        explorer.Next()
    return out


def test_an_independent_reading_finds_each_added_bore(out: Path, results: dict[str, Any]) -> None:
    """Without cadfeat's extraction: optimised.step has, for each added hole, a cylindrical face of the drill's
    radius on the hole's axis line running from the chamfer's foot (0.3 mm below the rim) to the floor (2.5 mm);
    move_only.step has none of them."""
    delivered, move_only = _cylinders(out / "optimised.step"), _cylinders(out / "move_only.step")
    for h in results["added_targets"]["holes"]:
        spans = _bore(delivered, h)
        assert spans, f"no cylindrical bore of {h['name']} in optimised.step"
        low, high = min(s[0] for s in spans), max(s[1] for s in spans)
        assert low == pytest.approx(-h["depth_mm"], abs=1e-6) and high == pytest.approx(-h["chamfer_mm"], abs=1e-6)
        assert not _bore(move_only, h)


def _bore(found: list[tuple[float, np.ndarray, np.ndarray, float, float]], h: dict[str, Any]
          ) -> list[tuple[float, float]]:
    """The spans along the axis (mm, 0 at the rim, negative into the part) of the cylindrical faces of ``found``
    with the drill's radius on added hole ``h``'s axis line."""
    c, a = np.asarray(h["centre"], float), np.asarray(h["axis"], float)
    spans = []
    for radius, p, d, v0, v1 in found:
        off = c - p
        if (abs(radius - 0.5 * h["diameter_mm"]) < 1e-6 and abs(abs(float(d @ a)) - 1.0) < 1e-9
                and np.linalg.norm(off - (off @ d) * d) < 1e-6):
            ends = sorted(float((p + v * d - c) @ a) for v in (v0, v1))
            spans.append((ends[0], ends[1]))
    return spans

def test_hole_table_and_results_list_the_added_holes(out: Path, results: dict[str, Any]) -> None:
    with (out / "holes.csv").open() as f:
        table = list(csv.DictReader(f))
    after = results["holes"]["after"]
    assert [r["name"] for r in table] == [h["name"] for h in after] == ["H1", "H2", "H3", "H4", "H5", "H6", "H7"]
    assert [r["changed"] for r in table] == ["yes", "yes", "no", "no", "no", "added", "added"]
    assert [bool(h.get("added")) for h in after] == [False] * 5 + [True] * 2
    for row, h in zip(table[5:], results["added_targets"]["holes"], strict=True):
        assert [float(row[k]) for k in ("x_mm", "y_mm", "z_mm")] == pytest.approx(h["centre"], abs=1e-3)
        assert float(row["depth_mm"]) == pytest.approx(2.5, abs=1e-3) and row["face"] == "+Z"
    assert len(results["measures"]["after"]["per_feature"]) == 7
    html = (out / "report.html").read_text()
    assert ">added<" in html and "move_only.step" in html


def test_verdict_judges_the_delivered_design(results: dict[str, Any]) -> None:
    """The objectives, requirements and closed loop the verdict reads are the delivered design's: g_POSE after is
    minus its predicted error, every requirement holds on its B-rep and its STEP (the added holes included), and
    the tracking rule is the delivered design against the original (paired runs, Wilcoxon)."""
    block = results["added_targets"]
    assert results["objectives"]["after"]["g_POSE"] == pytest.approx(-block["predicted"]["added"]["error_mm"],
                                                                     rel=1e-9)
    assert block["move_only"]["objectives"]["g_POSE"] > results["objectives"]["before"]["g_POSE"]
    checks = results["constraints"]
    assert {c["checked_on"] for c in checks} == {"brep", "step"} and all(c["ok"] for c in checks)
    for where in ("brep", "step"):
        assert {"H6", "H7"} <= {c["holes"][0] for c in checks if c["name"] == "edge" and c["checked_on"] == where}
    tr = results["tracking"]
    assert set(tr["designs"]) == {"before", "after", "move_only"}
    assert set(tr["comparisons"]) == {"move_only_vs_original", "added_vs_move_only"}
    for v in tr["verdicts"].values():
        assert "Wilcoxon" in v["translation"]["test"] and v["translation"]["runs"] == 8
    findings = {f["rule"]: f for f in results["verdict"]["findings"]}
    assert "with 2 added target holes" in findings["combined"]["detail"]
    assert findings["tracking"]["detail"].startswith("pose tracking, the delivered design (with 2 added target holes) "
                                                     "vs the original")
    summary = block["tracking"]
    assert set(summary["verdicts"]) == {"added_vs_original", "move_only_vs_original", "added_vs_move_only"}
    assert summary["verdicts"]["added_vs_original"] == {m: v["verdict"] for m, v in tr["verdicts"].items()}
