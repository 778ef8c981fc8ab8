"""The ``[add_targets]`` study phase (issue 31): bad input refused before any optimisation with one clear error
(file, key, allowed values), the recommendation rule, and the section's validation."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from cadfeat.errors import CadfeatError
from cadfeat.study.added_targets import allowed_sites, recommend
from cadfeat.study.schema import StudyError, load_study
from cadfeat.study.settings import ConstraintSettings, ShopSettings
from cadfeat.study.settings.add_targets import AddTargetsSettings

cq = pytest.importorskip("cadquery")
ROOT = Path(__file__).resolve().parents[2]


def _config(**keys: Any) -> Any:
    keys.setdefault("faces", ["+z"])
    return SimpleNamespace(label="s.toml", add_targets=AddTargetsSettings(**keys),
                           constraints=ConstraintSettings(edge_distance_mm=3.0, ligament_mm=3.0),
                           shop=ShopSettings())


@pytest.fixture(scope="module")
def plate() -> Any:
    """A 60 x 40 x 6 mm plate (top z = 6) with a Ø6 through hole at the origin, and its holes."""
    from cadfeat.cad.features import extract_holes

    shape = cq.Workplane("XY").box(60, 40, 6, centered=(True, True, False)).faces(">Z").workplane().hole(6.0).val()
    return shape, extract_holes(shape, prefer_direction=(0, 0, 1))


@pytest.fixture(scope="module")
def disc() -> Any:
    shape = cq.Workplane("XY").circle(20).extrude(5).val()
    return shape, []


def test_sites_on_the_plate(plate: Any) -> None:
    shape, holes = plate
    found = allowed_sites(_config(), shape, holes)
    c = found.sites.centres
    assert len(found.faces) == 1 and np.allclose(c[:, 2], 6.0)
    assert np.all(np.abs(c[:, 0]) <= 30 - 2.75 - 3 + 1e-9) and np.all(np.abs(c[:, 1]) <= 20 - 2.75 - 3 + 1e-9)
    assert np.all(np.hypot(c[:, 0], c[:, 1]) >= 3 + 2.75 + 3 - 1e-9)


def test_a_face_the_part_does_not_have(disc: Any) -> None:
    shape, holes = disc
    with pytest.raises(StudyError, match=r"s\.toml: add_targets\.faces: '\+x': the part has no planar face facing "
                                         r"\+x; allowed: a face the part has"):
        allowed_sites(_config(faces=["+x"]), shape, holes)


def test_a_host_hole_the_part_does_not_have(plate: Any) -> None:
    shape, holes = plate
    with pytest.raises(StudyError, match=r"add_targets\.faces: 'host:H7': the part has no hole 'H7'; allowed: "
                                         r"host:<one of H1>"):
        allowed_sites(_config(faces=["host:H7"]), shape, holes)


def test_a_drill_larger_than_the_face() -> None:
    shape = cq.Workplane("XY").box(10, 10, 5, centered=(True, True, False)).val()
    with pytest.raises(StudyError, match=r"add_targets\.diameter_mm: a Ø5\.5 mm drill .* is larger than face \d+ "
                                         r"\(normal \(0, 0, 1\), 100 mm²\); allowed: a diameter ≤ -?[0-9.]+ mm"):
        allowed_sites(_config(), shape, [])


def test_no_feasible_site(plate: Any) -> None:
    shape, holes = plate
    with pytest.raises(StudyError, match=r"add_targets: no feasible site on \+z: every site breaks a requirement "
                                         r"\(.*keepout_boxes: 100 % of the sites\); allowed: other faces"):
        allowed_sites(_config(keepout_boxes=[[-40, -30, 0, 40, 30, 10]]), shape, holes)


def test_a_hole_deeper_than_the_part_fails_in_the_dry_run(plate: Any) -> None:
    """What fails at the end is tried at the start: a blind hole deeper than the 6 mm plate breaks out."""
    from cadfeat.study.added_targets import preflight

    shape, holes = plate
    setup = SimpleNamespace(shape0=shape, holes0=holes, view_direction=(0.0, 0.0, 1.0))
    with pytest.raises(StudyError, match=r"add_targets: a hole cannot be drilled into the part \(dry run at .*\): .*"
                                         r"breaks out of the part.*; allowed: other faces, a shallower depth_mm"):
        preflight(_config(depth_mm=8.0), setup)
    assert preflight(_config(), setup)["sites"] > 10


def test_a_drill_not_in_the_shop_table(plate: Any) -> None:
    shape, holes = plate
    with pytest.raises(StudyError, match=r"add_targets\.diameter_mm: 5 is not a size of the shop's table "
                                         r"\(iso273-medium\); allowed: 1\.8, 2\.4, .*5\.5"):
        allowed_sites(_config(diameter_mm=5.0), shape, holes)


def test_the_section_is_validated_by_the_study_loader() -> None:
    data = load_study(ROOT / "studies" / "nema17_add_targets.toml").to_dict()
    data["add_targets"]["faces"] = ["front"]
    data["study"]["part"] = str(ROOT / "parts" / "nema17_mount.py")
    with pytest.raises(StudyError, match=r"add_targets\.faces: 'front' is not allowed; allowed: a list of faces"):
        load_study(data)
    del data["add_targets"]["faces"]
    with pytest.raises(StudyError, match=r"add_targets\.faces: missing"):
        load_study(data)


def test_bad_faces_fail_before_any_optimisation(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """A STEP study whose allowed face does not exist stops in the set-up: the optimiser is never called."""
    from cadfeat.design import optimize
    from cadfeat.study.run import run_study

    def never(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("the optimiser ran")
    monkeypatch.setattr(optimize, "optimise", never)
    monkeypatch.setattr(optimize, "solve_with_cad", never)
    data = load_study(ROOT / "studies" / "step_plate.toml").to_dict()
    data["study"]["part"] = str(ROOT / "tests" / "data" / "plate_holes.step")
    data["add_targets"] = {"faces": ["host:H42"]}
    with pytest.raises(StudyError, match=r"add_targets\.faces: 'host:H42': the part has no hole 'H42'"):
        run_study(data, tmp_path / "out", quiet=True, track="off")
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


@pytest.mark.parametrize(("errors", "target", "gain", "k"), [
    ([0.04, 0.03, 0.025, 0.022, 0.021], None, 10.0, 3),
    ([0.04, 0.03, 0.025, 0.022, 0.021], 0.026, 10.0, 2),
    ([0.04, 0.039, 0.038], None, 5.0, 0),
    ([0.04, 0.02, 0.01], None, 5.0, 2),
])
def test_recommendation_rule(errors: list[float], target: float | None, gain: float, k: int) -> None:
    got, why = recommend(errors, target, gain)
    assert got == k and why


def test_chamfer_must_be_shallower_than_the_depth() -> None:
    with pytest.raises(CadfeatError, match=r"add_targets\.chamfer_mm: 3 is not allowed; allowed: a chamfer "
                                           r"shallower than depth_mm = 3 mm"):
        AddTargetsSettings(faces=["+z"], chamfer_mm=3.0)


def test_a_shallow_hole_is_outside_what_the_models_describe() -> None:
    with pytest.raises(CadfeatError, match=r"add_targets\.depth_mm: 2 is not allowed; allowed: a depth ≥ 0\.5 × "
                                           r"diameter_mm = 2\.75 mm"):
        AddTargetsSettings(faces=["+z"], diameter_mm=5.5, depth_mm=2.0)


def _most_at_once(clash: np.ndarray) -> int:
    """The largest set of sites without a conflict (exact, branch and bound; a few dozen sites)."""
    n = len(clash)
    best = 0

    def grow(free: np.ndarray, size: int) -> None:
        nonlocal best
        idx = np.flatnonzero(free)
        if size + len(idx) <= best:
            return
        if not len(idx):
            best = max(best, size)
            return
        i = idx[0]
        grow(free & ~clash[i], size + 1)  # take site i (its conflicts, itself included, leave)
        rest = free.copy()
        rest[i] = False
        grow(rest, size)
    grow(np.ones(n, bool), 0)
    return best


@pytest.mark.parametrize(("pitch", "ligament"), [(8.0, 3.0), (6.0, 0.5), (5.0, 6.0)])
def test_most_that_fit_bounds_the_largest_conflict_free_set(plate: Any, pitch: float, ligament: float) -> None:
    """The count check refuses only what is impossible: ``most_that_fit`` is never below the largest set of sites
    that can be drilled together (computed exactly here on coarse grids of the plate's top face)."""
    from cadfeat.design.added_targets import conflicts
    from cadfeat.study.added_targets import most_that_fit

    shape, holes = plate
    config = _config(pitch_mm=pitch)
    config.constraints = ConstraintSettings(edge_distance_mm=3.0, ligament_mm=ligament)
    sites = allowed_sites(config, shape, holes).sites
    assert 5 <= len(sites) <= 60
    exact = _most_at_once(conflicts(sites, 2.75, ligament))
    bound = most_that_fit(sites, 2.75, ligament)
    assert exact <= bound <= 2 * exact + 2, (exact, bound)
