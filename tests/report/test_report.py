"""report.html and its plots, from a results dict computed on a real CadQuery plate (tests/report_fixture.py).

Independent references: the page is read back with html.parser and compared with the results dict; file
hashes with hashlib on the exported files; the hole move with the construction value of the rebuilt plate;
PNGs decoded with Pillow (pixel variance); escaping by searching the raw text.
"""

from __future__ import annotations

import copy
import hashlib
import logging
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from report_fixture import shared_case
from report_html import parse_report

import cadfeat
from cadfeat.report import ReportContext, build_report, write_report
from cadfeat.report.tables import FEATURE_COLUMNS

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def case():
    return shared_case()


@pytest.fixture(scope="module")
def report(case, tmp_path_factory):
    """The report of the plate study without renders (context None): plots and tables only."""
    _, results, _ = case
    out = tmp_path_factory.mktemp("report")
    built = build_report(out, copy.deepcopy(results), None)
    return built, parse_report(built.path), results


def _lean(results: dict, keep: tuple[str, ...] = ()) -> dict:
    """A deep copy without the data of the plots (except ``keep``): for tests about tables and renders."""
    out = copy.deepcopy(results)
    for key in ("history", "sweep", "pareto"):
        if key not in keep:
            out[key] = None
    if "per_pose" not in keep:
        for block in out["measures"].values():
            block["per_pose"] = {}
    return out


def _png_std(path: Path) -> float:
    return float(np.asarray(Image.open(path).convert("L"), dtype=float).std())


def _value(cell) -> float:
    assert cell.value is not None, f"cell {cell.text!r} has no data-value"
    return cell.value


# ------------------------------------------------------------------------------------------------ structure
def test_every_image_embedded_and_written_beside(report):
    """Self-contained by default: each <img> is a data URI holding exactly the bytes of its PNG in img/."""
    import base64

    built, page, _ = report
    assert page.images, "the report has no images"
    for src, data in zip(page.images, page.image_srcs, strict=True):
        assert not Path(src).is_absolute() and not src.startswith(("http:", "https:", "file:")), src
        assert (built.path.parent / src).is_file(), f"missing image {src}"
        assert data.startswith("data:image/png;base64,")
        assert base64.b64decode(data.split(",", 1)[1]) == (built.path.parent / src).read_bytes()


def test_linked_images_when_not_self_contained(case, tmp_path):
    _, results, _ = case
    built = build_report(tmp_path, _lean(results, keep=("history",)), None, self_contained=False)
    page = parse_report(built.path)
    assert page.image_srcs == page.images == ["img/convergence.png"]
    assert page.scripts == 0, "report.html must not need JavaScript"


def test_all_plots_written_non_blank(report):
    built, _, _ = report
    names = sorted(p.name for p in built.images)
    assert names == sorted(f"{k}.png" for k in ("tracks", "pose_measures", "motion", "convergence", "sweep",
                                                "pareto"))
    for path in built.images:
        img = Image.open(path)
        assert img.width > 300 and img.height > 200
        assert _png_std(path) > 10.0, f"{path.name} looks blank"
    assert built.notes == ["Renders skipped: the report was written without the part shapes (no report context), "
                           "e.g. from results.json alone."]


def test_plots_are_deterministic(report, tmp_path):
    built, _, results = report
    again = build_report(tmp_path, copy.deepcopy(results), None)
    for a, b in zip(sorted(built.images), sorted(again.images), strict=True):
        assert a.name == b.name and a.read_bytes() == b.read_bytes(), a.name


# ------------------------------------------------------------------------------------------------ numbers
def test_feature_table_matches_results(report):
    _, page, results = report
    rows = page.tables["features"]
    before = results["measures"]["before"]["per_feature"]
    after = results["measures"]["after"]["per_feature"]
    assert [r.cells[0].text for r in rows] == [f["name"] for f in after]
    for row, fb, fa in zip(rows, before, after, strict=True):
        for k, (key, _) in enumerate(FEATURE_COLUMNS):
            cb, ca = row.cells[1 + 2 * k], row.cells[2 + 2 * k]
            assert _value(cb) == pytest.approx(fb[key], rel=1e-15)
            assert _value(ca) == pytest.approx(fa[key], rel=1e-15)
            assert float(ca.text) == pytest.approx(fa[key], rel=1e-3, abs=1e-12)  # shown with 4 digits


def test_objectives_and_combined(report):
    _, page, results = report
    obj = results["objectives"]
    rows = {r.cells[0].text: r.cells for r in page.tables["objectives"]}
    assert list(rows) == obj["names"]
    for name, cells in rows.items():
        assert _value(cells[1]) == obj["before"][name] and _value(cells[2]) == obj["after"][name]
        assert _value(cells[3]) == pytest.approx(obj["after"][name] - obj["before"][name])
        if obj["after"][name] > obj["before"][name]:
            assert cells[3].css == "better"
    assert float(page.by_id["combined-before"]) == pytest.approx(obj["combined_before"], rel=1e-3)
    assert float(page.by_id["combined-after"]) == pytest.approx(obj["combined_after"], rel=1e-3)


def test_moves_table_against_the_cad_rebuild(report):
    """Hole A was rebuilt shifted by dx_A along x: the report's move is |dx_A|, the others 0 (CAD extraction)."""
    _, page, results = report
    dx = results["variables"][0]["after"]
    assert dx != 0.0
    rows = {r.cells[0].text: r for r in page.tables["moves"]}
    assert _value(rows["A"].cells[4]) == pytest.approx(abs(dx), abs=1e-6)
    assert rows["A"].css == "moved"
    for name in "BCD":
        assert _value(rows[name].cells[4]) == pytest.approx(0.0, abs=1e-6)
    assert _value(rows["C"].cells[5]) == pytest.approx(10.0, abs=1e-6)  # Ø of the 5 mm radius hole
    var = page.tables["variables"][0].cells
    assert var[0].text == "dx_A" and _value(var[5]) == dx


def test_constraints_design_matrix_files(report, case):
    out, results, _ = case
    _, page, _ = report
    rows = page.tables.get("constraints", []) + page.tables.get("constraints-trivial", [])
    assert len(rows) == len(results["constraints"])  # one check each (B-rep or STEP): one row each
    names = {h["index"]: h["name"] for h in results["holes"]["after"]}
    by_key = {(r.cells[0].text, r.cells[1].text): r for r in rows}
    for c in results["constraints"]:
        row = by_key[(c["name"], ", ".join(sorted(names[h] for h in c["holes"])))]
        # columns: name, holes, required, unit, B-rep value/margin, STEP value/margin, status
        col = 4 if c["checked_on"] == "brep" else 6
        assert _value(row.cells[col]) == c["value"] and _value(row.cells[col + 1]) == c["margin"]
        assert row.css in (("ok", "active") if c["ok"] else ("violated",))
        assert (row.css == "active") == (c["ok"] and c["margin"] < 0.1)
    assert page.by_id["coupling-verdict"] == "uncoupled"
    matrix = [[_value(c) for c in r.cells[1:]] for r in page.tables["design-matrix"]]
    assert matrix == results["design_matrix"]["matrix"]
    files = {r.cells[0].text: r.cells for r in page.tables["files"]}
    for name in ("original.step", "optimised.step"):
        data = (out / name).read_bytes()
        assert files[name][2].text == hashlib.sha256(data).hexdigest()
        assert _value(files[name][1]) == len(data)
    assert {r.cells[0].text for r in page.tables["versions"]} == {"numpy", "cadquery", "matplotlib"}
    assert {"report: plots", "report: renders", "build"} <= {r.cells[0].text for r in page.tables["timings"]}


# ------------------------------------------------------------------------------------------------ edge cases
def test_strings_are_escaped(case, tmp_path):
    _, results, _ = case
    results = _lean(results)
    evil = '<script>alert("x")</script>'
    results["measures"]["after"]["per_feature"][0]["name"] = evil
    results["constraints"][0]["name"] = evil
    results["files"][0]["name"] = evil
    raw = write_report(tmp_path, results, None).read_text()
    assert "<script" not in raw
    assert "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;" in raw
    assert "plate_&lt;demo&gt; &amp; co" in raw  # the study name of the fixture
    page = parse_report(tmp_path / "report.html")
    assert page.tables["features"][0].cells[0].text == evil


def test_violated_requirement_and_interrupted_warning(case, tmp_path):
    _, results, _ = case
    results = _lean(results)
    results["constraints"][1].update(value=3.0, margin=-2.0, ok=False)
    results["interrupted"] = True
    page = parse_report(write_report(tmp_path, results, None))
    classes = [r.css for r in page.tables["constraints"]]
    assert classes[0] == "violated" and classes.count("violated") == 1  # violated rows come first
    assert page.tables["constraints"][0].cells[-1].text == "VIOLATED"
    text = "".join(page.text)
    assert "interrupted" in text and "1 of 5 kept requirements are violated" in text
    assert page.by_id["verdict"] == "do not adopt"


def test_absent_data_skips_plots_and_sections(tmp_path, caplog):
    results = {"study": {"name": "bare"}, "sweep": None, "pareto": None, "history": [], "interrupted": False}
    with caplog.at_level(logging.WARNING):
        built = build_report(tmp_path, results, None)
    assert built.path.is_file() and built.images == []
    assert not list((tmp_path / "img").iterdir())
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
    page = parse_report(built.path)
    assert page.images == [] and "features" not in page.tables


def test_malformed_section_becomes_a_note(case, tmp_path, caplog):
    _, results, _ = case
    results = _lean(results, keep=("sweep",))
    results["design_matrix"]["matrix"] = [[1.0, 2.0], [3.0]]  # ragged
    results["sweep"]["values"] = "not numbers"
    with caplog.at_level(logging.WARNING):
        built = build_report(tmp_path, results, None)
    raw = built.path.read_text()
    assert "This section could not be built" in raw and "plot_sweep skipped" in raw
    assert "features" in parse_report(built.path).tables  # the rest is still there
    assert any("appendix" in r.getMessage() for r in caplog.records)  # the design matrix is in the appendix


# ------------------------------------------------------------------------------------------------ renders
def _fake_render(fail: bool) -> types.ModuleType:
    """Stand-in for cadfeat.render (the render helper's module) following contracts.md."""
    mod = types.ModuleType("cadfeat.render")

    def _png(path: Path, seed: int) -> Path:
        rng = np.random.default_rng(seed)
        Image.fromarray(rng.integers(0, 255, (60, 80, 3), dtype=np.uint8)).save(path)
        return path

    def render_comparison(shape_before, shape_after, holes_before, holes_after, fixed, out_dir, *, trajectory=None,
                          camera=None, T_task_part=None, n_frusta=5, closeup=False):
        if fail:
            raise RuntimeError("no EGL display")
        assert len(fixed) == len(holes_before) and trajectory is not None and camera is not None
        out_dir = Path(out_dir)
        out = {"before": _png(out_dir / "part_before.png", 1), "after": _png(out_dir / "part_after.png", 2)}
        if closeup:
            out.update(before_closeup=_png(out_dir / "closeup_before.png", 3),
                       after_closeup=_png(out_dir / "closeup_after.png", 4))
        return out

    def render_camera_views(shape, holes, camera, T_cam_part, out_dir, prefix, *, overlay=True):
        if fail:
            raise RuntimeError("no EGL display")
        assert T_cam_part.shape[1:] == (4, 4)
        mod.calls.append(np.asarray(T_cam_part))
        return [_png(Path(out_dir) / f"{prefix}_{k}.png", k) for k in range(len(T_cam_part))]

    mod.render_comparison, mod.render_camera_views, mod.calls = render_comparison, render_camera_views, []
    return mod


def test_render_wiring(case, tmp_path, monkeypatch):
    _, results, context = case
    fake = _fake_render(fail=False)
    monkeypatch.setitem(sys.modules, "cadfeat.render", fake)
    monkeypatch.setattr(cadfeat, "render", fake, raising=False)
    built = build_report(tmp_path, _lean(results), context)
    page = parse_report(built.path)
    L = len(context.trajectory)
    assert context.samples() == [0, L // 2, L - 1]  # without results: first, middle, last
    # with results: the camera views at each hole's worst pose, at inv(T_task_cam) @ T_task_part
    worst = sorted({f["worst_pose"] for f in results["measures"]["after"]["per_feature"]})
    expected = np.linalg.inv(context.trajectory.T_task_cam[worst])
    np.testing.assert_allclose(fake.calls[0], expected, atol=1e-9)
    for name in ("part_before.png", "part_after.png", "view_before_0.png", f"view_after_{len(worst) - 1}.png"):
        assert f"img/{name}" in page.images
    for src in page.images:
        assert (tmp_path / src).is_file()
    assert len(page.images) == 2 + 2 + 2 * len(worst)
    text = "".join(page.text)
    for f in results["measures"]["after"]["per_feature"]:
        assert "worst pose of" in text and f["name"] in text
    # the close-up pair comes first, above the trajectory overview
    assert page.images[:4] == ["img/closeup_before.png", "img/closeup_after.png", "img/part_before.png",
                               "img/part_after.png"]


def test_render_failure_still_writes_the_report(case, tmp_path, monkeypatch, caplog):
    _, results, context = case
    fake = _fake_render(fail=True)
    monkeypatch.setitem(sys.modules, "cadfeat.render", fake)
    monkeypatch.setattr(cadfeat, "render", fake, raising=False)
    ctx = ReportContext(**{**context.__dict__, "sample_indices": [-1, 3]})
    assert ctx.samples() == [3, len(context.trajectory) - 1]
    with caplog.at_level(logging.WARNING):
        path = write_report(tmp_path, _lean(results, keep=("history",)), ctx)
    raw = path.read_text()
    assert "No renders of the part" in raw and "no EGL display" in raw
    assert sum("not rendered" in r.getMessage() for r in caplog.records) == 3
    assert parse_report(path).images == ["img/convergence.png"]  # the plot, no renders


def test_import_is_light():
    code = ("import sys, cadfeat.report; "
            "print(sorted(m for m in ('cadquery', 'pyvista', 'matplotlib', 'vtk') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == "[]"


def test_cli_report_from_results_json(case, tmp_path):
    """`cadfeat report results.json` writes the page beside it (JSON round trip of the results)."""
    import json

    from cadfeat.cli import main

    _, results, _ = case
    path = tmp_path / "results.json"
    path.write_text(json.dumps(_lean(results, keep=("pareto",))))
    assert main(["report", str(path)]) == 0
    page = parse_report(tmp_path / "report.html")
    assert page.images == ["img/pareto.png"] and len(page.tables["features"]) == 4
    (tmp_path / "bad.json").write_text("[1, 2")
    assert main(["report", str(tmp_path / "bad.json")]) == 2
    assert main(["report", str(tmp_path / "missing.json")]) == 2


def _evaluation(results: dict) -> dict:
    """What `cadfeat evaluate` writes: the current design only (no after, no optimisation data)."""
    out = _lean(results, keep=("per_pose",))
    out["evaluation_only"] = True
    for key in ("constraints", "design_matrix", "variables"):
        out.pop(key)
    out["holes"].pop("after")
    out["measures"].pop("after")
    out["objectives"] = {k: v for k, v in out["objectives"].items() if k in ("names", "combine", "aggregate",
                                                                              "before")}
    return out


def test_evaluation_only_report(case, tmp_path, monkeypatch):
    _, results, context = case
    fake = _fake_render(fail=False)
    fake.render_part = lambda shape, path, holes=None, **kw: Image.new("RGB", (40, 30), "gray").save(path) or path
    monkeypatch.setitem(sys.modules, "cadfeat.render", fake)
    monkeypatch.setattr(cadfeat, "render", fake, raising=False)
    ctx = ReportContext(shape_before=context.shape_before, holes_before=context.holes_before,
                        camera=context.camera, trajectory=context.trajectory, sample_indices=[5])
    evaluation = _evaluation(results)
    # the study's evaluate also passes the current design as "after" (same values, same shape): shown once
    as_passed = {**evaluation, "holes": {**evaluation["holes"], "after": evaluation["holes"]["before"]},
                 "measures": {"before": evaluation["measures"]["before"], "after": evaluation["measures"]["before"]},
                 "objectives": {**evaluation["objectives"], "after": evaluation["objectives"]["before"]}}
    ctx = ReportContext(**{**ctx.__dict__, "shape_after": ctx.shape_before, "holes_after": ctx.holes_before})
    built = build_report(tmp_path, as_passed, ctx)
    page = parse_report(built.path)
    raw = built.path.read_text()
    assert "cadfeat evaluation" in raw and "nothing was optimised" in raw
    assert sorted(page.images) == ["img/motion.png", "img/part.png", "img/pose_measures.png", "img/tracks.png",
                                   "img/view_current_0.png"]
    before = evaluation["measures"]["before"]["per_feature"]
    for row, f in zip(page.tables["features"], before, strict=True):
        assert len(row.cells) == 1 + len(FEATURE_COLUMNS)
        assert [_value(c) for c in row.cells[1:]] == [f[k] for k, _ in FEATURE_COLUMNS]
    values = {r.cells[0].text: _value(r.cells[1]) for r in page.tables["objectives"]}
    assert values == evaluation["objectives"]["before"]


def test_plots_in_a_child_process_match(report, tmp_path, monkeypatch):
    """parallel=True draws the same plots (identical bytes) in `python -m cadfeat.report.plots`."""
    built, _, results = report
    fake = _fake_render(fail=False)
    monkeypatch.setitem(sys.modules, "cadfeat.render", fake)
    monkeypatch.setattr(cadfeat, "render", fake, raising=False)
    _, _, context = shared_case()
    out = build_report(tmp_path, _lean(results, keep=("pareto", "history")), context, parallel=True)
    assert "plots: wait" in out.timings_s and out.notes == []
    plots = {p.name: p for p in out.images if not p.stem.startswith(("part_", "closeup_", "view_"))}
    assert sorted(plots) == ["convergence.png", "pareto.png"]
    for p in built.images:
        if p.name in plots:
            assert plots[p.name].read_bytes() == p.read_bytes(), p.name


def test_render_inputs_camera_from_results_and_part_pose(case, tmp_path, monkeypatch):
    """Without a camera in the context the renders get the results' camera; camera views use
    inv(T_task_cam) @ T_task_part for a part that is not at the task origin."""
    from scipy.spatial.transform import Rotation

    _, results, context = case
    seen = {}
    fake = _fake_render(fail=False)
    views = fake.render_camera_views

    def spy(shape, holes, camera, T_cam_part, out_dir, prefix, **kw):
        seen["camera"] = camera
        return views(shape, holes, camera, T_cam_part, out_dir, prefix, **kw)

    fake.render_camera_views = spy
    monkeypatch.setitem(sys.modules, "cadfeat.render", fake)
    monkeypatch.setattr(cadfeat, "render", fake, raising=False)
    T_task_part = np.eye(4)
    T_task_part[:3, :3] = Rotation.from_euler("zyx", [30, -10, 5], degrees=True).as_matrix()
    T_task_part[:3, 3] = [12.0, -7.0, 3.0]
    ctx = ReportContext(**{**context.__dict__, "camera": None, "T_task_part": T_task_part, "sample_indices": [4]})
    build_report(tmp_path, _lean(results), ctx)
    assert seen["camera"] == context.camera
    expected = np.linalg.inv(context.trajectory.T_task_cam[4]) @ T_task_part
    np.testing.assert_allclose(fake.calls[0][0], expected, atol=1e-9)


# ------------------------------------------------------------------------------------------------ verdict
def test_verdict_rules_on_modified_results(case, tmp_path):
    """Each rule moves the decision the way the report states (independent cases built by hand)."""
    from cadfeat.report.verdict import decide

    _, results, _ = case
    base = _lean(results)
    for c in base["constraints"]:  # room to spare everywhere: only the objectives decide
        c.update(margin=max(c["margin"], 1.0), ok=True)
    base["objectives"].update(combined_before=1.0, combined_after=1.5, before={"g": 1.0}, after={"g": 1.5},
                              names=["g"])
    base["measures"]["after"] = copy.deepcopy(base["measures"]["before"])
    assert decide(base).decision == "adopt"
    worse = copy.deepcopy(base)
    worse["objectives"]["combined_after"] = 0.999
    assert decide(worse).decision == "do not adopt"
    active = copy.deepcopy(base)
    active["constraints"][0].update(margin=1e-6)
    assert decide(active).decision == "adopt with care"
    failing = copy.deepcopy(base)
    failing["measures"]["before"]["per_feature"][0]["focus_min"] = 0.2
    failing["measures"]["after"]["per_feature"][0]["focus_min"] = -0.1
    v = decide(failing)
    assert v.decision == "adopt with care" and any(c.newly_failing and c.hole == "A" for c in v.changes)
    unverified = copy.deepcopy(base)
    unverified["requirements_used"] = [{"name": "ligament", "holes": ["A", "C"], "margin": 0.0}]
    assert decide(unverified).decision == "do not adopt"
    tracked = copy.deepcopy(base)
    tracked["tracking"] = {"verdicts": {"ekf": {"verdict": "better"}, "iekf": {"verdict": "mixed"}}}
    assert decide(tracked).decision == "adopt with care"
    tracked["tracking"] = {"verdicts": {"ekf": {"verdict": "better"}, "iekf": {"verdict": "no significant difference"}}}
    assert decide(tracked).decision == "adopt"
    page = parse_report(write_report(tmp_path, failing, None))
    assert page.by_id["verdict"] == "adopt with care"
    changes = {(r.cells[0].text, r.cells[1].text): r for r in page.tables["hole-changes"]}
    row = changes[("A", "focus margin")]
    assert _value(row.cells[3]) == 0.2 and _value(row.cells[4]) == -0.1 and row.cells[6].text == "newly failing"


def test_verdict_tracking_worse_is_decisive(case):
    """Issue 17: a design that tracks significantly worse in the closed loop is "do not adopt", even when every
    proxy objective improved and every other rule says adopt; "mixed" stays "adopt with care"."""
    from cadfeat.report.verdict import decide

    _, results, _ = case
    base = _lean(results)
    for c in base["constraints"]:
        c.update(margin=max(c["margin"], 1.0), ok=True)
    base["objectives"].update(combined_before=0.019, combined_after=0.949, before={"g": 0.019},
                              after={"g": 0.949}, names=["g"])
    base["measures"]["after"] = copy.deepcopy(base["measures"]["before"])
    assert decide(base).decision == "adopt"
    base["tracking"] = {"verdicts": {"pnp": {"verdict": "worse"}, "iekf": {"verdict": "better"}}}
    v = decide(base)
    assert v.decision == "do not adopt"
    assert {f.rule: f.outcome for f in v.findings}["tracking"] == "do not adopt"
    base["tracking"] = {"verdicts": {"pnp": {"verdict": "mixed"}, "iekf": {"verdict": "better"}}}
    assert decide(base).decision == "adopt with care"


def test_hole_table_matches_results(report):
    """The hole table lists holes.after: centre, Ø = 2 r, depth, face from the axis (+Z for this plate)."""
    _, page, results = report
    rows = page.tables["hole-table"]
    after = results["holes"]["after"]
    assert [r.cells[0].text for r in rows] == [h["name"] for h in after]
    for row, h in zip(rows, after, strict=True):
        assert row.cells[1].text in ("+Z", "-Z")
        assert [_value(c) for c in row.cells[2:5]] == pytest.approx(h["centre_mm"], abs=1e-12)
        assert _value(row.cells[5]) == pytest.approx(2 * h["radius_mm"]) and _value(row.cells[6]) == h["depth_mm"]
    assert [r.cells[8].text for r in rows] == ["yes", "", "", ""]  # only A moved (dx_A)


def test_broken_pattern_is_flagged(case, tmp_path):
    _, results, _ = case
    results = _lean(results)
    results["patterns"] = [
        {"kind": "bolt_circle", "holes": ["A", "B", "C"], "count": 3, "radius_mm": 20.0, "broken": True,
         "why": "off the circle by up to 6 mm or unevenly spaced"},
        {"kind": "mirror", "holes": ["C", "D"], "normal": [1.0, 0.0, 0.0], "broken": False, "why": ""}]
    page = parse_report(write_report(tmp_path, results, None))
    rows = page.tables["patterns"]
    assert [r.cells[3].text for r in rows] == ["BROKEN", "kept"] and rows[0].css == "violated"
    assert page.by_id["verdict"] in ("adopt with care", "do not adopt")
    rules = {r.cells[0].text.split(" ")[0]: r.cells[1].text for r in page.tables["verdict-rules"]}
    assert rules["A"] == "adopt with care"  # "A hole pattern of the original ... broken": the patterns rule


def test_robustness_table_and_razor_edge(case, tmp_path):
    _, results, _ = case
    results = _lean(results)
    block = {"g": {"nominal": 2.0, "mean": 1.9, "p05": 1.5, "min": 1.2},
             "combined": {"nominal": 1.2, "mean": 1.1, "p05": 1.01, "min": 0.9}}
    results["robustness"] = {"names": ["g"], "samples": 50, "position_tol_mm": 0.1, "size_steps": 1,
                             "camera_position_mm": 2.0, "camera_angle_deg": 1.0, "manufacturing": block,
                             "camera": block, "razor_edge": ["camera"]}
    page = parse_report(write_report(tmp_path, results, None))
    rows = {r.cells[0].text: r.cells for r in page.tables["robustness"]}
    assert list(rows) == ["g", "combined"]
    assert _value(rows["g"][2]) == 1.5 and _value(rows["g"][4]) == pytest.approx(-25.0)
    assert "Razor-edge optimum" in "".join(page.text)
    rules = {r.cells[0].text.split(" ")[2]: r.cells[1].text for r in page.tables["verdict-rules"]
             if r.cells[0].text.startswith("When the robustness")}
    assert rules == {"robustness": "adopt with care"}


def test_verdict_says_when_every_hole_is_out_of_focus(case):
    """Issue 13: every hole out of focus at its worst pose must be said, even when it was so before too."""
    from cadfeat.report.verdict import decide

    _, results, _ = case
    r = _lean(results)
    for which in ("before", "after"):
        for f in r["measures"][which]["per_feature"]:
            f["focus_min"] = -0.5
    holes = next(f for f in decide(r).findings if f.rule == "holes")
    n = len(r["measures"]["after"]["per_feature"])
    assert f"focus margin ({n} of {n} holes)" in holes.detail


def test_tracking_frames_are_embedded_too(case, tmp_path):
    """The closed loop's camera frames (``tracking/*.png`` beside results.json) are embedded as data URIs like
    every other image: a report mailed alone shows them (issue 32 item 8)."""
    import base64

    _, results, _ = case
    (tmp_path / "tracking").mkdir()
    frame = tmp_path / "tracking" / "before_frame_000.png"
    Image.fromarray(np.full((24, 32, 3), 90, np.uint8)).save(frame)
    data = _lean(results)
    data["tracking"] = {"settings": {"estimators": ["pnp"], "frames": 1, "runs": 1},
                        "frames": [{"path": "tracking/before_frame_000.png", "design": "before", "frame": 0,
                                    "time_s": 0.0, "detected": 3, "holes": 4}]}
    page = parse_report(build_report(tmp_path, data, None).path)
    embedded = [d for s, d in zip(page.images, page.image_srcs, strict=True) if s.endswith("before_frame_000.png")]
    assert len(embedded) == 1 and embedded[0].startswith("data:image/png;base64,")
    assert base64.b64decode(embedded[0].split(",", 1)[1]) == frame.read_bytes()


def test_physical_views_section_embeds_the_frames_and_names_the_misses(case, tmp_path):
    """"What the robot's camera will see": each physically rendered frame embedded, its caption naming the missed
    holes; absent without a ``physical_views`` section."""
    _, results, _ = case
    (tmp_path / "camera").mkdir()
    Image.fromarray(np.full((24, 32, 3), 120, np.uint8)).save(tmp_path / "camera" / "after_frame_009.png")
    data = _lean(results)
    data["physical_views"] = {"light": "ring", "material": "machined_aluminium", "hole_ends": "drilled",
                              "detector": "edcircles", "spp": 16, "noise_grey": 2.0,
                              "frames": [{"design": "after", "frame": 9, "time_s": 1.5, "expected": ["H1", "H2", "H7"],
                                          "detected": ["H1", "H2"], "missed": ["H7"],
                                          "path": "camera/after_frame_009.png"}]}
    built = build_report(tmp_path, data, None)
    text = built.path.read_text(encoding="utf-8")
    page = parse_report(built.path)
    assert "What the robot&#x27;s camera will see" in text or "What the robot's camera will see" in text
    assert "2 of 3 expected holes found; missed: H7" in text and "edcircles detector" in text
    src = [d for s, d in zip(page.images, page.image_srcs, strict=True) if s.endswith("after_frame_009.png")]
    assert len(src) == 1 and src[0].startswith("data:image/png;base64,")
    data.pop("physical_views")
    assert "camera will see" not in build_report(tmp_path / "none", data, None).path.read_text(encoding="utf-8")


def test_a_malformed_section_is_one_line_naming_the_key(case, tmp_path, caplog):
    """A hand-edited results.json (a section of the wrong type inside another) gives one line naming the record and
    key, the value and what was expected — not pydantic's multi-line dump with its link (issue 32 item 8)."""
    _, results, _ = case
    data = _lean(results)
    data["pose_accuracy"] = {"before": "x"}
    with caplog.at_level(logging.WARNING):
        built = build_report(tmp_path, data, None)
    lines = [n for n in built.notes if "could not be built" in n]
    assert lines == ["section 'How well will the robot know the part's pose?' could not be built: "
                     "PoseAccuracy.before: 'x' is not allowed; expected: a valid dictionary or instance of PoseDesign"]
    assert all("\n" not in r.getMessage() and "errors.pydantic.dev" not in r.getMessage() for r in caplog.records)
