"""The thesis's chapter-5 numbers that cadfeat reproduces, pinned on the studies' own set-ups (issue 32 item 5; README
"The thesis's numbers", docs/results.md; ``tools/thesis_numbers.py`` prints them all).

- Fig. 5.11 / eq. 5.2: the max-min optimum of ``studies/thesis_combined.toml`` (the thesis: d = 1.41 mm; cadfeat
  1.502 mm, the middle of the reduced range where normalised focus and resolvability cross), away from its start;
- §5.4.4's set-up as read there: on the changed path the visual measures are positive at every pose for the reduced
  range 1-2 mm and not for most of §5.4.3's 2-6 mm;
- Fig. 5.10 (c): the cube's g_DIR rises quasi-linearly with d on §5.4.3's path (optimum at the bound, 6 mm).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cadfeat.design.objectives import per_pose_values
from cadfeat.design.optimize import optimise
from cadfeat.study.schema import load_study
from cadfeat.study.setup import setup_study

STUDIES = Path(__file__).parents[2] / "studies"


class _Arrays:
    def __init__(self, arrays: dict) -> None:
        self.__dict__.update(arrays)


@pytest.fixture(scope="module")
def combined():
    return setup_study(load_study(STUDIES / "thesis_combined.toml"))


def test_fig_5_11_max_min_optimum(combined):
    p = combined.problem
    assert (p.space.lower[0], p.space.upper[0], p.space.x0[0]) == (1.0, 2.0, 2.0)
    res = optimise(p, combined.config.optimizer)
    d = float(res.x_best[0])
    assert d == pytest.approx(1.502, abs=0.005)  # the thesis: 1.41 mm (docs/results.md: why not)
    assert abs(d - p.space.x0[0]) > 0.4  # it moves: the start was the answer on the earlier set-up
    g = np.array([res.objectives_best[n] for n in p.names])
    gn = dict(zip(p.names, p.normalised(g), strict=True))
    # at the crossing of the falling normalised focus and the rising normalised resolvability, FOV above both
    assert gn["g_FOC"] == pytest.approx(gn["g_DIR"], abs=0.01) and gn["g_FOV"] > gn["g_FOC"] + 0.03
    assert res.combined_best == pytest.approx(0.498, abs=0.005)


def test_the_changed_path_makes_the_visual_measures_not_positive_on_the_old_range(combined):
    p = combined.problem
    ds = np.array([1.0, 1.5, 2.0, 2.5, 4.0, 6.0])
    c, a, r = p.model.features_batch(ds[:, None])
    per_pose = per_pose_values(_Arrays(p.pose_arrays(c, np.broadcast_to(a, c.shape), r)), p.objective_config,
                               p.feature_mask)
    worst = np.minimum(per_pose["fov"].min(axis=-1), per_pose["focus"].min(axis=-1))
    assert np.all(worst[:3] > 0)  # the reduced range: every corner in view and in focus at every pose
    assert np.all(worst[3:] < 0)  # §5.4.3's range: the focus margin goes negative at the end of the approach
    assert np.all(per_pose["fov"].min(axis=-1) > 0)  # (the field of view holds throughout)


def test_fig_5_10_c_cube_resolvability_rises_quasi_linearly():
    s = setup_study(load_study(STUDIES / "thesis_cube.toml"))
    ds = np.arange(2.0, 6.0001, 0.5)
    g = s.problem.evaluate_batch(ds[:, None])[0][:, 0]
    steps = np.diff(g)
    assert np.all(steps > 0) and steps.max() < 1.1 * steps.min()  # rising, nearly straight
    assert g[0] == pytest.approx(64.2, abs=0.1) and g[-1] == pytest.approx(200.2, abs=0.1)  # px/mm, summed
