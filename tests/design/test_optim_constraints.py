"""Kept requirements: the 2-D fast form against brute-force geometry and against OCCT distances on real
CadQuery solids; ``verify_on_brep`` finds violations; design space and feature models."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.path import Path as MplPath
from optim_helpers import plate_with_holes

from cadfeat.cad.features import extract_holes, holes_to_arrays
from cadfeat.design.constraints import (
    ConstraintConfig,
    ConstraintSet,
    SymmetryPair,
    _pad_polygons,
    constraint_margins,
    point_polygon_distance,
    verify_on_brep,
)
from cadfeat.design.design_space import DesignSpace, HoleMoveModel, Variable
from cadfeat.errors import CadfeatError


def _brute_distance(point, polygon, samples=4000):
    """Distance from a point to a closed polygon by dense sampling of its edges."""
    a = polygon
    b = np.roll(polygon, -1, axis=0)
    t = np.linspace(0, 1, samples)[:, None, None]
    pts = a[None] + t * (b - a)[None]
    return np.min(np.linalg.norm(pts - point, axis=-1))


def test_point_polygon_distance_matches_sampling_and_matplotlib():
    rng = np.random.default_rng(3)
    # an L-shaped (non-convex) polygon and a triangle, counter-clockwise
    polys = [np.array([[0, 0], [10, 0], [10, 4], [4, 4], [4, 10], [0, 10]], float),
             np.array([[0, 0], [5, 1], [2, 6]], float)]
    a, b, valid = _pad_polygons(polys)
    pts = rng.uniform(-2, 12, size=(200, 2, 2))
    d, inside = point_polygon_distance(pts, a, b, valid)
    for k, poly in enumerate(polys):
        path = MplPath(poly)
        for i in range(0, 200, 7):
            assert d[i, k] == pytest.approx(_brute_distance(pts[i, k], poly), abs=2e-3)
            assert inside[i, k] == path.contains_point(pts[i, k])


@pytest.fixture(scope="module")
def plate_case():
    """Plate 80 × 60 with three holes (one 1.5 mm from the +x edge) and a rectangular pocket (keep-out)."""
    import cadquery as cq

    solid = plate_with_holes([(-20, 5), (10, -8), (34.5, 12)], [3.0, 2.5, 4.0])
    pocket = cq.Solid.makeBox(8, 5, 2, cq.Vector(-4, 14, -2))
    solid = solid.cut(pocket)
    holes = extract_holes(solid, prefer_direction=(0, 0, 1))
    return solid, holes


def test_2d_margins_equal_occt_distances_on_the_brep(plate_case):
    solid, holes = plate_case
    cfg = ConstraintConfig(edge_distance_mm=2.0, ligament_mm=1.5)
    fixed = [False] * len(holes)
    c, _, r = holes_to_arrays(holes)
    fast = constraint_margins(c, r, holes, cfg, fixed)
    checks = verify_on_brep(solid, holes, cfg, fixed)
    names = [h.name or f"H{i + 1}" for i, h in enumerate(holes)]
    by_kind = {}
    for ch in checks:
        by_kind.setdefault(ch.name, {})[tuple(ch.holes)] = ch.margin
    cset = ConstraintSet(holes, cfg, fixed)
    for kind, labels in cset.labels().items():
        for value, lab in zip(fast[kind], labels, strict=True):
            assert by_kind[kind][tuple(lab)] == pytest.approx(value, abs=1e-6), (kind, lab)
    assert len(fast["edge"]) == 3 and len(fast["ligament"]) == 3 and len(fast["keepout"]) == 3
    # the hole 1.5 mm from the edge violates edge distance 2 mm by 2.5 mm (radius 4 → rim 1.5 mm - 2 = -0.5)
    i = next(k for k, h in enumerate(holes) if abs(h.centre[0] - 34.5) < 1e-9)
    edge = {tuple(ch.holes): ch for ch in checks if ch.name == "edge"}[(names[i],)]
    assert not edge.ok and edge.value == pytest.approx(1.5, abs=1e-9) and edge.margin == pytest.approx(-0.5, abs=1e-9)
    assert all(ch.ok for ch in checks if ch.name != "edge" or ch.holes != [names[i]])


def test_verify_on_brep_reports_a_hole_breaking_out_and_fixed_moves():
    ref_solid = plate_with_holes([(-20, 0), (20, 0)], [3.0, 3.0])
    reference = extract_holes(ref_solid, prefer_direction=(0, 0, 1))
    moved = plate_with_holes([(-20, 0.5), (37.5, 0)], [3.0, 2.0])  # second rim 0.5 mm from the +x edge
    design = extract_holes(moved, prefer_direction=(0, 0, 1))
    xs = [h.centre[0] for h in design]
    cfg = ConstraintConfig(edge_distance_mm=1.0, ligament_mm=1.0, volume_change_max_frac=0.5)
    order = np.argsort([h.centre[0] for h in reference])
    ref_sorted = [reference[k] for k in order]
    des_sorted = [design[k] for k in np.argsort(xs)]
    # the -x hole is declared fixed but moved by 0.5 mm
    checks = verify_on_brep(moved, des_sorted, cfg, [True, False], reference=ref_sorted, reference_shape=ref_solid)
    bad = {ch.name for ch in checks if not ch.ok}
    assert "fixed" in bad
    edge = [ch for ch in checks if ch.name == "edge"]
    assert len(edge) == 1 and not edge[0].ok and edge[0].value == pytest.approx(0.5, abs=1e-9)
    assert edge[0].margin == pytest.approx(-0.5, abs=1e-9)
    assert [ch.ok for ch in checks if ch.name == "holes_match"] == [True]
    vol = [ch for ch in checks if ch.name == "volume"]
    assert len(vol) == 1 and vol[0].ok
    # a hole cutting through the edge is no longer a hole: the design does not match the solid
    broken = plate_with_holes([(-20, 0.5), (38.5, 0)], [3.0, 3.0])
    checks = verify_on_brep(broken, des_sorted, cfg, [True, False])
    assert not checks[0].ok and checks[0].name == "holes_match"


def test_symmetry_and_volume_margins():
    holes = extract_holes(plate_with_holes([(-20, 4), (20, 4)], [3.0, 3.0]), prefer_direction=(0, 0, 1))
    holes = sorted(holes, key=lambda h: h.centre[0])
    c, _, r = holes_to_arrays(holes)
    pair = SymmetryPair(0, 1, (0, 0, 0), (1, 0, 0))
    cfg = ConstraintConfig(symmetry=(pair,), volume_change_max_frac=0.01, part_volume_mm3=80 * 60 * 5.0)
    m = constraint_margins(c, r, holes, cfg, [False, False])
    assert m["symmetry"][0] == pytest.approx(1e-3)
    c2 = c.copy()
    c2[1, 1] += 0.5
    r2 = r * np.array([1.0, 1.2])
    m2 = constraint_margins(np.stack([c, c2]), np.stack([r, r2]), holes, cfg, [False, False])
    assert m2["symmetry"][1, 0] == pytest.approx(1e-3 - 0.5 - 0.6)
    dv = np.pi * ((3.6 ** 2) - 9.0) * 5.0
    assert m2["volume"][1, 0] == pytest.approx(0.01 * 24000 - dv)
    with pytest.raises(CadfeatError, match="part_volume_mm3"):
        ConstraintSet(holes, ConstraintConfig(volume_change_max_frac=0.1), [False, False])


def test_design_space_validation_and_snap():
    v = Variable("d", 2.0, 8.0, "mm", "diameter", (1.0, 3.0, 4.5, 6.0, 10.0))
    assert v.standard_sizes == (3.0, 4.5, 6.0)
    space = DesignSpace([Variable("x", -1, 1), v], [0.0, 5.0])
    assert space.snap([0.3, 5.1]).tolist() == [0.3, 4.5]
    assert space.groups() == {"position": [0], "diameter": [1]}
    np.testing.assert_allclose(space.from_unit(space.to_unit([0.5, 7.0])), [0.5, 7.0])
    with pytest.raises(CadfeatError, match="outside its bounds"):
        DesignSpace([Variable("x", -1, 1)], [2.0])
    with pytest.raises(CadfeatError, match="lower < upper"):
        Variable("x", 1, 1)
    with pytest.raises(CadfeatError, match="no standard size"):
        Variable("d", 2, 3, standard_sizes=(5.0,))


def test_hole_move_model_moves_in_the_host_plane_with_patterns_and_mirrors():
    solid = plate_with_holes([(-20, 5), (20, 5), (0, -15)], [3.0, 3.0, 2.0])
    holes = sorted(extract_holes(solid, prefer_direction=(0, 0, 1)), key=lambda h: h.centre[0])
    # holes sorted by x: (-20,5), (0,-15), (20,5); 0 and 2 a mirror pair in x = 0, 1 free with a diameter
    model = HoleMoveModel(holes, movable=[0, 1, 2], diameter=True, mirrors=[(0, 2, (1, 0, 0))])
    assert len(model.names) == 6
    space = model.design_space()
    x = space.x0.copy()
    x[0], x[1], x[2] = 2.0, -1.0, 5.0  # leader 0 moves by (2, -1) in its face frame, diameter 5
    c, a, r = model.features(x)
    u, v = holes[0].outline.u, holes[0].outline.v
    np.testing.assert_allclose(c[0], holes[0].centre + 2 * u - 1 * v, atol=1e-12)
    mirrored = c[0] * np.array([-1, 1, 1])
    np.testing.assert_allclose(c[2], mirrored, atol=1e-12)
    assert r[0] == r[2] == pytest.approx(2.5)
    np.testing.assert_allclose(a, holes_to_arrays(holes)[1])
    moves = model.hole_moves(x)
    assert len(moves) == 3 and moves[0].radius_mm == pytest.approx(2.5)
    cb, _, rb = model.features_batch(np.stack([x, space.x0]))
    np.testing.assert_allclose(cb[0], c)
    np.testing.assert_allclose(rb[1], holes_to_arrays(holes)[2])


def test_ligament_to_a_through_hole_reported_from_its_other_end():
    """Issue 13: a blind hole on the face where a through hole EXITS had no ligament row on the B-rep (the
    re-extracted through hole's host face was the other end). The rim-to-rim distance is the construction value
    |x_window − x_fiducial| − r_window − r_fiducial."""
    import cadquery as cq

    for z_fiducial, z_face in ((6.0, 8.0), (0.0, 0.0)):  # the fiducial on the top face, then on the bottom face
        plate = cq.Workplane("XY").box(80, 60, 8).translate((0, 0, 4))
        plate = plate.cut(cq.Workplane("XY").circle(8.0).extrude(20).translate((10, 0, -10)))
        plate = plate.cut(cq.Workplane("XY").circle(1.5).extrude(2).translate((-2.4, 0, z_fiducial)))
        solid = plate.val()
        real = extract_holes(solid)
        fixed = [h.radius_mm > 5 for h in real]
        checks = verify_on_brep(solid, real, ConstraintConfig(edge_distance_mm=3.0, ligament_mm=3.0), fixed)
        lig = [c for c in checks if c.name == "ligament"]
        assert len(lig) == 1, (z_face, [c.name for c in checks])
        assert lig[0].value == pytest.approx(12.4 - 8.0 - 1.5, abs=1e-6)
