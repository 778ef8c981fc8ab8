"""Added target holes in CAD (issue 31, ``cad.drill_targets``): cut into a part script's built solid and into a
real STEP part's B-rep, checked against exact geometry, re-extraction and the re-imported STEP."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from cadfeat.cad.drill_targets import AddedHole, drill_targets, planar_faces, verify_drilled
from cadfeat.design.constraints import ConstraintConfig, verify_on_brep
from cadfeat.errors import CadfeatError
from tests.real_step_truth import real_step_dir

cq = pytest.importorskip("cadquery")
ROOT = Path(__file__).resolve().parents[2]
UP, FRONT = np.array([0, 0, 1.0]), np.array([0, -1.0, 0])


@pytest.fixture(scope="module")
def mount() -> Any:
    from cadfeat.cad.features import as_shape, extract_holes
    from cadfeat.cad.parts import load_part

    part = load_part(ROOT / "parts" / "nema17_mount.py")
    shape = as_shape(part.build(**part.defaults()))
    return shape, extract_holes(shape, prefer_direction=(0, -1, 1))


def test_planar_faces_of_the_mount(mount: Any) -> None:
    shape, _ = mount
    faces = planar_faces(shape)
    front = max((f for f in faces if f.normal @ FRONT > 0.999), key=lambda f: f.area_mm2)
    top = max((f for f in faces if f.normal @ UP > 0.999), key=lambda f: f.area_mm2)
    # motor face 70 x 58 minus the pilot bore and 4 M3 rims (the outer polygon: the full rectangle)
    assert front.area_mm2 == pytest.approx(70 * 58, rel=1e-6)
    assert len(front.holes) == 6  # pilot, 4 x M3, the face target
    assert top.area_mm2 == pytest.approx(70 * 65, rel=1e-6) and len(top.outline.keepouts) == 2  # the two slots


def test_drilled_holes_are_where_they_were_put(mount: Any, tmp_path: Path) -> None:
    """Exact geometry: each added hole re-extracted at its centre, axis, rim radius (drill + chamfer) and depth;
    the removed volume the analytic one; every old hole unchanged; STEP round trip the same."""
    from cadfeat.cad.export import export_step, import_step, shape_volume_mm3

    shape, holes = mount
    added = [AddedHole(np.array([-28.0, 0.0, 8.0]), FRONT, 2.75, 2.0, 0.4, "H10"),
             AddedHole(np.array([12.0, 62.0, 5.0]), UP, 2.75, 2.0, 0.0, "H11")]
    result, found = drill_targets(shape, added, holes, label="mount", prefer_direction=(0, -1, 1))
    assert [h.name for h in found] == [h.name for h in holes] + ["H10", "H11"]
    for h, a in zip(found[-2:], added, strict=True):
        assert np.allclose(h.centre, a.centre, atol=1e-7) and np.allclose(h.axis, a.axis, atol=1e-9)
        assert h.radius_mm == pytest.approx(a.radius_mm + a.chamfer_mm, abs=1e-7)
        assert h.bore_radius_mm == pytest.approx(a.radius_mm, abs=1e-7)
        assert h.depth_mm == pytest.approx(2.0, abs=1e-7) and not h.through
    r, c = 2.75, 0.4
    chamfer_cone = np.pi * c / 3 * ((r + c) ** 2 + (r + c) * r + r * r) - np.pi * r * r * c
    removed = shape_volume_mm3(shape) - shape_volume_mm3(result)
    assert removed == pytest.approx(2 * np.pi * r * r * 2.0 + chamfer_cone, rel=1e-7)
    for old, new in zip(holes, found, strict=False):
        assert np.allclose(old.centre, new.centre, atol=1e-9) and old.radius_mm == pytest.approx(new.radius_mm)
    export_step(result, tmp_path / "a.step")
    back = verify_drilled(import_step(tmp_path / "a.step"), holes, added, label="re-imported",
                          prefer_direction=(0, -1, 1))
    assert [h.name for h in back] == [h.name for h in found]
    checks = verify_on_brep(result, found, ConstraintConfig(3.0, 3.0), [True] * len(holes) + [False, False],
                            prefer_direction=(0, -1, 1))
    assert checks and all(c.ok for c in checks)
    assert {c.name for c in checks} >= {"edge", "ligament", "holes_match"}


def test_a_hole_that_breaks_out_is_refused(mount: Any) -> None:
    shape, holes = mount
    out = AddedHole(np.array([0.0, 60.0, 5.0]), UP, 2.75, 6.0, 0.0, "H10")  # deeper than the 5 mm flange
    with pytest.raises(CadfeatError, match=r"mount: drilling H10 removed .* an added hole breaks out of the part"):
        drill_targets(shape, [out], holes, label="mount")


@pytest.mark.slow
def test_a_real_step_part_with_added_targets(tmp_path: Path) -> None:
    """A real third-party STEP part (ptm_support_leg): two added holes on its top face between its holes, the
    B-rep exported and re-imported — every old hole unchanged, every added hole where it was put, the
    requirements measured by OCCT."""
    from types import SimpleNamespace

    from cadfeat.cad.export import export_step, import_step
    from cadfeat.cad.step_parts import load_step
    from cadfeat.study.added_targets import allowed_sites
    from cadfeat.study.settings import ConstraintSettings, ShopSettings
    from cadfeat.study.settings.add_targets import AddTargetsSettings

    folder = real_step_dir()
    if folder is None or not (folder / "ptm_support_leg.step").is_file():
        pytest.skip("the real STEP corpus is not here")
    part = load_step(folder / "ptm_support_leg.step")
    config = SimpleNamespace(label="leg", add_targets=AddTargetsSettings(faces=["+z"], diameter_mm=3.4, depth_mm=2.0,
                                                                         chamfer_mm=0.2, pitch_mm=4.0),
                             constraints=ConstraintSettings(edge_distance_mm=2.0, ligament_mm=2.0), shop=ShopSettings())
    sites = allowed_sites(config, part.shape, list(part.holes)).sites
    far = int(np.argmax(np.linalg.norm(sites.centres - sites.centres[0], axis=1)))
    added = [AddedHole(sites.centres[i], sites.axes[i], 1.7, 2.0, 0.2, f"H{15 + j}") for j, i in enumerate((0, far))]
    result, found = drill_targets(part.shape, added, list(part.holes), part.tolerance, label="leg")
    export_step(result, tmp_path / "leg.step")
    back = verify_drilled(import_step(tmp_path / "leg.step"), list(part.holes), added, part.tolerance, "leg.step")
    assert [h.name for h in back] == [h.name for h in part.holes] + ["H15", "H16"]
    for old, new in zip(part.holes, back, strict=False):
        assert np.linalg.norm(old.centre - new.centre) < 1e-6 and abs(old.radius_mm - new.radius_mm) < 1e-6
        assert abs(old.depth_mm - new.depth_mm) < 1e-6 and old.through == new.through
    checks = verify_on_brep(result, found, ConstraintConfig(2.0, 2.0), [True] * len(part.holes) + [False, False])
    assert all(c.ok for c in checks), [c for c in checks if not c.ok]
