"""The traits of the real STEP exports added on 2026-11-28 (``../shared/real_step/SOURCES.md``), each rebuilt as a
small CadQuery part written to STEP and read back (issue 32 item 9); the real parts themselves are checked against
their truth in tests/cad/test_real_step_parts.py, the kernel's share in tests/cad/test_occt_bugs.py.

- an open seat: a Ø3.4 through hole whose far end opens into a Ø5.9 seat that breaks out of the side (the Thor motor
  holder B): through, as deep as its own bore, and re-drilled after a 0.5 mm move;
- a bore whose cylinder runs on above the plate as a sliver where a wall cuts into it (the Thor motor holder A's
  Ø26): the hole is as deep as the plate and re-drills;
- a radial set-screw path split by a captive-nut slot (the Thor gear): the inner hole enters from the slot, not from
  inside the shaft bore;
- coaxial holes in the two plates of a clevis (the low-cost-robot link): the B-rep ligament check does not take the
  other plate's rim for a neighbour at 0 mm;
- host faces of different outline sizes (the pan mount's 6-point tongue and 316-point plate): the constraints'
  same-face test compares them without a numpy broadcast error.

References: the construction values below (closed-form depths and positions), the holes re-extracted after a
re-drill (``real_step_truth.redrill_errors``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import real_step_truth as rs

from cadfeat.cad.export import export_step
from cadfeat.cad.step_parts import load_step

PLATE_T = 3.6  # mm, the Thor holders' base plate


def _step(shape, tmp_path, name: str):
    path = tmp_path / f"{name}.step"
    export_step(shape, path)
    return load_step(path)


def _on_line(part, xy, axis_index: int = 2):
    """The holes whose axis is along ``axis_index`` and whose line passes through ``xy`` (the other two coords)."""
    keep = [k for k in range(3) if k != axis_index]
    return [h for h in part.holes if abs(abs(h.axis[axis_index]) - 1) < 1e-9
            and np.allclose(np.asarray(h.centre)[keep], xy, atol=1e-6)]


# ------------------------------------------------------------------------------------------------ open seat
SEAT = (-6.0, 0.0, 3.4, 5.9, 2.0, 8.0)  # hole (x, y), bore Ø, seat Ø, seat floor z, plate half-width (mm)


def open_seat():
    import cadquery as cq

    x, y, bore, seat, floor, half = SEAT
    plate = cq.Workplane("XY").box(2 * half, 2 * half, PLATE_T, centered=(True, True, False))
    hole = cq.Workplane("XY").center(x, y).circle(bore / 2).extrude(PLATE_T + 2).translate((0, 0, -1))
    cup = cq.Workplane("XY").center(x, y).circle(seat / 2).extrude(PLATE_T).translate((0, 0, floor))
    return plate.cut(hole).cut(cup).val()


def test_a_hole_opening_into_a_seat_that_breaks_out_of_the_side_is_through_at_its_own_depth(tmp_path):
    x, y, bore, seat, floor, half = SEAT
    assert x - seat / 2 < -half  # the seat breaks out of the side face x = -half
    part = _step(open_seat(), tmp_path, "open_seat")
    (h,) = _on_line(part, (x, y))
    assert (h.kind, h.through) == ("plain", True)
    assert h.depth_mm == pytest.approx(floor, abs=1e-6)
    assert 2 * h.bore_radius_mm == pytest.approx(bore, abs=1e-6)
    assert any(abs(2 * s.radius_mm - seat) < 1e-6 and "near-round" in s.reason for s in part.skipped)
    assert rs.redrill_errors(part, h, np.zeros(3)) == []
    step = 0.5 * rs.move_direction(part, h)
    assert rs.redrill_errors(part, h, step) == []


# --------------------------------------------------------------------------------------------------- sliver
SLIVER = (13.0, 10.0, 4.0, 11.6, 21.5)  # bore radius, wall from x, wall thickness, wall top z, plate half-width


def bore_with_sliver():
    import cadquery as cq

    r, wall_x, wall_t, top, half = SLIVER
    plate = cq.Workplane("XY").box(2 * half, 2 * half, PLATE_T, centered=(True, True, False))
    wall = cq.Workplane("XY").box(wall_t, 2 * half, top - PLATE_T, centered=False).translate(
        (wall_x, -half, PLATE_T))
    bore = cq.Workplane("XY").circle(r).extrude(top + 2).translate((0, 0, -1))
    return plate.union(wall).cut(bore).val()


def test_a_bore_whose_cylinder_runs_on_above_the_plate_is_as_deep_as_the_plate(tmp_path):
    r, wall_x, *_ = SLIVER
    assert wall_x < r  # the wall is cut by the bore's cylinder: a sliver of it above the plate
    part = _step(bore_with_sliver(), tmp_path, "sliver")
    (h,) = _on_line(part, (0.0, 0.0))
    assert (h.kind, h.through) == ("plain", True)
    assert h.radius_mm == pytest.approx(r, abs=1e-6)
    assert h.depth_mm == pytest.approx(PLATE_T, abs=1e-6)
    assert rs.redrill_errors(part, h, np.zeros(3)) == []
    assert rs.redrill_errors(part, h, np.array([-0.5, 0.0, 0.0])) == []  # away from the wall


# ------------------------------------------------------------------------------------------ set-screw path
HUB = (12.0, 10.0, 2.5, 3.4, 5.0, 8.0, 5.9, -5.0)  # hub r, hub height, bore r, screw Ø, slot x0, x1, width, z


def set_screw_hub():
    import cadquery as cq

    R, height, r_bore, screw, x0, x1, width, z = HUB
    hub = cq.Workplane("XY").circle(R).extrude(height).translate((0, 0, -height))
    bore = cq.Workplane("XY").circle(r_bore).extrude(height + 2).translate((0, 0, -height - 1))
    slot = cq.Workplane("XY").box(x1 - x0, width, z + height + width / 2, centered=False).translate(
        (x0, -width / 2, -height - 1))
    radial = cq.Workplane("YZ").center(0, z).circle(screw / 2).extrude(R + 2)
    return hub.cut(bore).cut(slot).cut(radial).val()


def test_the_inner_hole_of_a_set_screw_path_enters_from_the_nut_slot_not_from_the_bore(tmp_path):
    R, _, r_bore, screw, x0, x1, _, z = HUB
    part = _step(set_screw_hub(), tmp_path, "set_screw_hub")
    radial = sorted(_on_line(part, (0.0, z), axis_index=0), key=lambda h: h.centre[0])
    assert len(radial) == 2
    inner, outer = radial
    np.testing.assert_allclose(inner.centre, [x0, 0.0, z], atol=1e-6)  # the slot face, not the bore
    np.testing.assert_allclose(inner.axis, [1.0, 0.0, 0.0], atol=1e-9)
    wall_end = math.sqrt(r_bore ** 2 - (screw / 2) ** 2)  # the saddle on the bore reaches deepest here
    assert inner.depth_mm == pytest.approx(x0 - wall_end, abs=1e-6) and inner.through
    np.testing.assert_allclose(outer.axis, [1.0, 0.0, 0.0], atol=1e-9)  # from the hub's outside
    assert outer.centre[0] == pytest.approx(R, abs=0.2)


# ----------------------------------------------------------------------------------------------- clevis
CLEVIS = (22.0, 3.0, 2.4, 8.0)  # plates' outer x, thickness, hole Ø, hole y


def clevis():
    import cadquery as cq

    x, t, d, y = CLEVIS
    base = cq.Workplane("XY").box(2 * x, 30, 4, centered=(True, True, False)).translate((0, 0, -14))
    plates = [cq.Workplane("XY").box(t, 30, 24, centered=False).translate((s, -15, -12))
              for s in (-x, x - t)]
    body = base.union(plates[0]).union(plates[1])
    pin = cq.Workplane("YZ").center(y, 0).circle(d / 2).extrude(2 * x + 2).translate((-x - 1, 0, 0))
    return body.cut(pin).val()


def test_coaxial_holes_in_two_plates_have_no_ligament_between_them():
    from cadfeat.cad.features import extract_holes
    from cadfeat.design.constraints import ConstraintConfig, verify_on_brep

    shape = clevis()
    holes = extract_holes(shape)
    assert len(holes) == 2 and np.linalg.norm(np.cross(holes[0].axis, holes[1].axis)) < 1e-9
    checks = verify_on_brep(shape, holes, ConstraintConfig(edge_distance_mm=0.5, ligament_mm=0.5), [False, False])
    assert not [c for c in checks if c.name == "ligament"]  # they share no face
    assert all(c.ok for c in checks), [c for c in checks if not c.ok]


# ------------------------------------------------------------------------------------------- same face
def test_holes_on_faces_with_outlines_of_different_sizes_are_compared_without_error():
    """The pan mount seen from above (the study's camera side): coplanar host faces of 6 and 316 outline points."""
    import itertools

    from cadfeat.design.constraints import ConstraintConfig, ConstraintSet, _same_face

    if rs.real_step_dir() is None:
        pytest.skip("no shared/real_step beside the repository")
    part = load_step(rs.real_step_dir() / "ptm_pan_mount.step", prefer_direction=(0.0, 0.0, 1.0))
    pairs = [(a, b) for a, b in itertools.combinations(part.holes, 2)
             if a.outline is not None and b.outline is not None and a.host_face != b.host_face
             and len(a.outline.outer) != len(b.outline.outer)
             and np.dot(a.outline.normal, b.outline.normal) > 1 - 1e-9
             and abs(np.dot(b.outline.origin - a.outline.origin, a.outline.normal)) < 1e-6]
    assert pairs  # coplanar host faces of different outlines (the crash of issue 32 item 9)
    assert not any(_same_face(a, b) for a, b in pairs)
    cset = ConstraintSet(part.holes, ConstraintConfig(edge_distance_mm=2.0, ligament_mm=2.0),
                         [False] * len(part.holes))
    assert len(cset.pairs) > 0
