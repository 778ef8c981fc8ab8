"""The CAD kernel's misbehaviours on real STEP exports (``../shared/real_step``, the parts added 2026-11-28), pinned
as build123d's ``test_occt_bugs.py`` does: each test states what OCCT does today and that cadfeat's workaround
still gives the right answer, so an OCCT upgrade that fixes or changes one is noticed here (then the workaround
may go), not as a wrong answer elsewhere. Issue 32 item 9.

- ``BRepGProp`` integrates a face along its p-curves: the Inventor bearing clamp's 45° cone faces, bounded by
  B-spline edges whose p-curves lie up to the edge tolerance (7e-3 mm) off the 3-D curves, come out 1.6e-4 smaller
  than their own fine mesh; the same face written by OCCT and read back agrees with the mesh. So the part's
  volume moves by 1.5e-5 relative on a STEP write/re-read that changes no geometry, and a round-trip volume check
  against ``V(design)`` fails on the unmodified part (``export.expected_step_volume`` compares with the re-read
  original instead).
- ``BRepMesh`` leaves a Fusion 360 45° entrance cone whose u-range is [π, 3π] without triangles at every chord and
  angular tolerance; its NURBS form meshes (``export._triangulate_as_nurbs``).
- FreeCAD (OCC 7.5) writes the Thor holder's Ø26 bore and a 20° sliver of the same cylinder above the plate as one
  face z 0..11.6 (an export trait, not a kernel bug: the hole is 3.6 deep; ``hole_profiles`` reads the wall
  within the depth).
"""

from __future__ import annotations

import numpy as np
import pytest
import real_step_truth as rs

cq = pytest.importorskip("cadquery")

FOLDER = rs.real_step_dir()
if FOLDER is None:
    pytest.skip("no shared/real_step beside the repository (CADFEAT_REAL_STEP unset)", allow_module_level=True)


def _solid(name: str):
    from cadfeat.cad.export import import_step

    return cq.Solid(import_step(FOLDER / name).Solids()[0].wrapped)


def _mesh_area(face, deflection: float) -> float:
    from OCP.BRep import BRep_Tool
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools
    from OCP.TopLoc import TopLoc_Location

    BRepTools.Clean_s(face)
    BRepMesh_IncrementalMesh(face, deflection, False, 0.05, False)
    tri = BRep_Tool.Triangulation_s(face, TopLoc_Location())
    p = np.array([[tri.Node(i).X(), tri.Node(i).Y(), tri.Node(i).Z()] for i in range(1, tri.NbNodes() + 1)])
    t = np.array([tri.Triangle(i).Get() for i in range(1, tri.NbTriangles() + 1)]) - 1
    return float(0.5 * np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1).sum())


def _cones(solid) -> list:
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_Cone

    return [f for f in solid.Faces() if BRepAdaptor_Surface(f.wrapped).GetType() == GeomAbs_Cone]


def test_gprop_area_of_inventor_cone_faces_is_off_their_mesh_until_written_and_read_again(tmp_path):
    from cadfeat.cad.export import export_step, import_step

    original = _solid("ptm_bearing_clamp.step")
    export_step(original, tmp_path / "again.step")
    again = cq.Solid(import_step(tmp_path / "again.step").Solids()[0].wrapped)
    worst_before = worst_after = 0.0
    centres = np.array([f.Center().toTuple() for f in _cones(again)])
    for face in _cones(original):
        twin = _cones(again)[int(np.argmin(np.linalg.norm(centres - face.Center().toTuple(), axis=1)))]
        mesh = _mesh_area(face.wrapped, 1e-4)
        worst_before = max(worst_before, abs(face.Area() - mesh) / mesh)
        worst_after = max(worst_after, abs(twin.Area() - _mesh_area(twin.wrapped, 1e-4)) / mesh)
    assert worst_before > 1e-4  # OCCT today: GProp along the Inventor p-curves, 1.6e-4 off
    assert worst_after < 2e-5   # the same faces as OCCT writes them: the mesh agrees (to its own chord error)
    rel = abs(again.Volume() - original.Volume()) / original.Volume()
    assert rel > 5e-6  # 1.5e-5: no geometry changed, only how the volume is integrated


def test_the_round_trip_volume_check_holds_on_a_re_drilled_inventor_part(tmp_path):
    """A re-drilled hole of the bearing clamp written to STEP: checked against V(design) the volume is off by
    1.5e-5 (the kernel's share above); against the re-read original plus the design's change it is exact."""
    from cadfeat.cad.export import ExportError, expected_step_volume, export_step, shape_volume_mm3
    from cadfeat.cad.export import verify_step_roundtrip as verify
    from cadfeat.cad.features import extract_holes
    from cadfeat.cad.step_parts import HoleMove, load_step, redrill

    part = load_step(FOLDER / "ptm_bearing_clamp.step")
    hole = min(part.holes, key=lambda h: h.radius_mm)  # the Ø1.8 pin hole
    design = redrill(part.shape, [HoleMove(hole, hole.centre + 0.3 * rs.move_direction(part, hole), hole.radius_mm)],
                     part.tolerance, part.path)
    export_step(part.shape, tmp_path / "original.step")
    export_step(design, tmp_path / "optimised.step")
    expected = extract_holes(design)
    with pytest.raises(ExportError, match="volume"):
        verify(tmp_path / "optimised.step", expected, tol_mm=1e-6, expected_volume_mm3=shape_volume_mm3(design),
               volume_rtol=1e-7)
    volume, uncertainty = expected_step_volume(design, part.shape, tmp_path / "original.step")
    assert uncertainty == pytest.approx(0.455, abs=0.01)  # the original's own volume error (1.5e-5)
    trip = verify(tmp_path / "optimised.step", expected, tol_mm=1e-6, expected_volume_mm3=volume, volume_rtol=1e-7)
    assert trip.volume_rel_error < 1e-7  # 2e-8 without the uncertainty: the pin hole's faces were exact


def test_brepmesh_leaves_a_fusion_cone_with_u_from_pi_to_3pi_empty_but_meshes_its_nurbs_form():
    from OCP.BRep import BRep_Tool
    from OCP.BRepBuilderAPI import BRepBuilderAPI_NurbsConvert
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools
    from OCP.TopLoc import TopLoc_Location

    from cadfeat.cad.export import mesh_from_shape

    solid = _solid("lcr_gripper_moving_part.step")
    BRepMesh_IncrementalMesh(solid.wrapped, 0.01, False, 0.1, False)
    empty = [f.wrapped for f in solid.Faces() if BRep_Tool.Triangulation_s(f.wrapped, TopLoc_Location()) is None]
    assert len(empty) == 1  # OCCT today: one entrance cone of the eight alike
    face = empty[0]
    assert any(face.IsSame(f.wrapped) for f in _cones(solid))
    np.testing.assert_allclose(BRepTools.UVBounds_s(face)[:2], [np.pi, 3 * np.pi], atol=1e-9)
    for deflection, angle in ((0.01, 1.0), (0.1, 0.5), (0.001, 0.1)):
        BRepTools.Clean_s(solid.wrapped)
        BRepMesh_IncrementalMesh(solid.wrapped, deflection, False, angle, False)
        assert BRep_Tool.Triangulation_s(face, TopLoc_Location()) is None  # at any tolerance
    nurbs = BRepBuilderAPI_NurbsConvert(face, True).Shape()
    BRepMesh_IncrementalMesh(nurbs, 0.01, False, 0.1, False)
    from OCP.TopoDS import TopoDS

    assert BRep_Tool.Triangulation_s(TopoDS.Face_s(nurbs), TopLoc_Location()) is not None
    mesh = mesh_from_shape(solid, 0.01)  # cadfeat: the NURBS copy's triangulation, one meshing for all faces
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(solid.Volume(), rel=1e-3)


def test_freecad_writes_a_bore_and_a_sliver_of_its_cylinder_above_the_plate_as_one_face():
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_Cylinder

    from cadfeat.cad.step_parts import hole_profile, load_step

    part = load_step(FOLDER / "thor_motor_holder_a.step")
    (bore,) = [f for f in part.shape.Faces() if BRepAdaptor_Surface(f.wrapped).GetType() == GeomAbs_Cylinder
               and BRepAdaptor_Surface(f.wrapped).Cylinder().Radius() == pytest.approx(13.0)]
    box = bore.BoundingBox()
    assert (box.zmin, box.zmax) == (pytest.approx(0.0, abs=1e-6), pytest.approx(11.6, abs=1e-6))
    (hole,) = [h for h in part.holes if h.radius_mm == pytest.approx(13.0)]
    assert hole.depth_mm == pytest.approx(3.6, abs=1e-6) and hole.through
    profile = hole_profile(part.shape, hole, part.tolerance, part.path)
    np.testing.assert_allclose(profile.segments, [[0.0, 3.6, 13.0, 13.0]], atol=1e-6)
