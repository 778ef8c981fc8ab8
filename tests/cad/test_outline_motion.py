"""Host-face outlines that move with the design (cadfeat.cad.outline_motion, issue 16 item 2).

Reference: the 2-D edge/keep-out margins of the holes and outlines of a REAL CAD rebuild at each design (the
thesis cube, whose plates and tunnel grow with d), against the margins predicted from the map at d = 4 mm."""

from __future__ import annotations

import numpy as np
import pytest

from cadfeat.cad.design_map import design_map
from cadfeat.cad.features import holes_to_arrays
from cadfeat.cad.parts import load_part
from cadfeat.design.constraints import ConstraintConfig, ConstraintSet
from cadfeat.design.design_space import LinearFeatureModel

CONFIG = ConstraintConfig(edge_distance_mm=0.5, ligament_mm=0.5)


@pytest.fixture(scope="module")
def cube():
    part = load_part("thesis_cube_points")
    dm = design_map(part, ["d_mm"], at={"d_mm": 4.0})
    return part, LinearFeatureModel.from_design_map(dm, ["d_mm"], [4.0])


def _by_name(holes, names):
    found = {h.name: h for h in holes}
    return [found[n] for n in names]


@pytest.mark.parametrize("d", [2.3, 5.7])
def test_moving_outlines_give_the_margins_of_the_real_rebuild(cube, d):
    part, model = cube
    fixed = np.zeros(len(model.holes), bool)
    real_holes = _by_name(part.holes(d_mm=d), [h.name for h in model.holes])
    c, _, r = holes_to_arrays(real_holes)
    real = ConstraintSet(real_holes, CONFIG, fixed).margins(c, r)
    moving = ConstraintSet(model.holes, CONFIG, fixed, outline_rates=model.outline_rates, x_anchor=model.x0)
    cp, _, rp = model.features(np.array([d]))
    predicted = moving.margins(cp, rp, X=np.array([d]))
    for kind in ("edge", "keepout"):
        assert predicted[kind].shape == real[kind].shape
        np.testing.assert_allclose(predicted[kind], real[kind], atol=1e-6)
    # the same holes against the outlines of d = 4 mm only: the tunnel floor's edge margin is wrong by (d − 4)/2
    static = ConstraintSet(model.holes, CONFIG, fixed).margins(cp, rp)
    assert np.abs(static["edge"] - real["edge"]).max() == pytest.approx(abs(d - 4.0) / 2, rel=1e-6)


def test_holes_at_moves_the_outline_like_the_rebuild(cube):
    part, model = cube
    (h,) = [h for h in model.holes_at(np.array([5.0])) if h.name == "H5"]
    (g,) = [g for g in part.holes(d_mm=5.0) if g.name == "H5"]
    span = lambda o: np.ptp(o.to_3d(o.outer), axis=0)  # noqa: E731 - the face's extent (mm, part frame)
    np.testing.assert_allclose(span(h.outline), span(g.outline), atol=1e-6)
