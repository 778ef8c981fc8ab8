"""Study-file validation: every bad input fails before any work with one StudyError naming the file, the
dotted key and the allowed values; good input becomes a frozen StudyConfig (integers stay integers)."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from study_helpers import BASE, DATA, PLATE, STEP, study, write_toml

from cadfeat.errors import CadfeatError
from cadfeat.study.schema import StudyError, load_study, part_parameters


def fails(path_or_dict: object, *needles: str) -> str:
    with pytest.raises(StudyError) as info:
        load_study(path_or_dict)
    msg = str(info.value)
    assert isinstance(info.value, CadfeatError)
    assert "\n" not in msg
    for needle in needles:
        assert needle in msg, f"{needle!r} not in {msg!r}"
    return msg


# ------------------------------------------------------------------------------------------ good input
def test_valid_study_loads(tmp_path):
    cfg = load_study(study(tmp_path))
    assert cfg.study.name == "plate" and cfg.study.part_kind == "script" and cfg.study.seed == 3
    assert cfg.study.part_path == (tmp_path / "study_plate.py").resolve()
    assert cfg.optimizer.seed == 3  # defaults to the study seed
    assert [p.name for p in cfg.design.parameters] == ["x0", "count"]
    x0 = cfg.design.parameters[0]
    assert (x0.lower, x0.upper, x0.default) == (-15.0, -5.0, -10.0)
    camera = cfg.camera.build()
    assert camera.width == 128 and camera.fx == pytest.approx(231.4119)
    traj = cfg.trajectory.build()
    assert len(traj) == 10
    np.testing.assert_allclose(cfg.part_pose.T_task_part, np.eye(4))


def test_integer_parameter_stays_int(tmp_path):
    cfg = load_study(study(tmp_path))
    count = cfg.design.parameters[1]
    assert count.is_int
    assert type(count.lower) is int and type(count.upper) is int and type(count.default) is int
    assert (count.lower, count.upper) == (2, 4)
    echoed = cfg.to_dict()["design"]["parameters"]["count"]
    assert type(echoed["lower"]) is int and type(echoed["upper"]) is int
    # integer-valued float bounds given in the file become ints too
    cfg = load_study(study(tmp_path, design={"parameters": {"count": {"lower": 2.0, "upper": 3.0}}}))
    assert type(cfg.design.parameters[0].upper) is int and cfg.design.parameters[0].upper == 3
    assert json.loads(json.dumps(cfg.to_dict()))["design"]["parameters"]["count"]["upper"] == 3


def test_parameter_list_form_uses_part_bounds(tmp_path):
    cfg = load_study(study(tmp_path, design={"parameters": ["pitch", "diameter"]}))
    assert [(p.name, p.lower, p.upper) for p in cfg.design.parameters] == [("pitch", 6.0, 14.0),
                                                                          ("diameter", 2.0, 6.0)]


def test_part_parameters_read_without_running_script(tmp_path):
    script = tmp_path / "p.py"
    script.write_text("raise RuntimeError('must not run')\n"
                      "PARAMETERS = {'a': {'default': 1, 'bounds': (0, 5)}, 'b': {'default': 2.5, 'bounds': (1, 3)}}\n")
    params = part_parameters(script)
    assert params["a"].is_int and not params["b"].is_int
    assert (params["b"].lower, params["b"].upper) == (1, 3)


def test_part_parameters_built_by_code_are_loaded(tmp_path, monkeypatch):
    """A PARAMETERS table filled by module-level code is not taken from its (empty) literal: the part is loaded."""
    import cadfeat.study.part_parameters as part_parameters_module

    script = tmp_path / "p.py"
    script.write_text("PARAMETERS = {}\nfor k in ('a', 'b'):\n    PARAMETERS[k] = {'default': 1.0, 'bounds': (0, 2)}\n")
    seen = []
    monkeypatch.setattr(part_parameters_module, "_parameters_by_loading", lambda path, limit: seen.append(path) or {})
    part_parameters(script)
    assert seen == [script]


def test_dict_input_and_to_dict_roundtrip(tmp_path):
    (tmp_path / "study_plate.py").write_text(PLATE.read_text())
    cfg = load_study(copy.deepcopy(BASE), base_dir=tmp_path)
    assert cfg.file is None
    echoed = cfg.to_dict()
    assert echoed["objective"]["aggregate"] == "sum" and echoed["optimizer"]["maxiter"] == 100
    json.dumps(echoed)  # plain data
    again = load_study(echoed, base_dir=tmp_path)
    assert again.to_dict() == echoed


def test_with_seed_replaces_both_seeds(tmp_path):
    cfg = load_study(study(tmp_path)).with_seed(42)
    assert cfg.study.seed == 42 and cfg.optimizer.seed == 42 and cfg.to_dict()["optimizer"]["seed"] == 42


def test_quaternion_pose(tmp_path):
    q = Rotation.from_euler("z", 30, degrees=True).as_quat().tolist()
    cfg = load_study(study(tmp_path, part_pose={"quaternion": q, "position_mm": [1, 2, 3]}))
    np.testing.assert_allclose(cfg.part_pose.T_task_part[:3, :3],
                               Rotation.from_euler("z", 30, degrees=True).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(cfg.part_pose.T_task_part[:3, 3], [1, 2, 3])


def test_step_study(tmp_path):
    data = copy.deepcopy(BASE)
    data["study"]["part"] = str(STEP)
    data["design"] = {"holes": [{"select": 1}, {"select": "H2", "resize": True, "max_offset_mm": 5.0}],
                      "standard_diameters_mm": [6, 5, 8], "fixed": [[20.0, -12.0, 10.0]]}
    cfg = load_study(write_toml(tmp_path / "s.toml", data))
    assert cfg.study.part_kind == "step"
    assert cfg.design.holes[1].resize and cfg.design.holes[1].max_offset_mm == 5.0
    assert cfg.design.standard_diameters_mm == (5.0, 6.0, 8.0)
    assert cfg.design.fixed == ((20.0, -12.0, 10.0),)


def test_calibration_file_relative_to_study(tmp_path):
    (tmp_path / "cal.yaml").write_text((DATA / "dalsa_calib_opencv.yaml").read_text())
    cfg = load_study(study(tmp_path, camera={"preset": None, "calibration": "cal.yaml", "focal_length_mm": 3.5}))
    assert cfg.camera.build().width > 0


# ------------------------------------------------------------------------------------------- bad input
def test_missing_study_file(tmp_path):
    fails(tmp_path / "nope.toml", "nope.toml", "does not exist", "allowed")


def test_invalid_toml(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[study\nname = 1\n")
    fails(p, "bad.toml", "not valid TOML")


def test_unknown_section(tmp_path):
    fails(study(tmp_path, optimiser={"method": "local"}), "s.toml", "optimiser", "unknown key", "optimizer")


def test_missing_section(tmp_path):
    fails(study(tmp_path, trajectory=None), "s.toml", "[trajectory]", "missing section", "required sections")


@pytest.mark.parametrize("section,key", [("study", "nmae"), ("objective", "agregate"), ("optimizer", "iters"),
                                         ("constraints", "edge_mm"), ("part_pose", "rotation"),
                                         ("design", "params")])
def test_unknown_key(tmp_path, section, key):
    msg = fails(study(tmp_path, **{section: {key: 1}}), "s.toml", f"{section}.{key}", "unknown key", "allowed")
    assert f"keys of [{section}]" in msg


@pytest.mark.parametrize("section,key,value,allowed", [
    ("objective", "aggregate", "median", "sum, mean, min, smoothmin"),
    ("objective", "combine", "product", "weighted, maxmin, constraint, pareto"),
    ("optimizer", "method", "annealing", "multistart, local, global, pareto"),
    ("optimizer", "local_solver", "BFGS", "SLSQP, trust-constr"),
    ("constraints", "symmetry", "radial", "none, x, y, xy"),
    ("objective", "normalisation", "max", "initial, natural, none"),
    ("objective", "fov_measure", "sphere", "cone, image"),
    ("objective", "measures", ["fov", "sharpness"], "fov, focus, resolution, resolvability"),
])
def test_bad_enum(tmp_path, section, key, value, allowed):
    fails(study(tmp_path, **{section: {key: value}}), "s.toml", f"{section}.{key}", allowed)


@pytest.mark.parametrize("section,key,value,allowed", [
    ("study", "seed", "seven", "an integer"),
    ("study", "seed", 1.5, "an integer"),
    ("study", "name", 12, "a name"),
    ("study", "name", "has space", "a name"),
    ("optimizer", "starts", 2.0, "an integer"),
    ("optimizer", "maxiter", True, "an integer"),
    ("optimizer", "snap_standard_sizes", "yes", "true or false"),
    ("objective", "min_axis_px", "5", "a number"),
    ("constraints", "ligament_mm", [1], "a number"),
    ("part_pose", "position_mm", [0, 0], "a list of 3 finite numbers"),
    ("part_pose", "rotvec_deg", "0,0,0", "a list of 3 finite numbers"),
    ("design", "parameters", 5, "a list of names or a table"),
    ("design", "fixed", "H1", "a list of hole selectors"),
])
def test_wrong_type(tmp_path, section, key, value, allowed):
    fails(study(tmp_path, **{section: {key: value}}), "s.toml", f"{section}.{key}", allowed)


@pytest.mark.parametrize("section,key,value,allowed", [
    ("optimizer", "starts", 0, "an integer in [1, 10000]"),
    ("optimizer", "seed", -1, "an integer in [0"),
    ("study", "seed", -3, "an integer in [0"),
    ("objective", "min_axis_px", 0.0, "a number > 0"),
    ("objective", "rotation_length_mm", -1.0, "a number > 0"),
    ("objective", "pose_rotation_length_mm", 0.0, "a number > 0"),
    ("constraints", "edge_distance_mm", -0.5, "a number ≥ 0"),
    ("constraints", "volume_change_max_percent", 150.0, "a number in (0, 100]"),
])
def test_out_of_range(tmp_path, section, key, value, allowed):
    fails(study(tmp_path, **{section: {key: value}}), "s.toml", f"{section}.{key}", allowed)


def test_bounds_outside_part_bounds(tmp_path):
    fails(study(tmp_path, design={"parameters": {"x0": {"lower": -25.0, "upper": -5.0}}}),
          "s.toml", "design.parameters.x0.lower", "a number in [-20, 0]")
    fails(study(tmp_path, design={"parameters": {"pitch": {"upper": 20}}}),
          "s.toml", "design.parameters.pitch.upper", "a number in [6, 14]")


def test_lower_not_below_upper(tmp_path):
    fails(study(tmp_path, design={"parameters": {"x0": {"lower": -5.0, "upper": -6.0}}}),
          "s.toml", "design.parameters.x0", "lower < upper")


def test_integer_parameter_fractional_bound(tmp_path):
    fails(study(tmp_path, design={"parameters": {"count": {"lower": 2.5}}}),
          "s.toml", "design.parameters.count.lower", "not an integer", "an integer in [2, 4]")


def test_unknown_parameter(tmp_path):
    fails(study(tmp_path, design={"parameters": ["x0", "radius"]}),
          "s.toml", "design.parameters.radius", "unknown parameter", "x0, y0, pitch, diameter, count")


def test_unknown_parameter_key(tmp_path):
    fails(study(tmp_path, design={"parameters": {"x0": {"min": 1}}}),
          "s.toml", "design.parameters.x0.min", "unknown key", "lower, upper, standard_sizes")


def test_standard_sizes_outside_bounds(tmp_path):
    fails(study(tmp_path, design={"parameters": {"diameter": {"standard_sizes": [3, 8]}}}),
          "s.toml", "design.parameters.diameter.standard_sizes", "values in [2.0, 6.0]")


def test_missing_part_file(tmp_path):
    fails(study(tmp_path, study={"part": "missing_part.py"}), "s.toml", "study.part", "does not exist")


def test_bad_part_suffix(tmp_path):
    fails(study(tmp_path, study={"part": "part.obj"}), "s.toml", "study.part", ".py, .step or .stp")


def test_missing_study_keys(tmp_path):
    fails(study(tmp_path, study={"name": None}), "s.toml", "study.name", "missing")
    fails(study(tmp_path, study={"part": None}), "s.toml", "study.part", "missing")


def test_part_script_syntax_error(tmp_path):
    path = study(tmp_path)
    (tmp_path / "study_plate.py").write_text("PARAMETERS = {\n")
    fails(path, "study_plate.py", "syntax error")


def test_part_script_without_parameters(tmp_path):
    path = study(tmp_path)
    (tmp_path / "study_plate.py").write_text("def build():\n    pass\n")
    fails(path, "study_plate.py", "PARAMETERS", "missing")


def test_missing_calibration_file(tmp_path):
    fails(study(tmp_path, camera={"preset": None, "calibration": "nope.yaml"}),
          "s.toml", "camera.calibration", "does not exist")


def test_bad_camera_preset(tmp_path):
    fails(study(tmp_path, camera={"preset": "nikon"}), "s.toml", "camera", "nikon", "dalsa-cad1-128a")


def test_unknown_camera_key(tmp_path):
    fails(study(tmp_path, camera={"focal_mm": 3}), "s.toml", "camera.focal_mm", "unknown key", "focal_length_mm")


def test_bad_camera_value(tmp_path):
    fails(study(tmp_path, camera={"fx": -5.0}), "s.toml", "camera", "fx")


def test_bad_trajectory_kind(tmp_path):
    fails(study(tmp_path, trajectory={"kind": "spiral"}), "s.toml", "trajectory", "kind", "orbit_arc")


def test_bad_trajectory_argument(tmp_path):
    fails(study(tmp_path, trajectory={"speed": 3}), "s.toml", "trajectory", "speed", "allowed")


def test_missing_trajectory_csv(tmp_path):
    fails(study(tmp_path, trajectory={"kind": None, "start": None, "end": None, "target": None, "n": None,
                                      "csv": "poses.csv"}), "s.toml", "trajectory", "csv")


def test_rotvec_and_quaternion_together(tmp_path):
    fails(study(tmp_path, part_pose={"rotvec_deg": [0, 0, 0], "quaternion": [0, 0, 0, 1]}),
          "s.toml", "part_pose.quaternion", "one of rotvec_deg or quaternion")


def test_non_unit_quaternion(tmp_path):
    fails(study(tmp_path, part_pose={"quaternion": [0, 0, 0, 2]}), "s.toml", "part_pose.quaternion", "unit")


def test_weights_for_unselected_measure(tmp_path):
    fails(study(tmp_path, objective={"combine": "weighted", "weights": {"focus": 1.0}}),
          "s.toml", "objective.weights.focus", "fov, resolvability")


def test_negative_weight(tmp_path):
    fails(study(tmp_path, objective={"combine": "weighted", "weights": {"fov": -1.0}}),
          "s.toml", "objective.weights.fov", "a number ≥ 0")


def test_constraint_combine_needs_thresholds(tmp_path):
    fails(study(tmp_path, objective={"combine": "constraint"}), "s.toml", "objective.thresholds", "missing")
    fails(study(tmp_path, objective={"combine": "constraint", "thresholds": {"fov": 0.0, "resolvability": 1.0}}),
          "s.toml", "objective.thresholds", "none is left")


def test_thresholds_without_constraint_combine(tmp_path):
    fails(study(tmp_path, objective={"thresholds": {"fov": 0.0}}), "s.toml", "objective.thresholds", "constraint")


def test_pareto_needs_pareto_method(tmp_path):
    fails(study(tmp_path, objective={"combine": "pareto"}), "s.toml", "optimizer.method", "pareto")
    fails(study(tmp_path, optimizer={"method": "pareto"}), "s.toml", "objective.combine", "pareto")


def test_step_part_rejects_parameters_and_script_rejects_holes(tmp_path):
    fails(study(tmp_path, design={"holes": [{"select": 1}]}), "s.toml", "design.holes", "only for STEP parts")
    data = copy.deepcopy(BASE)
    data["study"]["part"] = str(STEP)
    fails(write_toml(tmp_path / "t.toml", data), "t.toml", "design.parameters", "only for part scripts")


@pytest.mark.parametrize("holes,key,allowed", [
    ([{"select": 0}], "design.holes[0].select", "a 1-based hole index"),
    ([{"select": True}], "design.holes[0].select", "a 1-based hole index"),
    ([{"select": [1, 2]}], "design.holes[0].select", "a list of 3 finite numbers"),
    ([{"move": True}], "design.holes[0].select", "missing"),
    ([{"select": 1, "move": False}], "design.holes[0]", "move = true and/or resize = true"),
    ([{"select": 1, "max_offset_mm": 0}], "design.holes[0].max_offset_mm", "a number > 0"),
    ([{"select": 1, "depth": 3}], "design.holes[0].depth", "select, move, resize, max_offset_mm"),
    ([{"select": 1}, {"select": 1}], "design.holes[1].select", "each hole once"),
    ([], "design.holes", "a list of tables"),
])
def test_bad_step_holes(tmp_path, holes, key, allowed):
    data = copy.deepcopy(BASE)
    data["study"]["part"] = str(STEP)
    data["design"] = {"holes": holes}
    fails(write_toml(tmp_path / "t.toml", data), "t.toml", key, allowed)


def test_fixed_hole_also_movable(tmp_path):
    data = copy.deepcopy(BASE)
    data["study"]["part"] = str(STEP)
    data["design"] = {"holes": [{"select": 2}], "fixed": [2]}
    fails(write_toml(tmp_path / "t.toml", data), "t.toml", "design.fixed[0]", "not in design.holes")


def test_bad_standard_diameters(tmp_path):
    data = copy.deepcopy(BASE)
    data["study"]["part"] = str(STEP)
    data["design"] = {"holes": [{"select": 1}], "standard_diameters_mm": [3, -1]}
    fails(write_toml(tmp_path / "t.toml", data), "t.toml", "design.standard_diameters_mm", "positive diameters")
    fails(study(tmp_path, design={"standard_diameters_mm": [3, 4]}), "s.toml", "design.standard_diameters_mm",
          "design.parameters.<name>.standard_sizes")


def test_pattern_needs_two_holes(tmp_path):
    fails(study(tmp_path, design={"patterns": [[1]]}), "s.toml", "design.patterns[0]", "at least two")


def test_dict_study_label():
    data = copy.deepcopy(BASE)
    data["objective"]["aggregate"] = "median"
    data["study"]["part"] = str(PLATE)
    fails(data, "<study dict>", "objective.aggregate", "sum, mean, min, smoothmin")


def test_docs_example_is_a_valid_study():
    """The annotated example of docs/guide/study-files.md ("An annotated study") loads (relative to studies/,
    like the flagship)."""
    import re
    import tomllib

    root = DATA.parents[1]
    text = (root / "docs" / "guide" / "study-files.md").read_text()
    section = text[text.index("## An annotated study"):]
    block = re.search(r"```toml\n(.*?)```", section, re.S).group(1)
    cfg = load_study(tomllib.loads(block), base_dir=root / "studies")
    assert cfg.study.name == "nema17_mount" and cfg.objective.combine == "maxmin"
    assert len(cfg.design.parameters) == 4
