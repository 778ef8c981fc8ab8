"""Issue 32.3: a design at which the part's holes change in number (a moved hole breaks into an edge or into
another hole) is an infeasible point for the optimiser and one clear error from ``score_design``, never the end
of a run.

The part is tests/data/cqgi/dowel_plate.py with wider bounds: the blind target hole (8 mm) may reach the dowel
hole at (-30, 15). References: the script's constants — a 12 mm target hole centred on that dowel hole merges with
it into one counterbored through hole (2 holes where the study has 3); exact CAD counts on the built solid.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from cadfeat.cad.features import Hole
from cadfeat.errors import CadfeatError

DATA = Path(__file__).parents[1] / "data" / "cqgi"
MERGED = {"target_x": -30.0, "target_y": 15.0, "target_dia": 12.0}  # on the dowel hole at (-30, 15)


@pytest.fixture(scope="module")
def study(tmp_path_factory) -> Path:
    """The dowel plate with bounds wide enough to merge the target hole into a dowel hole, and its study."""
    folder = tmp_path_factory.mktemp("count")
    script = (DATA / "dowel_plate.py").read_text().replace("# [0, 25] mm", "# [-35, 25] mm").replace(
        "# [-12, 12] mm", "# [-20, 20] mm").replace("# [5, 12] mm", "# [5, 14] mm")
    (folder / "dowel_plate.py").write_text(script)
    text = (DATA / "dowel_study.toml").read_text().replace('parameters = ["target_x", "target_y"]',
                                                           'parameters = ["target_x", "target_y", "target_dia"]')
    (folder / "study.toml").write_text(text)
    return folder / "study.toml"


def test_the_merged_design_has_fewer_holes(study):
    """The premise, on the exact CAD: 3 holes at the start, 2 at the merged design."""
    from cadfeat.cad.features import extract_holes
    from cadfeat.cad.parts import load_part

    part = load_part(study.parent / "dowel_plate.py")
    assert len(extract_holes(part.build())) == 3
    assert len(extract_holes(part.build(**MERGED))) == 2


def test_score_design_is_one_error_naming_the_design_and_the_counts(study):
    from cadfeat.study.designs import score_design

    with pytest.raises(CadfeatError) as info:
        score_design(study, MERGED)
    text = str(info.value)
    assert "\n" not in text
    assert all(s in text for s in ("target_x=-30", "target_y=15", "target_dia=12", "2 holes", "design 3"))


def test_the_optimiser_treats_a_count_change_as_infeasible(study):
    """The CAD-in-the-loop search with a rebuild whose target hole, past x = 12 mm, comes with a fourth hole
    (as a hole breaking into an edge splits off another): every such round is a failed (infeasible) rebuild and
    the design returned lies where the part keeps its 3 holes."""
    from cadfeat.design import optimize
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_study

    setup = setup_study(load_study(study))
    stray = dataclasses.replace(setup.holes0[0], centre=np.array([35.0, 20.0, 3.0]), name="")

    def holes_at(x: np.ndarray) -> list[Hole]:
        holes = setup.rebuild_holes(setup.rebuild_shape(x))
        return holes + [stray] if setup.values(x)["target_x"] > 12.0 else holes

    res = optimize.solve_with_cad(setup.problem, holes_at, setup.config.optimizer, max_rounds=4)
    beyond = [r for r in res.cad_rounds if setup.values(np.asarray(r["x"]))["target_x"] > 12.0]
    assert beyond, "the search never went past x = 12 mm: the test does not test anything"
    assert all(r["status"] == "rebuild failed" and "4 holes found, 3 designed" in r["error"] for r in beyond)
    assert setup.values(np.asarray(res.x_best))["target_x"] <= 12.0
    assert len(res.holes) == 3
