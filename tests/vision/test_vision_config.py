"""``TrackingConfig`` IS the study's ``[tracking]`` section (issue 29 item 2): one declaration, no spec → config copy.

The estimators' and the images' parameter records (``FilterTuning``, ``SensorModel``) are views of it: every field
of theirs is the config's field of the same name (a changed value arrives) or one the config derives
(``TUNING_DERIVED``, ``SENSOR_DERIVED``: P₀'s pose σ from the initial error unless given, the noise from the cell)
— so a field added to a record must be declared in the config.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cadfeat.cell import Cell
from cadfeat.errors import CadfeatError
from cadfeat.study.settings import TrackingSettings
from cadfeat.vision.config import SENSOR_DERIVED, TUNING_DERIVED, TrackingConfig
from cadfeat.vision.estimate import FilterTuning
from cadfeat.vision.images import SensorModel

RECORDS = ((FilterTuning, "tuning", TUNING_DERIVED), (SensorModel, "sensor", SENSOR_DERIVED))


def test_the_tracking_section_is_the_vision_config():
    assert TrackingSettings is TrackingConfig
    assert "cell" in TrackingConfig.model_fields and "cell" not in TrackingConfig.study_keys()
    assert "cell" not in TrackingConfig.model_json_schema()["properties"]


@pytest.mark.parametrize("record, view, derived", RECORDS)
def test_every_field_of_the_parameter_records_is_placed(record, view, derived):
    names = {f.name for f in dataclasses.fields(record)}
    assert names - set(TrackingConfig.model_fields) <= set(derived) <= names


@pytest.mark.parametrize("record, view, derived", RECORDS)
def test_a_changed_setting_arrives_in_its_record(record, view, derived):
    default = getattr(TrackingConfig(), view)
    for f in dataclasses.fields(record):
        if f.name not in TrackingConfig.model_fields:
            continue
        old = getattr(TrackingConfig(), f.name)
        old = getattr(default, f.name) if old is None else old
        new = (not old) if isinstance(old, bool) else (old + 1 if isinstance(old, int) else old * 1.5 + 0.01)
        changed = getattr(TrackingConfig().replace(**{f.name: new}), view)
        assert getattr(changed, f.name) == new, f.name
        assert dataclasses.replace(changed, **{f.name: getattr(default, f.name)}) == default, f.name
    plain = record()  # the record's own defaults are the config's where the config does not derive them
    assert all(getattr(default, f.name) == getattr(plain, f.name) for f in dataclasses.fields(record)
               if f.name not in derived)


def test_the_derived_fields():
    config = TrackingConfig(initial_error_mm=0.5, initial_error_deg=3.0).in_cell(Cell(noise_sigma_grey=1.5))
    assert config.tuning.sigma0_mm == 1.0 and config.tuning.sigma0_rad == pytest.approx(np.radians(3.0))
    assert TrackingConfig(initial_error_mm=40.0).tuning.sigma0_mm == 40.0
    assert TrackingConfig(initial_error_deg=0.1).tuning.sigma0_rad == 0.01
    given = TrackingConfig(sigma0_mm=20.0, sigma0_rad=0.1).tuning
    assert (given.sigma0_mm, given.sigma0_rad) == (20.0, 0.1)
    assert not {"sigma0_mm", "blur_scale", "q_pose_mm2"} & set(TrackingConfig.study_keys())
    assert config.sensor.noise_grey == 1.5 and config.noise_grey == 1.5
    assert TrackingConfig(min_change_percent=12.5).min_change == 0.125


def test_the_cell_is_kept_through_replace_and_not_a_section_key():
    cell = Cell(placement_position_mm=1.0, gate_px=4.0, detector="blob")
    config = TrackingConfig(runs=3).in_cell(cell).replace(r_px2=2.0)
    assert config.cell == cell and (config.runs, config.r_px2) == (3, 2.0)
    assert (config.gate_px, config.detector, config.placement_mm) == (4.0, "blob", pytest.approx(0.4))
    assert "cell" not in config.study_dump()
    with pytest.raises(CadfeatError, match="tracking.placement_mm: unknown key"):
        TrackingConfig(placement_mm=0.2)
