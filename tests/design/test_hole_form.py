"""Hole depth and rim chamfer as live design variables (issue 17) on the flagship part (``parts/nema17_mount.py``).

References: the exact CAD geometry (holes re-extracted from an exported and re-imported STEP; the material under a
blind hole measured on the solid by intersecting it with a thin rod along the hole's axis), finite differences of
g_POSE through real CAD rebuilds (build → extract → ``Problem.features_objectives`` with the extracted holes'
depths), and the shop's tables (ISO 273 sizes, the 0.1 mm step).
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

cq = pytest.importorskip("cadquery")

from cadfeat.cad.export import export_step, import_step  # noqa: E402
from cadfeat.cad.features import extract_holes, holes_to_arrays, match_holes  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
STUDY = ROOT / "studies" / "nema17_mount.toml"
FORM = ["target_radius_mm", "target_depth_mm", "target_chamfer_mm"]
PLATE_MM = 5.0  # the flagship's plate thickness (parts/nema17_mount.py T)


@pytest.fixture(scope="module")
def setup():
    """The flagship study with the target holes' radius, depth and chamfer as its only design variables."""
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_script

    data = tomllib.loads(STUDY.read_text())
    data["design"]["parameters"] = FORM
    data["study"]["part"] = str(ROOT / "parts" / "nema17_mount.py")
    return setup_script(load_study(data, base_dir=STUDY.parent))


def _targets(holes):
    return [i for i, h in enumerate(holes) if not h.through]


def test_map_carries_depth_and_bore_exactly(setup, tmp_path):
    model, space = setup.model, setup.space
    assert [v.kind for v in space.variables] == ["diameter", "other", "other"]  # the chamfer is no drill size
    assert setup.linear
    x = np.array([2.6, 1.3, 0.7])  # far from the map's anchor (the box centre)
    predicted = model.holes_at(x)
    step = tmp_path / "x.step"
    export_step(setup.rebuild_shape(x), step)
    holes = extract_holes(import_step(step), prefer_direction=setup.part.view_direction)
    idx = match_holes(predicted, holes, tol_mm=0.05)
    for i in _targets(predicted):
        p, h = predicted[i], holes[idx[i]]
        assert h.depth_mm == pytest.approx(p.depth_mm, abs=1e-6) and p.depth_mm == pytest.approx(1.3, abs=1e-9)
        assert h.bore_radius_mm == pytest.approx(p.bore_radius_mm, abs=1e-6) and p.bore_radius_mm == pytest.approx(2.6)
        assert h.radius_mm == pytest.approx(p.radius_mm, abs=1e-6) and p.radius_mm == pytest.approx(3.3)
        assert h.kind == "plain, chamfered rim"


def test_deepest_target_leaves_a_floor(setup):
    """The part script's depth bound keeps at least 1 mm of the 5 mm plate under a blind target hole: the material
    along each target's axis, measured on the solid at the upper bound, is 5 − 4 = 1 mm (a rod intersection)."""
    upper = next(v.upper for v in setup.space.variables if v.name == "target_depth_mm")
    shape = setup.rebuild_shape(np.array([2.0, upper, 0.0]))
    solid = shape.val() if hasattr(shape, "val") else shape
    holes = extract_holes(shape, prefer_direction=setup.part.view_direction)
    targets = [h for h in holes if not h.through]
    assert len(targets) == 2
    rod_r = 0.05
    for h in targets:
        start = h.centre + 2.0 * h.axis  # from outside the face, inwards past the far side of the plate
        rod = cq.Solid.makeCylinder(rod_r, 10.0, cq.Vector(*start), cq.Vector(*(-h.axis)))
        floor_mm = solid.intersect(rod).Volume() / (math.pi * rod_r ** 2)
        assert floor_mm == pytest.approx(PLATE_MM - upper, rel=1e-6) and floor_mm >= 1.0 - 1e-9
        assert h.depth_mm == pytest.approx(upper, abs=1e-6)


def _g_pose_cad(setup, x):
    """g_POSE of the CAD rebuild at x: extracted holes in the model's order, their own depths."""
    predicted = setup.model.holes_at(x)
    holes = extract_holes(setup.rebuild_shape(x), prefer_direction=setup.part.view_direction)
    ordered = [holes[i] for i in match_holes(predicted, holes, tol_mm=0.05)]
    g = setup.problem.features_objectives(*holes_to_arrays(ordered), depth_mm=[h.depth_mm for h in ordered])
    return float(g[setup.problem.names.index("g_POSE")]) if "g_POSE" in setup.problem.names else float(g[0])


def test_g_pose_gradient_through_the_map_matches_the_cad_rebuild(setup):
    problem = setup.problem
    x = np.array([2.2, 2.4, 0.3])
    h = 0.1
    for j, name in ((1, "depth"), (2, "chamfer")):
        e = np.eye(3)[j] * h
        G, _ = problem.evaluate_batch(np.stack([x + e, x - e]))
        by_map = (G[0, 0] - G[1, 0]) / (2 * h)
        by_cad = (_g_pose_cad(setup, x + e) - _g_pose_cad(setup, x - e)) / (2 * h)
        scale = abs(problem.evaluate_batch(x[None])[0][0, 0])
        assert abs(by_map) > 1e-4 * scale, name  # g_POSE sees the design's depth / chamfer (not the anchor's)
        assert by_map == pytest.approx(by_cad, rel=1e-6, abs=1e-9 * scale), name


def test_shop_snaps_the_bore_and_keeps_the_chamfer(setup):
    from cadfeat.design.shop import ISO_273, shop_design

    x = np.array([1.23, 2.345, 0.537])
    sd = shop_design(setup.space, setup.model, x, grid_mm=0.1, sizes=ISO_273["medium"])
    radius, depth, chamfer = sd.x
    assert 2 * radius == pytest.approx(2.4, abs=1e-9)  # the bore Ø2.46 → ISO 273 medium Ø2.4 (M2)
    assert depth == pytest.approx(2.3, abs=1e-9) and chamfer == pytest.approx(0.5, abs=1e-9)  # the 0.1 mm step
    bores = setup.model.bores_batch(sd.x)[0]
    rims = setup.model.features(sd.x)[2]
    for i in _targets(setup.model.holes):
        assert 2 * bores[i] == pytest.approx(sd.target_diameters[i], abs=1e-9)
        assert rims[i] - bores[i] == pytest.approx(0.5, abs=1e-9)  # the rim keeps its chamfer: Ø3.4 is no drill


def test_robust_design_statistics_see_the_designs_depths(setup):
    """``robust_study.design_statistics`` (results.json ``robustness.designs``, the report's robust figures and the
    held-out choice) evaluates each design with its own hole depths: the nominal entry equals the single-design
    ``Problem.features_objectives`` with those depths, and each camera draw equals a Problem rebuilt with the
    displaced camera (no occlusion, so the two paths are exact to round-off; the depth-map lookup of displaced
    cameras is tests/design/test_robust.py's), and not the value with the reference holes' depths."""
    from cadfeat.design.problem import Problem
    from cadfeat.design.robust import RobustObjective, RobustProblem
    from cadfeat.design.uncertainty import Uncertainty, draws
    from cadfeat.study.robust_study import design_statistics
    from cadfeat.trajectory import Trajectory

    p0 = setup.problem
    traj = setup.trajectory

    def problem(trajectory):
        return Problem(p0.space, p0.model, p0.camera, trajectory, p0.T_task_part, p0.objective_config,
                       p0.constraint_config, p0.fixed_mask, normaliser=p0.normaliser, feature_mask=p0.feature_mask)
    p = problem(traj)
    D = draws(Uncertainty(camera_position_mm=2.0, camera_angle_deg=1.0), 2, len(p.model.holes), seed=3)
    rp = RobustProblem(p, RobustObjective(), D)
    X = np.array([[2.2, 1.2, 0.3], [2.2, 3.8, 0.3]])  # shallow and deep targets, same rim
    feats = [p.model.features(x) for x in X]
    depths = list(p.hole_depths(X))
    assert np.ptp(np.stack(depths), axis=0).max() > 2.0
    stats = design_statistics(rp, feats, D, values=True, sources=("camera",), depths=depths)
    for (c, a, r), d, st in zip(feats, depths, stats, strict=True):
        assert st.blocks["camera"]["g_POSE"]["nominal"] == pytest.approx(p.features_objectives(c, a, r, depth_mm=d)[0],
                                                                  rel=1e-9)
        for s in range(D.size):
            ref = problem(Trajectory(np.asarray(traj.T_task_cam) @ D.dC[s], np.asarray(traj.times_s)))
            g, g_ref_depth = (float(p.combined_from(ref.features_objectives(c, a, r, depth_mm=dd)))
                              for dd in (d, None))
            assert st.values["camera"][s] == pytest.approx(g, rel=1e-8, abs=1e-10)
            assert abs(g - g_ref_depth) > 1e-4  # the test sees the depth
