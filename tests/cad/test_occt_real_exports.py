"""Pins of OCCT behaviours that cadfeat works around (like build123d's test_occt_bugs.py).

Each test asserts the behaviour as it is today, on a real third-party export (``../shared/real_step``). If a
new OCCT release changes it, the test fails: then check whether the workaround named in the test is still
needed. References: closed-form hole volumes (cylinder plus cone) and the untouched part's own volume.
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
import real_step_truth as rs

FOLDER = rs.real_step_dir()
if FOLDER is None:
    if os.environ.get("CI"):
        raise RuntimeError("tests/cad/test_occt_real_exports.py: no shared/real_step beside the repository")
    pytest.skip("no shared/real_step beside the repository (CADFEAT_REAL_STEP unset)", allow_module_level=True)


def test_cut_of_two_near_identical_solids_fails_but_intersect_with_the_hole_solid_is_exact():
    """A blind Ø3.4 pilot hole whose drill-point apex touches a pocket wall (OpenBot phone mount, Fusion 360):
    filled with its own profile and cut again, ``filled.cut(result)`` (the material the cut removed) returns most
    of the part instead of the 33.3 mm³ hole. Workaround (``step_parts._material_in``): the re-drilling checks
    measure the part's material inside the small hole solid (``filled ∩ tool``), which is exact."""
    from cadfeat.cad.export import shape_volume_mm3
    from cadfeat.cad.hole_profiles import revolved
    from cadfeat.cad.step_parts import fill_holes, hole_profile, load_step

    part = load_step(FOLDER / "openbot_phone_mount_bottom.step")
    hole = part.select((20.0, 7.5, 11.0), tol_mm=1e-3)
    r = 1.7  # Ø3.4, cylinder 3 mm then an 80.7° drill point 2 mm long (truth.json)
    closed_form = math.pi * r * r * (3.0 + 2.0 / 3.0)
    profile = hole_profile(part.shape, hole, part.tolerance)
    assert profile.volume_mm3 == pytest.approx(closed_form, rel=1e-6)
    tool = revolved(profile, np.asarray(hole.centre), np.asarray(hole.axis))
    filled = fill_holes(part.shape, [hole], part.tolerance)
    result = filled.cut(tool)
    assert shape_volume_mm3(filled.intersect(tool)) == pytest.approx(closed_form, rel=1e-6)
    assert shape_volume_mm3(filled) - shape_volume_mm3(result) == pytest.approx(closed_form, rel=1e-2)
    removed_by_difference = shape_volume_mm3(filled.cut(result))
    assert removed_by_difference > 100 * closed_form  # the failure: should be closed_form


def test_defeaturing_a_counterbore_across_two_levels_silently_changes_nothing():
    """``BRepAlgoAPI_Defeaturing`` asked to remove the faces of a counterbore whose rim straddles a rail top and
    a ledge 2 mm lower (PS2-Portable, SolidWorks) reports success and returns the part unchanged. So cadfeat
    fills holes with the solid of revolution of their own profile and refuses such a hole with the reason
    (tests/cad/test_real_step_parts.py ``REFUSED``) rather than trusting defeaturing."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Defeaturing

    from cadfeat.cad.export import shape_volume_mm3
    from cadfeat.cad.features.extraction import _Extractor
    from cadfeat.cad.step_parts import load_step

    part = load_step(FOLDER / "ps2_lower_display_mount.step")
    hole = part.select((-36.0, 4.9, 15.0), tol_mm=1e-3)  # entrance on the ledge (truth: either level)
    ex = _Extractor(part.shape, None, part.tolerance)
    group = next(g for g in ex.groups() if (h := ex.hole(g)) and np.allclose(h[0].centre, hole.centre))
    tool = BRepAlgoAPI_Defeaturing()
    tool.SetShape(part.shape.wrapped)
    for f in group:
        tool.AddFaceToRemove(ex.topo.faces[f])
    tool.Build()
    assert tool.IsDone()
    import cadquery as cq

    after = cq.Shape.cast(tool.Shape())
    # the counterbore (Ø3.5 x 1.6 below the ledge) and bore alone are > 10 mm³; nothing was filled
    assert abs(shape_volume_mm3(after) - shape_volume_mm3(part.shape)) < 1e-6


def test_brepmesh_leaves_chamfer_cones_untriangulated_at_a_small_angular_tolerance():
    """The 0.5 × 45° rim chamfers (cones) of a Fusion 360 part get no triangles from BRepMesh at 0.05 mm /
    0.1 rad (a study's occlusion mesh then failed with "a face could not be triangulated" during the run).
    Workaround (``export._triangulate``): mesh again with a larger angular tolerance, then with relaxed face
    interiors, the chord tolerance kept on the edges. Reference: trimesh's closed-mesh volume against OCCT's."""
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools

    from cadfeat.cad.export import _untriangulated_faces, mesh_from_shape, shape_volume_mm3
    from cadfeat.cad.step_parts import load_step

    part = load_step(FOLDER / "poseidon_pump_carriage.step")
    occ = part.shape.wrapped
    BRepTools.Clean_s(occ)
    BRepMesh_IncrementalMesh(occ, 0.05, False, 0.1, False)
    assert _untriangulated_faces(occ) == 2  # the failure
    mesh = mesh_from_shape(part.shape, tolerance=0.05)
    assert mesh.is_watertight
    assert abs(mesh.volume) == pytest.approx(shape_volume_mm3(part.shape), rel=1e-3)
