"""STEP parts and re-drilling.

References: the fixture plate's construction values and the same plate BUILT DIRECTLY in CadQuery with
the holes left out or at their new places (tests/data/make_fixtures.py); analytic hole volumes; OCCT
BRepCheck; trimesh on the exported STL; hashlib on the input file's bytes.
"""

from __future__ import annotations

import hashlib
import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from cadfeat.cad.export import (
    check_solid,
    check_stl,
    export_step,
    export_stl,
    shape_volume_mm3,
    staged_output,
    verify_step_roundtrip,
)
from cadfeat.cad.step_parts import HoleMove, fill_holes, hole_profile, load_step, redrill
from cadfeat.errors import CadfeatError

DATA = Path(__file__).parents[1] / "data"
STEP = DATA / "plate_holes.step"
_spec = importlib.util.spec_from_file_location("make_fixtures", DATA / "make_fixtures.py")
fx = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fx)
T = fx.PLATE[2]

# (x, y) and entrance diameter of every fixture hole, by construction name
DESIGN = {"A": fx.PLAIN["A"], "B": fx.PLAIN["B"], "CBORE": (fx.CBORE[0], fx.CBORE[2]),
          "CSINK": (fx.CSINK[0], fx.CSINK[2]), "BLIND": (fx.BLIND[0], fx.BLIND[1])}
# the re-design used below: new (x, y) and entrance diameter; "B" stays
MOVED = {"A": ((-30.0, -20.0), 10.0), "CBORE": ((15.0, -15.0), 9.0), "CSINK": ((25.0, 15.0), 12.0),
         "BLIND": ((0.0, 5.0), 4.0)}


def hole_volume(name: str, entrance_dia: float) -> float:
    """Exact volume (mm³) of fixture hole ``name`` resized to ``entrance_dia`` (profile as in make_fixtures: a
    counterbore or countersink keeps its bore, a plain hole is the entrance diameter)."""
    if name in ("A", "B"):
        return math.pi * (entrance_dia / 2) ** 2 * T
    if name == "BLIND":
        return math.pi * (entrance_dia / 2) ** 2 * fx.BLIND[2]
    if name == "CBORE":
        _, bore, cbore, depth = fx.CBORE
        r_c, r_b = entrance_dia / 2, bore / 2
        return math.pi * (r_c**2 * depth + r_b**2 * (T - depth))
    _, bore, csink, angle = fx.CSINK
    r_c, r_b = entrance_dia / 2, bore / 2
    h = (r_c - r_b) / math.tan(math.radians(angle) / 2)
    return math.pi * (h * (r_c**2 + r_c * r_b + r_b**2) / 3 + r_b**2 * (T - h))


@pytest.fixture(scope="module")
def part():
    return load_step(STEP)


@pytest.fixture(scope="module")
def by_name(part):
    """Construction name -> extracted hole, picked by position (StepPart.select)."""
    return {name: part.select((*xy, T)) for name, (xy, _) in DESIGN.items()}


@pytest.fixture(scope="module")
def redrilled(part, by_name):
    moves = [HoleMove(by_name[n], np.array([*xy, T]), dia / 2) for n, (xy, dia) in MOVED.items()]
    return redrill(part.shape, moves)


# ------------------------------------------------------------------------------------------- load_step
def test_load_step_reads_one_solid_and_names_its_holes(part, by_name):
    assert part.name == "plate_holes" and part.path == STEP
    assert [h.name for h in part.holes] == [f"H{i}" for i in range(1, 6)]
    assert shape_volume_mm3(part.shape) == pytest.approx(shape_volume_mm3(fx.build_plate()), rel=1e-12)
    for name, (xy, dia) in DESIGN.items():
        hole = by_name[name]
        np.testing.assert_allclose(hole.centre, [*xy, T], atol=1e-9)
        np.testing.assert_allclose(hole.axis, [0, 0, 1], atol=1e-12)
        assert hole.radius_mm == pytest.approx(dia / 2, abs=1e-9)
    assert by_name["CBORE"].kind == "counterbore" and by_name["CSINK"].kind == "countersink"
    assert by_name["BLIND"].through is False and by_name["A"].through is True
    again = load_step(STEP).holes  # deterministic order and names
    np.testing.assert_array_equal([h.centre for h in again], [h.centre for h in part.holes])


def test_select_by_index_name_and_position(part, by_name):
    second = part.holes[1]
    assert part.select(2) is second and part.select("H2") is second and part.select("2") is second
    xy, _ = DESIGN["CBORE"]
    assert part.select((xy[0] + 0.004, xy[1], T)) is by_name["CBORE"]
    assert part.select(f"{xy[0]},{xy[1]},{T}") is by_name["CBORE"]
    with pytest.raises(CadfeatError, match=r"no hole 'H9'.*H1 \(.*H5 \("):
        part.select("H9")
    with pytest.raises(CadfeatError, match=r"no hole within 0.01 mm.*nearest H\d.*available holes: H1"):
        part.select((xy[0] + 1.0, xy[1], T))
    with pytest.raises(CadfeatError, match="no hole 0"):
        part.select(0)


def test_load_step_errors(tmp_path):
    import cadquery as cq

    with pytest.raises(CadfeatError, match="nothing.step.*not found"):
        load_step(tmp_path / "nothing.step")
    text = tmp_path / "text.step"
    text.write_text("solid cube\nendsolid\n")
    with pytest.raises(CadfeatError, match="text.step.*not a STEP"):
        load_step(text)
    face = export_step(cq.Face.makePlane(10, 10), tmp_path / "face.step")
    with pytest.raises(CadfeatError, match="face.step.*no solid.*exactly one solid"):
        load_step(face)
    two = cq.Compound.makeCompound([cq.Solid.makeBox(1, 1, 1), cq.Solid.makeBox(1, 1, 1, pnt=cq.Vector(5, 0, 0))])
    pair = export_step(two, tmp_path / "pair.step")
    with pytest.raises(CadfeatError, match="pair.step.*2 solids"):
        load_step(pair)


# ------------------------------------------------------------------------------------------- profiles
def test_hole_profiles_match_the_construction(part, by_name):
    for name, (_, dia) in DESIGN.items():
        profile = hole_profile(part.shape, by_name[name])
        assert profile.volume_mm3 == pytest.approx(hole_volume(name, dia), rel=1e-12)
    cbore = hole_profile(part.shape, by_name["CBORE"]).segments
    _, bore, cdia, cdepth = fx.CBORE
    np.testing.assert_allclose(cbore, [[0, cdepth, cdia / 2, cdia / 2], [cdepth, T, bore / 2, bore / 2]], atol=1e-9)


# ---------------------------------------------------------------------------------------------- filling
def _same_solid(a, b, rel: float = 1e-9) -> None:
    """Same volume, same face count, and no material in one that is not in the other."""
    va, vb = shape_volume_mm3(a), shape_volume_mm3(b)
    assert va == pytest.approx(vb, rel=rel)
    assert shape_volume_mm3(a.cut(b)) <= rel * va and shape_volume_mm3(b.cut(a)) <= rel * va
    assert len(a.Faces()) == len(b.Faces())


@pytest.mark.parametrize("name", ["A", "CBORE", "CSINK", "BLIND"])
def test_fill_one_hole_equals_the_plate_built_without_it(part, by_name, name):
    filled = fill_holes(part.shape, [by_name[name]])
    assert check_solid(filled) == []
    _same_solid(filled, fx.build_plate(skip=(name,)))


def test_fill_all_holes_gives_back_the_plain_plate(part):
    filled = fill_holes(part.shape, part.holes)
    assert len(filled.Faces()) == 6  # the box's faces: the filled host faces merged back
    assert shape_volume_mm3(filled) == pytest.approx(math.prod(fx.PLATE), rel=1e-9)


# -------------------------------------------------------------------------------------------- redrill
def test_redrill_equals_the_plate_built_with_the_new_holes(redrilled):
    assert check_solid(redrilled) == []
    _same_solid(redrilled, fx.build_plate(moved=MOVED))


def test_redrill_volume_change_is_the_analytic_hole_volume_change(part, redrilled):
    change = sum(hole_volume(n, DESIGN[n][1]) - hole_volume(n, dia) for n, (_, dia) in MOVED.items())
    assert shape_volume_mm3(redrilled) - shape_volume_mm3(part.shape) == pytest.approx(change, rel=1e-6)


def test_redrill_keeps_other_holes_and_moves_the_chosen_ones(part, by_name, redrilled):
    from cadfeat.cad.features import extract_holes

    after = extract_holes(redrilled)
    assert len(after) == len(part.holes)
    by_centre = {tuple(np.round(h.centre, 6)): h for h in after}
    untouched = by_name["B"]
    kept = by_centre[tuple(np.round(untouched.centre, 6))]
    for key in ("radius_mm", "bore_radius_mm", "depth_mm"):
        assert getattr(kept, key) == pytest.approx(getattr(untouched, key), abs=1e-9)
    assert (kept.kind, kept.through) == (untouched.kind, untouched.through)
    for name, (xy, dia) in MOVED.items():
        moved = by_centre[(*np.round(xy, 6), round(T, 6))]
        old = by_name[name]
        assert moved.radius_mm == pytest.approx(dia / 2, abs=1e-9)
        bore = dia / 2 if old.kind == "plain" else old.bore_radius_mm  # resize keeps the screw bore
        assert moved.bore_radius_mm == pytest.approx(bore, abs=1e-9)
        assert moved.depth_mm == pytest.approx(old.depth_mm, abs=1e-9)
        assert (moved.kind, moved.through) == (old.kind, old.through)
        np.testing.assert_allclose(moved.axis, old.axis, atol=1e-12)


def test_redrilled_part_exports_a_watertight_stl_and_exact_step(redrilled, tmp_path):
    import trimesh

    from cadfeat.cad.features import extract_holes

    stl = export_stl(redrilled, tmp_path / "r.stl", tolerance_mm=0.01)
    mesh = trimesh.load(str(stl), file_type="stl", force="mesh")
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert check_stl(stl, redrilled, tolerance_mm=0.01) == []
    step = export_step(redrilled, tmp_path / "r.step")
    verify_step_roundtrip(step, extract_holes(redrilled), expected_volume_mm3=shape_volume_mm3(redrilled))


def test_redrill_rejects_bad_moves(part, by_name):
    a = by_name["A"]
    with pytest.raises(CadfeatError, match=r"off its host face plane"):
        redrill(part.shape, [HoleMove(a, np.array([-30.0, -20.0, T + 1e-4]), 4.0)])
    with pytest.raises(CadfeatError, match="radius_mm must be > 0"):
        HoleMove(a, np.array([-30.0, -20.0, T]), 0.0)
    with pytest.raises(CadfeatError, match="breaks out of the part or overlaps"):  # into hole B
        redrill(part.shape, [HoleMove(a, np.array([-25.0, 10.0, T]), 4.0)])
    with pytest.raises(CadfeatError, match="breaks out of the part or overlaps"):  # over the plate's edge
        redrill(part.shape, [HoleMove(a, np.array([-38.0, -20.0, T]), 4.0)])


def test_redrill_on_a_tilted_face_equals_the_direct_build():
    """A blind hole drilled normal to a 45° chamfer face, moved along that face and made smaller."""
    import cadquery as cq

    from cadfeat.cad.features import extract_holes

    def on_chamfer():
        block = cq.Workplane().box(40, 40, 20, centered=(True, True, False)).faces(">Z").edges(">X").chamfer(12)
        face = block.faces(cq.selectors.DirectionMinMaxSelector(cq.Vector(1, 0, 1)))
        return face.workplane(centerOption="CenterOfBoundBox")

    original = on_chamfer().hole(4.0, 5.0).val()
    (hole,) = extract_holes(original)
    new_centre = np.array(on_chamfer().plane.toWorldCoords((3.0, -4.0)).toTuple())
    moved = redrill(original, [HoleMove(hole, new_centre, 1.5)])
    assert check_solid(moved) == []
    _same_solid(moved, on_chamfer().pushPoints([(3.0, -4.0)]).hole(3.0, 5.0).val())


def test_redrill_keeps_the_drill_point_angle():
    """A blind hole with a 118° drill point: the bore is rescaled, the cylinder depth and tip angle kept."""
    import cadquery as cq

    from cadfeat.cad.features import extract_holes

    half_tip = math.radians(59.0)

    def drilled(x: float, y: float, r: float):
        section = [(0, 10), (r, 10), (r, 4), (0, 4 - r / math.tan(half_tip))]  # (radius, z) in the XZ plane
        tool = cq.Workplane("XZ").polyline(section).close().revolve(360, (0, 0, 0), (0, 1, 0)).translate((x, y, 0))
        return cq.Workplane().box(40, 40, 10, centered=(True, True, False)).cut(tool).val()

    original = drilled(0.0, 0.0, 3.0)
    (hole,) = extract_holes(original)
    profile = hole_profile(original, hole)
    assert profile.conical.tolist() == [False, True]
    np.testing.assert_allclose(profile.segments, [[0, 6, 3, 3], [6, 6 + 3 / math.tan(half_tip), 3, 0]], atol=1e-9)
    moved = redrill(original, [HoleMove(hole, np.array([8.0, 5.0, 10.0]), 2.0)])
    assert check_solid(moved) == []
    _same_solid(moved, drilled(8.0, 5.0, 2.0))


def test_redrill_refuses_a_through_hole_that_would_not_come_out():
    import cadquery as cq

    from cadfeat.cad.features import extract_holes

    plate = cq.Workplane().box(80, 60, 10, centered=(True, True, False)).faces(">Z").workplane().hole(6)
    stepped = plate.union(cq.Workplane().box(20, 60, 5, centered=(False, True, False)).translate((20, 0, -5))).val()
    (hole,) = extract_holes(stepped)
    assert hole.through and hole.depth_mm == pytest.approx(10.0, abs=1e-9)
    assert check_solid(redrill(stepped, [HoleMove(hole, np.array([10.0, 0.0, 10.0]), 3.0)])) == []
    with pytest.raises(CadfeatError, match="not 10 mm thick at the new centre"):  # over the 15 mm step
        redrill(stepped, [HoleMove(hole, np.array([30.0, 0.0, 10.0]), 3.0)])


def test_input_step_is_never_modified(tmp_path):
    before = hashlib.sha256(STEP.read_bytes()).hexdigest()
    mtime = STEP.stat().st_mtime_ns
    part = load_step(STEP)
    hole = part.holes[0]
    new = redrill(part.shape, [HoleMove(hole, hole.centre + 2.0 * np.cross(hole.axis, [1.0, 0, 0]),
                                        hole.radius_mm)])
    with staged_output(tmp_path / "out") as stage:
        export_step(new, stage / "plate_holes.step")
    assert hashlib.sha256(STEP.read_bytes()).hexdigest() == before and STEP.stat().st_mtime_ns == mtime
    assert (tmp_path / "out" / "plate_holes.step").is_file()
