"""Drill points cut into blind holes' floors (``cad.hole_ends``) against exact geometry.

Reference: the volume of a cone, π r² h / 3 with h = r / tan 59°, and its apex at depth + h on the axis (the
solid's lowest point inside the bore), by OCCT's mass properties and bounding boxes of the result.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

cq = pytest.importorskip("cadquery")

from cadfeat.cad.features import extract_holes  # noqa: E402
from cadfeat.cad.hole_ends import drill_points, with_hole_ends  # noqa: E402
from cadfeat.errors import CadfeatError  # noqa: E402


def _plate() -> object:
    """Two blind Ø5 holes 4 mm deep (top face) and one Ø3 through hole, on a 40 × 30 × 10 plate."""
    wp = cq.Workplane("XY").box(40, 30, 10)
    wp = wp.faces(">Z").workplane().pushPoints([(-10, 0), (10, 5)]).hole(5.0, 4.0)
    return wp.faces(">Z").workplane().pushPoints([(0, -8)]).hole(3.0)


def test_drill_points_remove_exactly_the_cones():
    plate = _plate()
    holes = extract_holes(plate)
    blind = [h for h in holes if not h.through]
    assert len(blind) == 2 and len(holes) == 3
    before = plate.val().Volume()
    after = drill_points(plate, holes)
    h = 2.5 / math.tan(math.radians(59.0))
    assert before - after.Volume() == pytest.approx(2 * math.pi * 2.5 ** 2 * h / 3, rel=1e-6)
    assert after.isValid()
    # each apex: the lowest material-free point of its bore is depth + h below the rim, on the axis
    for hole in blind:
        apex = hole.centre - hole.axis * (hole.depth_mm + h)
        probe = cq.Solid.makeSphere(0.05, cq.Vector(*(apex + hole.axis * 0.2)))
        assert probe.intersect(after).Volume() == pytest.approx(0.0, abs=1e-9)   # free just above the apex
        below = cq.Solid.makeSphere(0.05, cq.Vector(*(apex - hole.axis * 0.2)))
        assert below.intersect(after).Volume() == pytest.approx(below.Volume(), rel=1e-6)  # material below it


def test_through_holes_and_milled_ends_are_left_alone():
    plate = _plate()
    holes = extract_holes(plate)
    v = plate.val().Volume()
    assert with_hole_ends(plate, holes, "milled") is plate
    through_only = [h for h in holes if h.through]
    assert drill_points(plate, through_only).Volume() == pytest.approx(v, rel=1e-12)
    with pytest.raises(CadfeatError, match="hole_ends"):
        with_hole_ends(plate, holes, "reamed")


def test_drilled_hole_is_still_found_with_its_rim():
    plate = _plate()
    holes = extract_holes(plate)
    again = extract_holes(drill_points(plate, holes))
    rims = sorted(tuple(np.round(h.centre, 6)) for h in again)
    assert rims == sorted(tuple(np.round(h.centre, 6)) for h in holes)
