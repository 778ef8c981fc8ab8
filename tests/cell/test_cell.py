"""The robot cell is one model (``cadfeat.cell.Cell``, the study's ``[cell]``): each number says whether it is a ±
bound or a standard deviation, the old keys are refused with where they moved, and one study file's cell arrives
with the same values in g_POSE's models, the robust draws and the closed loop."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from study_helpers import study

from cadfeat.cell import BOUND_KEYS, SIGMA_KEYS, Cell
from cadfeat.errors import CadfeatError
from cadfeat.settings import StudyError

pytestmark = pytest.mark.numerics

CELL = {"camera_position_mm": 1.5, "camera_angle_deg": [0.5, 1.0, 2.0], "placement_position_mm": 2.0,
        "placement_angle_deg": 1.0, "noise_sigma_grey": 3.0, "noise_spread_grey": 0.5, "gain_sigma": 0.1,
        "gate_px": 3.0, "detector": "edcircles"}


def test_each_number_says_whether_it_is_a_bound_or_a_sigma():
    numeric = {"camera_position_mm", "camera_angle_deg", "placement_position_mm", "placement_angle_deg",
               "noise_sigma_grey", "noise_spread_grey", "gain_sigma"}  # the cell's uncertain quantities
    assert set(BOUND_KEYS) | set(SIGMA_KEYS) == numeric and not set(BOUND_KEYS) & set(SIGMA_KEYS)
    assert set(SIGMA_KEYS) == {"noise_sigma_grey", "gain_sigma"}
    schema = Cell.model_json_schema()["properties"]
    assert schema["placement_position_mm"]["x-statistic"] == "bound"
    assert schema["noise_sigma_grey"]["x-statistic"] == "sigma"
    with pytest.raises(CadfeatError, match=r"cell\.detector: 'hough' is not allowed; allowed: cadfeat, edcircles"):
        Cell(detector="hough")


@pytest.mark.parametrize(("section", "key", "where"), [
    ("robustness", "placement_position_mm", "[cell] placement_position_mm"),
    ("robustness", "camera_angle_deg", "[cell] camera_angle_deg"),
    ("robustness", "pixel_noise_grey", "[cell] noise_spread_grey"),
    ("tracking", "noise_grey", "[cell] noise_sigma_grey"),
    ("tracking", "gate_px", "[cell] gate_px"),
    ("tracking", "gain_sigma", "[cell] gain_sigma"),
])
def test_a_cell_number_elsewhere_is_refused_with_where_it_moved(tmp_path, section, key, where):
    from cadfeat.study.schema import load_study

    with pytest.raises(StudyError) as err:
        load_study(study(tmp_path, **{section: {key: 1.0}}))
    assert f"{section}.{key}: this key moved; allowed: {where}" in str(err.value) and "\n" not in str(err.value)


@pytest.fixture(scope="module")
def celled(tmp_path_factory):
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_study

    tmp = tmp_path_factory.mktemp("cell")
    config = load_study(study(tmp, cell=CELL, objective={"measures": ["fov", "pose"], "pose_aggregate": "rms",
                                                        "pose_rotation_length_mm": 20.0}))
    return config, setup_study(config)


def test_the_study_cell_reaches_g_pose(celled):
    """g_POSE of the study equals ``pose_information`` with the models written out by hand for this cell: the gate
    3 px, the placement σ = 0.4 t (0.8 mm; 0.4°) and 3 grey levels of noise — and differs from the default cell's."""
    from cadfeat.cad.export import mesh_from_shape
    from cadfeat.design.objectives import pose_objective
    from cadfeat.measures import pose_information
    from cadfeat.measures.pose_models import models_for
    from cadfeat.measures.rim_occlusion import rim_occlusion
    from cadfeat.poses import invert_T
    from cadfeat.study.pipeline import score

    config, setup = celled
    assert setup.problem.cell == config.cell == Cell(**CELL)
    values, _ = score(setup, setup.holes0)
    holes = setup.holes0
    c, a = np.array([h.centre for h in holes]), np.array([h.axis for h in holes])
    r, through = np.array([h.radius_mm for h in holes]), np.array([h.through for h in holes])
    depth = np.array([h.depth_mm for h in holes])
    T = invert_T(np.asarray(setup.trajectory.T_task_cam)) @ setup.T_task_part
    occ = rim_occlusion(mesh_from_shape(setup.shape0, tolerance=0.05), T, c, a, r, through=through, depth_mm=depth)

    def g(model, noise):
        info = pose_information(setup.camera, T, c, a, r, occlusion=occ, through=through, depth_ratio=depth / (2 * r),
                                rotation_length_mm=20.0, model=model, noise_grey=noise)
        return pose_objective(info, "rms", 20.0)

    by_hand = replace(models_for(config.cell), gate_px=3.0, placement_mm=0.8, placement_deg=0.4)
    assert values["g_POSE"] == pytest.approx(g(by_hand, 3.0), rel=1e-9)
    assert abs(values["g_POSE"] - g(models_for(Cell()), 2.0)) > 1e-3 * abs(values["g_POSE"])


def test_the_study_cell_reaches_the_robust_draws(celled):
    """The draws span the cell's ± bounds: placement within ±2 mm and reaching past 1.8 mm, camera angle within its
    per-axis bounds, the noise σ within 3 ± 0.5 grey levels."""
    from cadfeat.design.uncertainty import Uncertainty, draws
    from cadfeat.poses import invert_T

    config, setup = celled
    D = draws(Uncertainty.from_settings(config.robustness, config.cell), 256, len(setup.holes0), seed=1)
    place = np.abs(D.dP[:, :3, 3])
    assert place.max() <= 2.0 + 1e-12 and place.max() > 1.8
    from scipy.spatial.transform import Rotation

    cam_deg = np.degrees(Rotation.from_matrix(invert_T(D.dC)[:, :3, :3]).as_rotvec())
    assert np.all(np.abs(cam_deg).max(axis=0) <= np.array([0.5, 1.0, 2.0]) + 1e-9)
    assert np.all(np.abs(cam_deg).max(axis=0) > 0.8 * np.array([0.5, 1.0, 2.0]))
    assert D.noise_grey is not None and 2.5 - 1e-12 <= D.noise_grey.min() and D.noise_grey.max() <= 3.5 + 1e-12
    assert D.noise_grey.max() - D.noise_grey.min() > 0.8


def test_the_study_cell_reaches_the_closed_loop(celled):
    """The closed loop's configuration: the same noise σ, gain σ, gate and detector, and the placement drawn with
    σ = 0.4 t (scipy's normal: ±t holds 98.8 % of the draws)."""
    from scipy.stats import norm

    from cadfeat.study.settings import TrackingSettings
    from cadfeat.vision.closed_loop import placement_errors

    config, _ = celled
    tc = TrackingSettings(runs=1000).in_cell(config.cell)
    assert (tc.sensor.noise_grey, tc.gain_sigma, tc.gate_px, tc.detector) == (3.0, 0.1, 3.0, "edcircles")
    t = np.abs(placement_errors(tc, tc.runs)[:, :3, 3])
    inside = (t <= 2.0).mean()
    p = 2 * norm.cdf(2.5) - 1
    assert inside == pytest.approx(p, abs=4 * np.sqrt(p * (1 - p) / t.size))


def test_the_lower_layers_default_to_the_default_cell():
    """Each lower layer's default is the default cell's number (``cadfeat.cell.defaults``, declared once): the
    closed loop's, g_POSE's models', the robust draws' and ``pose_information``'s."""
    import inspect

    from cadfeat.design.uncertainty import Uncertainty
    from cadfeat.measures import pose_information
    from cadfeat.measures.pose_models import PoseModels
    from cadfeat.study.settings import RobustnessSettings, TrackingSettings
    from cadfeat.vision.closed_loop import TrackingConfig
    from cadfeat.vision.images import SensorModel

    cell = Cell()
    tc = TrackingConfig()
    assert SensorModel().noise_grey == cell.noise_sigma_grey
    assert (tc.gate_px, tc.gain_sigma, (tc.placement_mm, tc.placement_deg), tc.detector) == \
        (cell.gate_px, cell.gain_sigma, cell.placement_sigma(), cell.detector)
    assert TrackingSettings() == TrackingSettings().in_cell(cell) and TrackingSettings is TrackingConfig
    assert PoseModels().for_cell(cell) == PoseModels()
    assert Uncertainty() == Uncertainty.from_settings(RobustnessSettings(), cell)
    assert inspect.signature(pose_information).parameters["noise_grey"].default == cell.noise_sigma_grey


def test_the_cell_light_and_material_are_sub_tables_with_one_line_errors(tmp_path):
    """``[cell.light]`` / ``[cell.material]``: validated as their models, errors keyed ``cell.light.kind``; they
    reach the physically based closed loop's renderer options."""
    from cadfeat.study.schema import load_study
    from cadfeat.study.settings import TrackingSettings

    config = load_study(study(tmp_path, cell={"light": {"kind": "dome", "intensity": 2.0},
                                              "material": {"name": "grey_plastic"}, "hole_ends": "drilled"}))
    options = TrackingSettings(renderer="pbr", spp=4).in_cell(config.cell).render_options()
    assert (options["light"].kind, options["light"].intensity, options["material"].name, options["hole_ends"],
            options["spp"]) == ("dome", 2.0, "grey_plastic", "drilled", 4)
    assert TrackingSettings().in_cell(config.cell).render_options() == {}  # the raster loop takes none
    for cell, where in (({"light": {"kind": "laser"}}, "cell.light.kind: 'laser' is not allowed; allowed: ring"),
                        ({"material": {"name": "oak"}}, "cell.material.name: 'oak' is not allowed; allowed: "),
                        ({"light": {"colour": 1}}, "cell.light.colour: unknown key; allowed: keys of [cell.light]")):
        with pytest.raises(StudyError) as err:
            load_study(study(tmp_path, cell=cell))
        assert where in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize(("key", "value"), [("noise_sigma_grey", 500.0), ("noise_spread_grey", -1.0),
                                            ("gain_sigma", float("nan")), ("gain_sigma", 2.0)])
def test_a_statistic_out_of_its_range_is_refused_naming_the_key(key, value):
    """The σ / spread keys keep their ranges (a field marked bound or σ for the JSON Schema once lost them)."""
    with pytest.raises(Exception, match=rf"cell\.{key}: .* is not allowed; allowed: a number in \["):
        Cell(**{key: value})
