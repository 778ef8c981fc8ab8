"""End-to-end studies: outputs, independent checks of the exported STEP, determinism, interruption.

The kept requirements are re-checked here WITHOUT the optimiser's constraint code: the holes are
re-extracted from the written optimised.step and the edge distances / ligaments are computed from the
plate's known outline (tests/data/study_plate.py: a 60 x 40 mm plate centred on the origin).
"""

from __future__ import annotations

import copy
import hashlib
import html
import json
import re
from pathlib import Path

import jsonschema
import numpy as np
import pytest
from study_helpers import DATA, EDGE_MM, LIGAMENT_MM, PLATE, SMALL, STEP, compare_results_tool, no_report

from cadfeat.study.outputs import plain
from cadfeat.study.run import evaluate_study, run_study

PLATE_HALF = (30.0, 20.0)   # study_plate.py: 60 x 40 mm, centred
FIXED_HOLE = (-22.0, -12.0, 2.0)
ALLOWED_EXTRA = {"report.html", "img", "holes.csv", ".cadfeat-output.json"}
RESULT_KEYS = {"cadfeat_version", "created", "study", "inputs", "camera", "trajectory", "variables", "holes",
               "objectives", "measures", "constraints", "design_matrix", "history", "sweep", "pareto", "files",
               "timings_s", "versions", "interrupted", "verification"}



def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "small"
    before = sha(PLATE)
    result = run_study(copy.deepcopy(SMALL), out, quiet=True)
    return result, out, before


def test_outputs_exactly_the_expected_files(small_run):
    result, out, _ = small_run
    assert result.out_dir == out
    names = {p.name for p in out.iterdir()}
    assert {"original.step", "optimised.step", "optimised.stl", "results.json"} <= names
    assert names - {"original.step", "optimised.step", "optimised.stl", "results.json"} <= ALLOWED_EXTRA
    assert not [p for p in out.parent.iterdir() if p.name.startswith(".")]  # no staging folders left


def test_results_json_keys_and_files(small_run):
    result, out, _ = small_run
    data = json.loads((out / "results.json").read_text())
    assert RESULT_KEYS <= set(data)
    assert data["study"] == plain(result.results["study"]) and data["variables"] == plain(result.results["variables"])
    for entry in data["files"]:
        path = out / entry["name"]
        assert path.stat().st_size == entry["bytes"] and sha(path) == entry["sha256"]
    assert data["interrupted"] is False
    assert data["study"]["part_kind"] == "script"
    assert data["verification"]["step_roundtrip_max_error_mm"] <= 1e-6
    assert [v["name"] for v in data["variables"]] == ["x0", "y0"]
    for v in data["variables"]:
        assert v["lower"] - 1e-9 <= v["after"] <= v["upper"] + 1e-9
    assert all(c["ok"] for c in data["constraints"])
    assert {c["checked_on"] for c in data["constraints"]} == {"brep", "step"}
    obj = data["objectives"]
    assert obj["combined_after"] >= obj["combined_before"] - 1e-9
    assert set(obj["before"]) == set(obj["after"]) == set(obj["names"])
    n = len(data["holes"]["after"])
    assert len(data["measures"]["after"]["per_feature"]) == n
    assert len(data["measures"]["after"]["per_pose"]["resolvability"]) == data["trajectory"]["n_samples"] == 12


def test_verdict_in_results_and_summary_is_the_reports(small_run):
    """Issue 16: results.json and the console summary carry the report's verdict, so a pipeline can gate on it."""
    result, out, _ = small_run
    verdict = json.loads((out / "results.json").read_text())["verdict"]
    shown = re.search(r'<span id="verdict">([^<]*)</span>', (out / "report.html").read_text()).group(1)
    assert verdict["decision"] == html.unescape(shown) in ("adopt", "adopt with care", "do not adopt")
    assert {f["rule"] for f in verdict["findings"]} >= {"combined", "requirements"}
    assert f"verdict: {verdict['decision']}" in result.summary()


def test_exported_step_keeps_every_requirement(small_run):
    """Independent of the optimiser: re-extract the holes of optimised.step, measure edge distances to the
    known plate outline and the ligaments between holes, and find the fixed dowel hole unchanged."""
    from cadfeat.cad.export import import_step
    from cadfeat.cad.features import extract_holes

    _, out, _ = small_run
    holes = extract_holes(import_step(out / "optimised.step"), prefer_direction=(0, 0, 1))
    assert len(holes) == 4
    c = np.array([h.centre for h in holes])
    r = np.array([h.radius_mm for h in holes])
    np.testing.assert_allclose(c[:, 2], 6.0, atol=1e-9)  # all on the top face
    edge = np.minimum(PLATE_HALF[0] - np.abs(c[:, 0]), PLATE_HALF[1] - np.abs(c[:, 1])) - r
    assert edge.min() >= EDGE_MM - 1e-6
    gaps = np.linalg.norm(c[:, None, :2] - c[None, :, :2], axis=-1) - r[:, None] - r[None, :]
    assert gaps[np.triu_indices(4, 1)].min() >= LIGAMENT_MM - 1e-6
    fixed = np.linalg.norm(c[:, :2] - np.array(FIXED_HOLE[:2]), axis=1)
    k = int(np.argmin(fixed))
    assert fixed[k] < 1e-9 and abs(r[k] - FIXED_HOLE[2]) < 1e-9
    # the row holes are equally spaced at the part's pitch (10 mm), on one line y = y0
    row = np.delete(c, k, axis=0)
    row = row[np.argsort(row[:, 0])]
    np.testing.assert_allclose(np.diff(row[:, 0]), 10.0, atol=1e-9)
    np.testing.assert_allclose(row[:, 1], row[0, 1], atol=1e-9)


def test_results_match_the_exported_step(small_run):
    from cadfeat.cad.export import import_step
    from cadfeat.cad.features import extract_holes

    result, out, _ = small_run
    after = {v["name"]: v["after"] for v in result.results["variables"]}
    holes = extract_holes(import_step(out / "optimised.step"), prefer_direction=(0, 0, 1))
    xs = sorted(h.centre[0] for h in holes if abs(h.centre[0] - FIXED_HOLE[0]) > 1e-6)
    assert abs(xs[0] - after["x0"]) < 1e-6
    ys = [h.centre[1] for h in holes if abs(h.centre[0] - FIXED_HOLE[0]) > 1e-6]
    assert max(abs(y - after["y0"]) for y in ys) < 1e-6


def test_input_part_unchanged(small_run):
    _, _, before = small_run
    assert sha(PLATE) == before


@pytest.mark.slow
def test_same_seed_same_results(tmp_path, monkeypatch):
    no_report(monkeypatch)
    a = run_study(copy.deepcopy(SMALL), tmp_path / "a", quiet=True, seed=3)
    b = run_study(copy.deepcopy(SMALL), tmp_path / "b", quiet=True, seed=3)
    assert compare_results_tool().compare_files(tmp_path / "a", tmp_path / "b") == []  # tools/compare_results.py
    ja = json.loads((tmp_path / "a" / "results.json").read_text())
    from cadfeat.results import StudyResults, results_json_schema

    jsonschema.Draft202012Validator(results_json_schema()).validate(ja)  # a run's results meet the schema
    assert StudyResults.read(tmp_path / "a").to_data() == ja and StudyResults.read(tmp_path / "a").is_run
    assert compare_results_tool().compare(a.typed.to_data(), ja) == []  # run_study's return is what it wrote
    assert a.results["study"]["seed"] == 3 and ja["inputs"]["optimizer"]["seed"] == 3
    for name in ("original.step", "optimised.step", "optimised.stl"):
        assert sha(tmp_path / "a" / name) == sha(tmp_path / "b" / name)
    assert b.out_dir == tmp_path / "b"


def test_interrupt_before_any_design_writes_nothing(tmp_path, monkeypatch):
    import cadfeat.design.optimize as optimize

    def stop(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(optimize, "optimise", stop)
    monkeypatch.setattr(optimize, "solve_with_cad", stop)
    before = sha(PLATE)
    with pytest.raises(KeyboardInterrupt):
        run_study(copy.deepcopy(SMALL), tmp_path / "out", quiet=True)
    assert list(tmp_path.iterdir()) == []  # no output folder, no staging folder
    assert sha(PLATE) == before


def test_interrupt_keeps_best_design(tmp_path, monkeypatch):
    """Ctrl-C during the optimisation (raised from the progress callback after a few iterations): the best
    design so far is verified and written, marked ``interrupted``."""
    import cadfeat.design.optimize as optimize

    no_report(monkeypatch)
    real = optimize.optimise

    def interrupted(problem, config, progress=None, **kw):
        count = {"n": 0}

        def tick(entry):
            if progress is not None:
                progress(entry)
            count["n"] += 1
            if count["n"] >= 3:
                raise KeyboardInterrupt

        return real(problem, config, tick, **kw)

    monkeypatch.setattr(optimize, "optimise", interrupted)
    result = run_study(copy.deepcopy(SMALL), tmp_path / "out", quiet=True)
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    assert data["interrupted"] is True and result.results["interrupted"] is True
    assert all(c["ok"] for c in data["constraints"])
    assert (tmp_path / "out" / "optimised.step").exists()


def test_failed_verification_leaves_previous_output(tmp_path, monkeypatch):
    """A failure after the optimiser (here: the STEP round trip) leaves the old output folder untouched."""
    from cadfeat.cad.export import ExportError

    no_report(monkeypatch)
    from cadfeat.output_folder import staged_output

    out = tmp_path / "out"
    with staged_output(out) as stage:  # the previous output: a folder cadfeat made
        (stage / "keep.txt").write_text("old")

    def broken(*a, **k):
        raise ExportError("simulated round-trip mismatch")

    monkeypatch.setattr("cadfeat.cad.export.verify_step_roundtrip", broken)
    with pytest.raises(ExportError):
        run_study(copy.deepcopy(SMALL), out, quiet=True)
    assert sorted(p.name for p in out.iterdir()) == [".cadfeat-output.json", "keep.txt"]
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_infeasible_study_names_the_conflict(tmp_path, monkeypatch):
    """No position of the row keeps 25 mm from the edges of a 60 x 40 mm plate: one StudyError naming the
    violated requirement, nothing written."""
    from cadfeat.study.schema import StudyError

    no_report(monkeypatch)
    data = copy.deepcopy(SMALL)
    data["constraints"]["edge_distance_mm"] = 25.0
    with pytest.raises(StudyError, match="no design meets the kept requirements.*edge"):
        run_study(data, tmp_path / "out", quiet=True)
    assert list(tmp_path.iterdir()) == []


def test_parameter_moving_a_declared_fixed_hole_is_an_error(tmp_path):
    """A part script marks a hole functional ("fixed": True in expected_holes): a study varying a parameter
    that moves it fails before optimising, naming the parameter."""
    from cadfeat.study.schema import StudyError

    script = tmp_path / "dowel_plate.py"
    script.write_text(
        "import cadquery as cq\n"
        "PARAMETERS = {'dowel_x': {'default': 0.0, 'bounds': (-5.0, 5.0)},\n"
        "              'x': {'default': 10.0, 'bounds': (8.0, 12.0)}}\n"
        "def build(dowel_x, x):\n"
        "    plate = cq.Workplane('XY').box(40, 30, 5, centered=(True, True, False))\n"
        "    return plate.faces('>Z').workplane(origin=(0, 0, 0)).pushPoints([(dowel_x, 0), (x, 8)]).hole(3)\n"
        "def expected_holes(dowel_x, x):\n"
        "    return [{'centre': (dowel_x, 0, 5), 'axis': (0, 0, 1), 'radius_mm': 1.5, 'fixed': True},\n"
        "            {'centre': (x, 8, 5), 'axis': (0, 0, 1), 'radius_mm': 1.5}]\n")
    data = copy.deepcopy(SMALL)
    data["study"]["part"] = str(script)
    data["design"] = {"parameters": ["dowel_x", "x"]}
    with pytest.raises(StudyError, match="design.parameters: dowel_x would move hole"):
        run_study(data, tmp_path / "out", quiet=True)
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_integer_parameter_stays_int(tmp_path, monkeypatch):
    """``count`` (an int parameter) is enumerated, never turned into a float: the CAD model is built with an
    int, results.json holds ints, and the exported STEP has the chosen number of row holes."""
    from cadfeat.cad.export import import_step
    from cadfeat.cad.features import extract_holes

    no_report(monkeypatch)
    data = copy.deepcopy(SMALL)
    data["design"]["parameters"]["count"] = {"lower": 2, "upper": 3}
    result = run_study(data, tmp_path / "out", quiet=True)
    var = {v["name"]: v for v in json.loads((tmp_path / "out" / "results.json").read_text())["variables"]}
    assert type(var["count"]["before"]) is int and type(var["count"]["after"]) is int
    assert var["count"]["before"] == 3 and var["count"]["after"] in (2, 3)
    assert result.results["optimizer"]["integer_combinations"] == 2
    holes = extract_holes(import_step(tmp_path / "out" / "optimised.step"))
    assert len(holes) == var["count"]["after"] + 1


@pytest.mark.slow
def test_step_study_end_to_end(tmp_path, monkeypatch):
    """A STEP part: two plain holes move on the top face of tests/data/plate_holes.step; the others are fixed
    and come back unchanged in the re-imported STEP."""
    from cadfeat.cad.export import import_step
    from cadfeat.cad.features import extract_holes

    no_report(monkeypatch)
    data = copy.deepcopy(SMALL)
    data["study"] = {"name": "step_plate", "part": str(STEP), "seed": 2}
    data["design"] = {"holes": [{"select": [-25.0, -15.0, 10.0], "max_offset_mm": 6.0},
                                {"select": [-25.0, 15.0, 10.0], "max_offset_mm": 6.0}]}
    data["trajectory"]["target"] = [0.0, 0.0, 10.0]
    result = run_study(data, tmp_path / "out", quiet=True)
    assert result.results["study"]["part_kind"] == "step"
    original = extract_holes(import_step(STEP))
    final = extract_holes(import_step(tmp_path / "out" / "optimised.step"))
    moved = {(-25.0, -15.0), (-25.0, 15.0)}
    kept = [h for h in original if (round(h.centre[0], 6), round(h.centre[1], 6)) not in moved]
    for h in kept:
        d = [np.linalg.norm(f.centre - h.centre) + abs(f.radius_mm - h.radius_mm) for f in final]
        assert min(d) < 1e-6
    assert len(final) == len(original)
    plate_half = (40.0, 30.0)
    for f in final:
        edge = min(plate_half[0] - abs(f.centre[0]), plate_half[1] - abs(f.centre[1])) - f.radius_mm
        assert edge >= EDGE_MM - 1e-6


def test_evaluate_prints_table_and_writes(tmp_path, capsys, monkeypatch):
    no_report(monkeypatch)
    results = evaluate_study(copy.deepcopy(SMALL), tmp_path / "ev", echo=True)
    text = capsys.readouterr().out
    assert "FOV cone" in text and "worst pose" in text and "resolvability" in text
    assert results["measures"]["before"]["per_feature"][0]["name"]
    assert json.loads((tmp_path / "ev" / "results.json").read_text())["evaluation_only"] is True
    single = evaluate_study(copy.deepcopy(SMALL), pose=5)
    assert single["trajectory"]["n_samples"] == 1
    assert len(single["measures"]["before"]["per_pose"]["resolvability"]) == 1


def test_evaluate_bad_pose():
    from cadfeat.study.schema import StudyError

    with pytest.raises(StudyError, match="--pose 99"):
        evaluate_study(copy.deepcopy(SMALL), pose=99)


def test_studies_folder_validates():
    """Every study in studies/ passes validation (names, bounds, files)."""
    from cadfeat.study.schema import load_study

    folder = Path(__file__).resolve().parents[2] / "studies"
    files = sorted(folder.glob("*.toml"))
    assert len(files) >= 6
    for f in files:
        assert load_study(f).study.name == f.stem


def test_step_data_is_shared():
    assert STEP.exists() and DATA.is_dir()


def _step_study(**design) -> dict:
    data = copy.deepcopy(SMALL)
    data["study"] = {"name": "step_plate", "part": str(STEP), "seed": 2}
    data["design"] = {"holes": [{"select": "H1", "max_offset_mm": 6.0}, {"select": "H2", "max_offset_mm": 6.0}],
                      **design}
    data["trajectory"]["target"] = [0.0, 0.0, 10.0]
    return data


def test_step_pattern_moves_together(tmp_path, monkeypatch):
    """Two STEP holes in a pattern share one offset: one pair of variables, the same displacement of both
    holes in the re-imported STEP."""
    from cadfeat.cad.export import import_step
    from cadfeat.cad.features import extract_holes

    no_report(monkeypatch)
    result = run_study(_step_study(patterns=[["H1", "H2"]]), tmp_path / "out", quiet=True)
    assert [v["name"] for v in result.results["variables"]] == ["H1.s", "H1.t"]
    before = {h["name"]: np.array(h["centre_mm"]) for h in result.results["holes"]["before"]}
    final = extract_holes(import_step(tmp_path / "out" / "optimised.step"))
    moves = []
    for name in ("H1", "H2"):
        c = np.array([f.centre for f in final])
        k = int(np.argmin(np.linalg.norm(c - before[name], axis=1)))
        moves.append(c[k] - before[name])
    np.testing.assert_allclose(moves[0], moves[1], atol=1e-6)


def test_symmetry_the_part_does_not_have(tmp_path):
    from cadfeat.study.schema import StudyError

    data = _step_study()
    data["constraints"]["symmetry"] = "y"  # H1 (Ø8) and H2 (Ø6) mirror in position but not in size
    with pytest.raises(StudyError, match="constraints.symmetry: no two movable holes mirror"):
        run_study(data, tmp_path / "out", quiet=True)
    assert not (tmp_path / "out").exists()


def test_pareto_study_front_is_non_dominated_and_the_chosen_design_is_exported(tmp_path, monkeypatch):
    """combine = "pareto": the front in results.json is mutually non-dominated (checked here by brute force),
    the exported design's objectives are the chosen front point, and the STEP still keeps every requirement."""
    no_report(monkeypatch)
    spec = copy.deepcopy(SMALL)
    spec["study"]["name"] = "small_pareto"
    spec["objective"]["combine"] = "pareto"
    spec["optimizer"] = {"method": "pareto"}
    spec["shop"] = {"grid_mm": 0.0, "hole_sizes": "none"}  # the front point itself, not rounded for the shop
    out = tmp_path / "pareto"
    results = run_study(spec, out, quiet=True).results
    front = results["pareto"]
    points = np.array(front["points"], dtype=float)
    assert len(front["names"]) == 3 and points.shape[1] == 3 and len(points) >= 2
    better_eq = (points[:, None, :] >= points[None, :, :]).all(-1)   # maximised objectives
    strictly = (points[:, None, :] > points[None, :, :]).any(-1)
    assert not (better_eq & strictly).any(), "a front point dominates another"
    chosen = points[front["chosen"]]
    after = np.array([results["objectives"]["after"][n] for n in front["names"]])
    np.testing.assert_allclose(after, chosen, rtol=1e-6, atol=1e-9)
    assert all(c["ok"] for c in results["constraints"])


def test_results_schema_version_poses_and_requirements_used(small_run):
    """Issue 13: schema_version, the sampled camera poses (equal to the trajectory built directly from the
    study's table) and every requirement the optimiser used verified on the B-rep and the STEP."""
    from cadfeat.study.outputs import SCHEMA_VERSION
    from cadfeat.trajectory import straight_approach

    _, out, _ = small_run
    data = json.loads((out / "results.json").read_text())
    assert data["schema_version"] == SCHEMA_VERSION >= 2
    t = SMALL["trajectory"]
    traj = straight_approach(start=t["start"], end=t["end"], target=t["target"], n=t["n"], duration_s=t["duration_s"])
    np.testing.assert_allclose(data["trajectory"]["T_task_cam"], traj.T_task_cam, atol=1e-8)
    np.testing.assert_allclose(data["trajectory"]["time_s"], traj.times_s, atol=1e-9)
    rb = data["robustness"]
    assert rb["names"] == data["objectives"]["names"] and rb["samples"] == 200
    for block in ("manufacturing", "camera"):
        for name in (*rb["names"], "combined"):
            s = rb[block][name]
            assert s["min"] <= s["p05"] <= s["mean"] + 1e-12 and np.isfinite(s["nominal"])
    assert rb["manufacturing"]["combined"]["nominal"] == pytest.approx(data["objectives"]["combined_after"],
                                                                        rel=1e-9)
    used = {(u["name"], tuple(sorted(u["holes"]))) for u in data["requirements_used"]}
    assert used and all(isinstance(u["margin"], float) for u in data["requirements_used"])
    for where in ("brep", "step"):
        checked = {(c["name"], tuple(sorted(c["holes"]))) for c in data["constraints"] if c["checked_on"] == where}
        assert used <= checked, (where, used - checked)


def test_version_flag(capsys):
    from cadfeat import __version__
    from cadfeat.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"cadfeat {__version__}"


@pytest.fixture(scope="module")
def shop_run(tmp_path_factory):
    """The small plate with the hole diameter and pitch free too: the optimum is rounded for the shop."""
    cfg = copy.deepcopy(SMALL)
    cfg["design"]["parameters"].update(diameter={"lower": 2.0, "upper": 6.0}, pitch={"lower": 7.0, "upper": 12.0})
    out = tmp_path_factory.mktemp("shop") / "shop"
    mp = pytest.MonkeyPatch()
    no_report(mp)
    try:
        result = run_study(cfg, out, quiet=True)
    finally:
        mp.undo()
    return result, out


def test_exported_step_is_shop_ready(shop_run):
    """Issue 13: the re-imported optimised.step has every moved hole on the 0.1 mm grid and every resized hole
    at an ISO 273 medium clearance diameter (values typed from the standard here: M3 3.4, M4 4.5, M5 5.5, M6 6.6),
    holes.csv lists exactly those holes, and every requirement holds on the B-rep and the STEP after rounding."""
    import csv

    from cadfeat.cad.export import import_step
    from cadfeat.cad.features import extract_holes

    result, out = shop_run
    data = json.loads((out / "results.json").read_text())
    shop = data["shop"]
    assert shop["applied"] and shop["grid_mm"] == 0.1 and shop["hole_sizes"] == "iso273-medium"
    assert shop["x_optimum"] != shop["x_shop"]
    holes = extract_holes(import_step(out / "optimised.step"), prefer_direction=(0, 0, 1))
    dowel = [h for h in holes if np.allclose(h.centre[:2], FIXED_HOLE[:2], atol=1e-6)]
    row = [h for h in holes if h not in dowel]
    assert len(dowel) == 1 and len(row) == 3
    for h in row:
        xy = np.asarray(h.centre[:2])
        np.testing.assert_allclose(xy, np.round(xy, 1), atol=1e-6)
        assert min(abs(2 * h.radius_mm - d) for d in (3.4, 4.5, 5.5, 6.6)) < 1e-6, 2 * h.radius_mm
    with (out / "holes.csv").open() as f:
        table = list(csv.DictReader(f))
    assert len(table) == len(holes)
    for h in holes:
        match = [r for r in table if np.allclose([float(r["x_mm"]), float(r["y_mm"]), float(r["z_mm"])], h.centre,
                                                 atol=1e-3)]
        assert len(match) == 1 and float(match[0]["diameter_mm"]) == pytest.approx(2 * h.radius_mm, abs=1e-3)
        assert match[0]["face"] == "+Z"
    assert all(c["ok"] for c in data["constraints"])
    assert {c["checked_on"] for c in data["constraints"]} == {"brep", "step"}
    assert data["holes"]["after"][1]["centre_mm"][0] == pytest.approx(round(shop["x_shop"]["x0"], 1), abs=1e-6)


def test_shop_rounding_on_a_nonlinear_part(tmp_path, monkeypatch):
    """The DN50 flange's target holes sit at a polar angle (a nonlinear map): the rounded design is refined on
    the real CAD rebuild; the re-imported STEP has the two targets within 1e-3 mm of the 0.1 mm grid, at an
    ISO 273 medium diameter, still diametrically opposite (their pattern), every requirement holding."""
    from cadfeat.cad.export import import_step
    from cadfeat.cad.features import extract_holes

    no_report(monkeypatch)
    cfg = {"study": {"name": "flange_shop", "part": str(Path(__file__).parents[2] / "parts" / "pipe_flange_dn50.py"),
                     "seed": 2},
           "camera": {"preset": "realsense-d435-rgb", "focus_distance_mm": 300.0},
           "trajectory": {"kind": "straight_approach", "start": [-120.0, -150.0, 380.0], "end": [100.0, -60.0, 300.0],
                          "target": [0.0, 0.0, 18.0], "n": 12, "duration_s": 2.0},
           "design": {"parameters": {"target_angle_rad": {}, "target_radius_mm": {}, "target_circle_radius_mm": {}}},
           "constraints": {"edge_distance_mm": 3.0, "ligament_mm": 3.0},
           # (normalised by the initial design: an optimum with the polar angle inside its bounds, so both drawing
           # coordinates of each target can reach the grid; at an angle bound only one can, and the shop note says so)
           "objective": {"measures": ["fov", "resolution", "resolvability"], "aggregate": "sum", "combine": "maxmin",
                         "normalisation": "initial"},
           "optimizer": {"method": "multistart", "starts": 2, "maxiter": 25}, "robustness": {"robust": False}}
    result = run_study(cfg, tmp_path / "out", quiet=True)
    shop = result.results["shop"]
    assert shop["applied"] and shop["rebuilt_off_target_mm"] < 1e-3
    holes = extract_holes(import_step(tmp_path / "out" / "optimised.step"), prefer_direction=(0, 0, 1))
    targets = [h for h in holes if h.depth_mm < 5.0]  # the 4 mm deep blind targets
    assert len(targets) == 2
    for h in targets:
        np.testing.assert_allclose(h.centre[:2], np.round(h.centre[:2], 1), atol=1e-3)
        assert min(abs(2 * h.radius_mm - d) for d in (4.5, 5.5, 6.6, 9.0)) < 1e-6
    np.testing.assert_allclose(targets[0].centre[:2], -targets[1].centre[:2], atol=2e-3)
    assert all(c["ok"] for c in result.results["constraints"])
    assert [p["broken"] for p in result.results["patterns"]] == [False]


def test_flagship_requirements_are_checked_under_the_holes_own_names(tmp_path, monkeypatch):
    """The B-rep/STEP checks re-extract holes in geometric order; each must carry the design hole's own name
    (nema17: extraction order and the part's names differ), so every requirement the optimiser used is found
    verified under the same holes, and the 'fixed' checks name exactly the holes the results call fixed."""
    import tomllib

    no_report(monkeypatch)
    root = Path(__file__).parents[2]
    cfg = tomllib.loads((root / "studies" / "nema17_mount.toml").read_text())
    cfg["study"]["part"] = str(root / "parts" / "nema17_mount.py")
    cfg["trajectory"]["n"] = 12
    cfg["optimizer"].update(starts=2, maxiter=20)
    cfg["robustness"] = {"samples": 0, "robust": False}
    data = run_study(cfg, tmp_path / "out", quiet=True).results
    names = [h["name"] for h in data["holes"]["after"]]
    fixed = {h["name"] for h in data["holes"]["after"] if h["fixed"]}
    used = {(u["name"], tuple(sorted(u["holes"]))) for u in data["requirements_used"]}
    assert used
    for where in ("brep", "step"):
        checks = [c for c in data["constraints"] if c["checked_on"] == where]
        assert used <= {(c["name"], tuple(sorted(c["holes"]))) for c in checks}, where
        assert {h for c in checks if c["name"] == "fixed" for h in c["holes"]} <= fixed
        assert all(h in names for c in checks for h in c["holes"])


def test_score_design_of_the_delivered_values_is_the_runs_after(small_run):
    """The public API (issue 17): ``score_design`` of the run's delivered variables rebuilds the same CAD model and
    scores it as the run did — the same objectives, combined value and kept requirements, holes at the exported
    positions; an unknown variable or a value out of bounds is one error naming the key and what is allowed."""
    from cadfeat.study import score_design
    from cadfeat.study.schema import StudyError

    result, _, _ = small_run
    r = result.results
    values = {v["name"]: v["after"] for v in r["variables"]}
    s = score_design(copy.deepcopy(SMALL), values)
    assert s["values"] == pytest.approx(values, abs=1e-9)
    assert s["objectives"] == pytest.approx(r["objectives"]["after"], rel=1e-9, abs=1e-12)
    assert s["combined"] == pytest.approx(r["objectives"]["combined_after"], rel=1e-9)
    brep = [c for c in r["constraints"] if c.get("checked_on") == "brep"]
    assert s["requirements_hold"] and [c["name"] for c in s["requirements"]] == [c["name"] for c in brep]
    assert [c["value"] for c in s["requirements"]] == pytest.approx([c["value"] for c in brep], rel=1e-9, abs=1e-9)
    for got, want in zip(s["holes"], r["holes"]["after"], strict=True):
        assert got["centre_mm"] == pytest.approx(want["centre_mm"], abs=1e-6)
        assert got["radius_mm"] == pytest.approx(want["radius_mm"], abs=1e-6)
    with pytest.raises(StudyError, match=r"design variable\(s\) z9 not in the study; allowed: x0, y0"):
        score_design(copy.deepcopy(SMALL), {"z9": 1.0})
    with pytest.raises(StudyError, match=r"x0=5.0 is not allowed; allowed: a number in \[-18, -4\] mm"):
        score_design(copy.deepcopy(SMALL), {"x0": 5.0})


def test_score_design_refuses_a_bad_script_design_before_any_cad_work(monkeypatch):
    """A part script's design values are checked against the study's parameters before its set-up builds anything:
    an integer parameter given 2.5 or outside its bounds, an unknown name, a value out of bounds."""
    from cadfeat.study import score_design
    from cadfeat.study import setup as setup_mod
    from cadfeat.study.schema import StudyError

    def no_cad(*a, **k):
        raise AssertionError("set-up (CAD work) started before the design values were checked")

    monkeypatch.setattr(setup_mod, "setup_study", no_cad)
    data = copy.deepcopy(SMALL)
    data["design"]["parameters"]["count"] = {"lower": 2, "upper": 4}
    with pytest.raises(StudyError, match=r"count=2.5 is not allowed; allowed: an integer in \[2, 4\]"):
        score_design(data, {"count": 2.5})
    with pytest.raises(StudyError, match=r"count=5 is not allowed; allowed: an integer in \[2, 4\]"):
        score_design(data, {"count": 5})
    with pytest.raises(StudyError, match=r"design variable\(s\) z9 not in the study; allowed: x0, y0, count"):
        score_design(data, {"z9": 1.0})
    with pytest.raises(StudyError, match=r"y0=20 is not allowed; allowed: a number in \[-8, 12\] mm"):
        score_design(data, {"y0": 20})
