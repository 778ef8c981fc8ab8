"""STEP/STL export and verification, staged output.

References: the construction values of the fixture plate (tests/data/make_fixtures.py), the STEP file's
own text, OCCT re-import, trimesh's mesh checks, and hashlib on the raw bytes.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import math
import os
import re
import stat
import struct
from pathlib import Path

import numpy as np
import pytest

from cadfeat.cad.export import (
    ExportError,
    check_solid,
    check_stl,
    export_step,
    export_stl,
    import_step,
    mesh_from_shape,
    sha256_file,
    shape_volume_mm3,
    staged_output,
    step_length_unit,
    verify_step_roundtrip,
)
from cadfeat.errors import CadfeatError

DATA = Path(__file__).parents[1] / "data"
_spec = importlib.util.spec_from_file_location("make_fixtures", DATA / "make_fixtures.py")
fx = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fx)


def analytic_plate_volume() -> float:
    """Plate volume from the construction values: box minus each hole's exact profile volume."""
    x, y, z = fx.PLATE
    vol = x * y * z
    for _, dia in fx.PLAIN.values():
        vol -= math.pi * (dia / 2) ** 2 * z
    _, bore, cbore, cdepth = fx.CBORE
    vol -= math.pi * (cbore / 2) ** 2 * cdepth + math.pi * (bore / 2) ** 2 * (z - cdepth)
    _, bore, csink, angle = fx.CSINK
    r_big, r_small = csink / 2, bore / 2
    h_cone = (r_big - r_small) / math.tan(math.radians(angle) / 2)
    vol -= math.pi * h_cone * (r_big**2 + r_big * r_small + r_small**2) / 3 + math.pi * r_small**2 * (z - h_cone)
    _, dia, depth = fx.BLIND
    vol -= math.pi * (dia / 2) ** 2 * depth
    return vol


@pytest.fixture(scope="module")
def plate():
    return fx.build_plate()


@pytest.fixture(scope="module")
def plate_step(plate, tmp_path_factory):
    return export_step(plate, tmp_path_factory.mktemp("step") / "plate.step")


# ------------------------------------------------------------------------------------------------ STEP
def test_step_file_declares_millimetres_and_ap214(plate_step):
    text = plate_step.read_text()
    assert "AUTOMOTIVE_DESIGN" in re.search(r"FILE_SCHEMA\s*\(\s*\(\s*'([^']*)'", text).group(1)
    length_units = [e for e in text.split(";") if "LENGTH_UNIT" in e]
    assert len(length_units) == 1
    assert re.search(r"SI_UNIT\s*\(\s*\.MILLI\.\s*,\s*\.METRE\.\s*\)", length_units[0])
    assert step_length_unit(plate_step) == "MM"


def test_step_unit_is_read_from_other_writers(plate, tmp_path):
    """cadquery's own exporter writing inch and metre files: our unit reader and importer agree."""
    for unit in ("INCH", "M"):
        path = tmp_path / f"plate_{unit}.step"
        plate.exportStep(str(path), outputUnit=unit)
        assert step_length_unit(path) == unit
        with pytest.raises(ExportError, match=f"length unit is {unit}"):
            verify_step_roundtrip(path, [])
        bb = import_step(path).BoundingBox()  # OCCT converts back to mm
        assert (bb.xlen, bb.ylen, bb.zlen) == pytest.approx(fx.PLATE, abs=1e-6)


def test_roundtrip_keeps_dimensions_and_volume(plate, plate_step):
    back = import_step(plate_step)
    bb = back.BoundingBox()
    assert (bb.xmin, bb.ymin, bb.zmin) == pytest.approx((-40.0, -30.0, 0.0), abs=1e-9)
    assert (bb.xmax, bb.ymax, bb.zmax) == pytest.approx((40.0, 30.0, 10.0), abs=1e-9)
    assert shape_volume_mm3(back) == pytest.approx(analytic_plate_volume(), rel=1e-9)
    assert shape_volume_mm3(plate) == pytest.approx(analytic_plate_volume(), rel=1e-9)
    assert len(back.Faces()) == len(plate.Faces())
    assert check_solid(back) == []


def test_verify_roundtrip_holes(plate, plate_step):
    from cadfeat.cad.features import extract_holes

    designed = extract_holes(plate)
    assert len(designed) == 5
    rt = verify_step_roundtrip(plate_step, designed, expected_volume_mm3=analytic_plate_volume())
    assert rt.n_holes == 5 and rt.unit == "MM"
    assert rt.max_centre_error_mm <= 1e-6 and rt.max_radius_error_mm <= 1e-6 and rt.max_depth_error_mm <= 1e-6
    assert rt.volume_rel_error <= 1e-9
    assert rt.sha256 == hashlib.sha256(plate_step.read_bytes()).hexdigest()
    # the re-imported holes are the constructed ones (independent of the extraction of the original)
    reimported = {(round(h.centre[0], 6), round(h.centre[1], 6)): h for h in extract_holes(import_step(plate_step))}
    (xy, dia) = fx.PLAIN["A"]
    assert reimported[xy].radius_mm == pytest.approx(dia / 2, abs=1e-9)
    assert reimported[xy].centre[2] == pytest.approx(10.0, abs=1e-9)
    np.testing.assert_allclose(reimported[xy].axis, [0, 0, 1], atol=1e-12)


def test_verify_roundtrip_names_the_mismatch(plate, plate_step):
    import dataclasses

    from cadfeat.cad.features import extract_holes

    designed = extract_holes(plate)
    moved = [dataclasses.replace(designed[0], centre=designed[0].centre + [1e-3, 0, 0], name="H7"),
             *designed[1:]]
    with pytest.raises(ExportError, match=r"plate.step: hole H7 at .*: centre error 1.000e-03 mm > 1e-06"):
        verify_step_roundtrip(plate_step, moved)
    wider = [dataclasses.replace(designed[1], radius_mm=designed[1].radius_mm + 1e-4, name="H2"),
             designed[0], *designed[2:]]
    with pytest.raises(ExportError, match=r"hole H2 at .*: radius error 1.000e-04 mm"):
        verify_step_roundtrip(plate_step, wider)
    far = [dataclasses.replace(designed[0], centre=designed[0].centre + [0, 0, 5.0], name="H3"), *designed[1:]]
    with pytest.raises(ExportError, match="do not match the design.*H3"):
        verify_step_roundtrip(plate_step, far)
    with pytest.raises(ExportError, match="volume"):
        verify_step_roundtrip(plate_step, designed, expected_volume_mm3=analytic_plate_volume() * (1 + 1e-7))
    with pytest.raises(ExportError, match="4 designed"):
        verify_step_roundtrip(plate_step, designed[:4])


def test_import_step_errors(tmp_path):
    with pytest.raises(CadfeatError, match="missing.step.*not found"):
        import_step(tmp_path / "missing.step")
    bad = tmp_path / "notes.step"
    bad.write_text("hello\n")
    with pytest.raises(CadfeatError, match="notes.step.*not a STEP"):
        import_step(bad)


# -------------------------------------------------------------------------------------------- validity
def test_check_solid_reports_invalid_shapes():
    import cadquery as cq
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakePolygon, BRepBuilderAPI_MakeSolid
    from OCP.gp import gp_Pnt

    assert check_solid(cq.Solid.makeBox(1, 2, 3)) == []
    # a bow-tie (self-intersecting) face
    poly = BRepBuilderAPI_MakePolygon(gp_Pnt(0, 0, 0), gp_Pnt(1, 1, 0), gp_Pnt(1, 0, 0), gp_Pnt(0, 1, 0), True)
    bowtie = BRepBuilderAPI_MakeFace(poly.Wire(), True).Face()
    assert any("SelfIntersectingWire" in p for p in check_solid(bowtie))
    # a "solid" whose shell lacks one face of a box
    box = cq.Solid.makeBox(1, 1, 1)
    shell = cq.Shell.makeShell(box.Faces()[:5])
    open_solid = BRepBuilderAPI_MakeSolid(shell.wrapped).Solid()
    problems = check_solid(open_solid)
    assert any("NotClosed" in p for p in problems), problems


# ------------------------------------------------------------------------------------------------- STL
def test_stl_is_binary_watertight_and_close_to_the_brep(plate, tmp_path):
    import trimesh

    path = export_stl(plate, tmp_path / "plate.stl", tolerance_mm=0.01)
    raw = path.read_bytes()
    (n_tri,) = struct.unpack("<I", raw[80:84])
    assert len(raw) == 84 + 50 * n_tri  # binary STL layout
    mesh = trimesh.load(str(path), file_type="stl", force="mesh")
    assert mesh.is_watertight and mesh.is_winding_consistent
    area = plate.Area()
    assert abs(mesh.volume - analytic_plate_volume()) <= area * 0.01
    assert check_stl(path, plate, tolerance_mm=0.01) == []
    # a coarser absolute tolerance gives a mesh further from the B-rep but within its own bound
    coarse = export_stl(plate, tmp_path / "coarse.stl", tolerance_mm=0.2, angular_tolerance_rad=1.0)
    coarse_mesh = trimesh.load(str(coarse), file_type="stl", force="mesh")
    assert len(coarse_mesh.faces) < len(mesh.faces)
    assert abs(coarse_mesh.volume - analytic_plate_volume()) <= area * 0.2
    assert check_stl(coarse, plate, tolerance_mm=0.2) == []


def test_mesh_from_shape_is_a_closed_outward_mesh(plate):
    mesh = mesh_from_shape(plate, 0.01)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    assert abs(mesh.volume - analytic_plate_volume()) <= plate.Area() * 0.01
    bounds = mesh.bounds
    np.testing.assert_allclose(bounds, [[-40, -30, 0], [40, 30, 10]], atol=1e-9)


def test_check_stl_reports_holes_in_the_mesh(plate, tmp_path):
    mesh = mesh_from_shape(plate, 0.05)
    mesh.update_faces(np.arange(len(mesh.faces)) != 0)  # drop one triangle
    path = tmp_path / "open.stl"
    mesh.export(str(path))
    problems = check_stl(path, plate, tolerance_mm=0.05)
    assert any("not watertight" in p for p in problems)
    assert check_stl(tmp_path / "none.stl") == [f"{tmp_path / 'none.stl'}: file not found"]


# ---------------------------------------------------------------------------------------- staged output
def _snapshot(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_staged_output_publishes_on_success(plate, tmp_path):
    final = tmp_path / "out"
    with staged_output(final) as stage:  # a previous run: a folder cadfeat created
        (stage / "old.txt").write_text("previous run")
    with staged_output(final) as stage:
        assert stage.parent == final.parent and stage != final
        assert not (final / "part.step").exists()
        export_step(plate, stage / "part.step")
        (stage / "sub").mkdir()
        (stage / "sub" / "notes.txt").write_text("x")
        assert not (final / "part.step").exists()  # nothing visible before the block ends
    assert sorted(_snapshot(final)) == [".cadfeat-output.json", "part.step", "sub/notes.txt"]  # old one replaced
    assert step_length_unit(final / "part.step") == "MM"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no staging or backup folder left
    umask = os.umask(0o022)
    os.umask(umask)
    assert stat.S_IMODE(final.stat().st_mode) == 0o777 & ~umask  # like a folder made by mkdir


@pytest.mark.parametrize("error", [RuntimeError("boom"), KeyboardInterrupt()])
def test_staged_output_failure_leaves_everything_as_it_was(plate, tmp_path, error):
    final = tmp_path / "out"
    with staged_output(final) as stage:
        export_step(plate, stage / "part.step")
    before = _snapshot(final)
    with pytest.raises(type(error)), staged_output(final) as stage:
        (stage / "part.step").write_text("half-written")
        (stage / "extra.stl").write_bytes(b"\0" * 100)
        raise error
    assert _snapshot(final) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_staged_output_creates_a_new_folder_and_refuses_a_file(tmp_path):
    with staged_output(tmp_path / "a" / "b") as stage:
        (stage / "r.txt").write_text("ok")
    assert (tmp_path / "a" / "b" / "r.txt").read_text() == "ok"
    assert json.loads((tmp_path / "a" / "b" / ".cadfeat-output.json").read_text())["files"] == ["r.txt"]
    (tmp_path / "file").write_text("")
    with pytest.raises(CadfeatError, match="not a folder"), staged_output(tmp_path / "file"):
        pass


def test_sha256_file_matches_hashlib(plate_step):
    assert sha256_file(plate_step) == hashlib.sha256(plate_step.read_bytes()).hexdigest()
