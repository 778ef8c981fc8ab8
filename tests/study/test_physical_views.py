"""What the robot's camera will see (``study.physical_views``): both designs rendered physically in the study's cell
at the first, middle and last sample, the cell's detector's detections drawn and the misses named; and the report
section that shows them (embedded)."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image
from study_helpers import study

from cadfeat.study.physical_views import physical_views
from cadfeat.study.schema import load_study


@pytest.fixture(scope="module")
def views(tmp_path_factory):
    from cadfeat.cad.parts import load_part
    from cadfeat.study.tracking import _named

    tmp = tmp_path_factory.mktemp("views")
    config = load_study(study(tmp, camera={"fx": 900.0, "fy": 900.0, "cx": 160.0, "cy": 120.0, "width": 320,
                                           "height": 240, "focus_distance_mm": 200.0},
                              cell={"material": {"name": "grey_plastic"}}, tracking={"spp": 4}))
    part = load_part(config.study.part_path)
    designs = {name: (part.build(**values), _named(part.holes(**values)))
               for name, values in (("before", {}), ("after", {"x0": -14.0}))}
    return config, physical_views(config, designs, tmp / "out"), tmp / "out"


def test_three_frames_per_design_with_expected_detected_and_missed_holes(views):
    config, section, out = views
    assert [(f["design"], f["frame"]) for f in section["frames"]] == [
        (d, k) for d in ("before", "after") for k in (0, 5, 9)]  # first, middle, last of 10 samples
    assert (section["material"], section["light"], section["detector"], section["spp"]) == \
        ("grey_plastic", "ring", "cadfeat", 4)
    for f in section["frames"]:
        assert set(f["detected"]) | set(f["missed"]) == set(f["expected"])
        assert not set(f["detected"]) & set(f["missed"])
        img = np.asarray(Image.open(out / f["path"]))
        assert img.shape == (240, 320, 3) and img.std() > 5  # a drawn frame, not blank
    assert sum(len(f["expected"]) for f in section["frames"]) > 0
