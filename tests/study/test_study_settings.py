"""Study settings as pydantic models and the JSON Schema of a study file (``cadfeat schema``).

Independent references: the ``jsonschema`` library validates every study of studies/ (tests/test_docs.py: the
annotated example of docs/guide/study-files.md) against the written schema and refuses planted mistakes; the vision
layer's own defaults (``FilterTuning``) are what a study without ``[tracking]`` keys gets.
"""

from __future__ import annotations

import copy
import json
import tomllib
from pathlib import Path

import jsonschema
import numpy as np
import pytest
from study_helpers import BASE, study

from cadfeat.cli import main
from cadfeat.study.schema import load_study
from cadfeat.study.settings import StudyError, TrackingSettings
from cadfeat.vision import FilterTuning

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def validator(tmp_path_factory):
    out = tmp_path_factory.mktemp("schema") / "study.schema.json"
    assert main(["schema", "--out", str(out)]) == 0
    schema = json.loads(out.read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def test_every_study_file_meets_the_schema(validator):
    files = sorted((ROOT / "studies").glob("*.toml"))
    assert files
    for f in files:
        errors = list(validator.iter_errors(tomllib.loads(f.read_text())))
        assert not errors, (f.name, [e.message for e in errors[:3]])


@pytest.mark.parametrize("section,key,value", [("objective", "agregate", "sum"), ("objective", "combine", "product"),
                                               ("tracking", "r_px2", -1.0), ("optimizer", "maxiter", 1.5),
                                               ("shop", "grid_mm", 20.0), ("study", "nmae", "x"),
                                               ("objective", "pose_aggregate", "mean"),
                                               ("part_pose", "position_mm", [0, 0]), ("camera", "focal_mm", 3.0),
                                               ("design", "fixed", "H1"), ("study", "seed", -1)])
def test_schema_refuses_what_load_study_refuses(validator, tmp_path, section, key, value):
    data = copy.deepcopy(BASE)
    data.setdefault(section, {})[key] = value
    assert not validator.is_valid(data)
    with pytest.raises(StudyError, match=rf"{section}\.{key}"):
        load_study(study(tmp_path, **{section: {key: value}}))


def test_one_default_per_setting(tmp_path):
    """[tracking] defaults are the vision layer's (one declaration: the r_px2 drift 0.25 vs 1.0 is gone)."""
    cfg = load_study(study(tmp_path, tracking={"runs": 2}))
    assert cfg.tracking.r_px2 == FilterTuning().r_px2 == TrackingSettings().r_px2
    assert cfg.tracking.seed == BASE["study"]["seed"]  # the study's seed unless given
    assert cfg.tracking.replace(runs=3).runs == 3
    with pytest.raises(Exception, match="frozen"):
        cfg.tracking.runs = 4


def test_one_placement_tolerance(tmp_path):
    """The part's placement tolerance is declared once, ``[cell] placement_position_mm`` /
    ``placement_angle_deg`` (±t): the old ``[tracking]`` keys are refused in one line saying where they moved; the
    closed loop draws σ = 0.4 t, so vision's own default (0.2) is what the default tolerance (0.5) gives, and the
    ±t bound holds 2.5 σ of the drawn placements (scipy's normal CDF, over vision's own draws)."""
    from scipy.stats import norm

    from cadfeat.cell import Cell
    from cadfeat.vision.closed_loop import TrackingConfig, placement_errors

    for key in ("placement_mm", "placement_deg"):
        msg = str(pytest.raises(StudyError, load_study, study(tmp_path, tracking={key: 0.3})).value)
        assert f"tracking.{key}: this key moved; allowed: [cell] placement_" in msg and "\n" not in msg
    default = TrackingSettings()
    assert (default.placement_mm, default.placement_deg) == (TrackingConfig().placement_mm,
                                                             TrackingConfig().placement_deg)
    t = 1.5
    per_axis = TrackingSettings(runs=2000).in_cell(Cell(placement_position_mm=t, placement_angle_deg=(0.5, 1.0, 2.0)))
    assert per_axis.placement_deg == pytest.approx((0.2, 0.4, 0.8))
    inside = np.abs(placement_errors(per_axis, per_axis.runs)[:, :3, 3]) <= t
    coverage = 2 * norm.cdf(2.5) - 1  # ≈ 0.988
    assert inside.mean() == pytest.approx(coverage, abs=4 * np.sqrt(coverage * (1 - coverage) / inside.size))


def test_pose_measure_and_its_aggregate(tmp_path):
    """g_POSE: "pose" in [objective] measures with pose_aggregate rms | worst | logdet (one-line errors)."""
    cfg = load_study(study(tmp_path, objective={"measures": ["pose"], "pose_aggregate": "worst"}))
    assert cfg.objective.pose_aggregate == "worst" and cfg.objective.names == ["g_POSE"]
    assert load_study(study(tmp_path, objective={"measures": ["pose"]})).objective.pose_aggregate == "rms"
    with pytest.raises(StudyError) as err:
        load_study(study(tmp_path, objective={"measures": ["pose"], "pose_aggregate": "median"}))
    assert str(err.value).count("\n") == 0
    assert "objective.pose_aggregate: 'median' is not allowed; allowed: rms, worst, logdet" in str(err.value)


def test_new_studies_default_to_g_pose(tmp_path):
    """Issue 17: a study that lists no measures optimises g_POSE; the thesis studies list the thesis measures
    (and so reproduce the thesis), the flagship and its added-target study list g_POSE."""
    cfg = load_study(study(tmp_path, objective={"measures": None}))
    assert list(cfg.objective.measures) == ["pose"] and cfg.objective.names == ["g_POSE"]
    for f in sorted((ROOT / "studies").glob("*.toml")):
        measures = tomllib.loads(f.read_text())["objective"]["measures"]
        assert ("pose" in measures) == (f.stem in ("nema17_mount", "nema17_add_targets")), f.name
