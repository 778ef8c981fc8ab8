"""Hole and point extraction on a hand-built solid.

Reference: the construction values of the solid below (exact CAD geometry): a 100 × 60 × 20 mm block
(top face z = 0) with a plain through hole, a flat blind hole, a blind hole with a 118° drill point, a
counterbored and a countersunk through hole, a boss (convex cylinder) carrying a blind hole on its top,
a pocket with filleted corners (concave partial cylinders), filleted vertical block edges, a face tilted
by 30° carrying two blind holes, and a blind hole in a side face. Tolerance 1e-9 mm.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cadfeat.cad.features import extract_holes, extract_points, holes_to_arrays, match_holes

TILT = math.radians(30.0)
N_TILT = np.array([math.sin(TILT), 0.0, math.cos(TILT)])  # outward normal of the tilted face
U_TILT = np.array([math.cos(TILT), 0.0, -math.sin(TILT)])  # down-slope direction in that face
P0_TILT = np.array([40.0, 0.0, 0.0])  # the tilted face passes through this point
POINT_DEPTH = 2.0 / math.tan(math.radians(59.0))  # drill-point cone height for r = 2, 118°
UP, SIDE = (0.0, 0.0, 1.0), (0.0, -1.0, 0.0)
tilt_a, tilt_b = P0_TILT + 6.0 * U_TILT, P0_TILT + 6.0 * U_TILT + np.array([0.0, 12.0, 0.0])

# name: centre, axis, entrance radius, bore radius, depth, through, kind
EXPECTED = {
    "through": ((-35.0, -15.0, 0.0), UP, 3.0, 3.0, 20.0, True, "plain"),
    "blind": ((-35.0, 15.0, 0.0), UP, 2.5, 2.5, 8.0, False, "plain"),
    "drilled": ((-35.0, 0.0, 0.0), UP, 2.0, 2.0, 6.0 + POINT_DEPTH, False, "plain"),
    "cbore": ((-15.0, -15.0, 0.0), UP, 5.5, 3.3, 20.0, True, "counterbore"),
    "csink": ((-15.0, 15.0, 0.0), UP, 5.2, 2.75, 20.0, True, "countersink"),
    "boss": ((25.0, 15.0, 5.0), UP, 2.0, 2.0, 4.0, False, "plain"),
    "tilt_a": (tuple(tilt_a), tuple(N_TILT), 1.5, 1.5, 5.0, False, "plain"),
    "tilt_b": (tuple(tilt_b), tuple(N_TILT), 1.5, 1.5, 5.0, False, "plain"),
    "side": ((20.0, -30.0, -10.0), SIDE, 2.0, 2.0, 6.0, False, "plain"),
}


def make_solid(reverse: bool = False):
    """The test solid; ``reverse`` cuts the holes in the opposite order (same geometry)."""
    import cadquery as cq

    V = cq.Vector
    block = cq.Workplane("XY").box(100, 60, 20, centered=(True, True, False)).translate((0, 0, -20))
    block = block.edges("|Z").fillet(5.0).val()
    boss = cq.Solid.makeCylinder(5.0, 5.0, V(25, 15, 0))
    body = block.fuse(boss).clean()
    wedge = cq.Workplane(cq.Plane(origin=tuple(P0_TILT), xDir=tuple(U_TILT), normal=tuple(N_TILT)))
    body = body.cut(wedge.rect(300, 300).extrude(100).val())
    pocket = cq.Workplane("XY").box(20, 15, 3, centered=False).translate((0, -25, -3)).edges("|Z").fillet(3).val()
    cuts = [
        pocket,
        cq.Solid.makeCylinder(3.0, 22, V(-35, -15, -21)),
        cq.Solid.makeCylinder(2.5, 9, V(-35, 15, -8)),
        cq.Solid.makeCylinder(2.0, 7, V(-35, 0, -6)),
        cq.Solid.makeCone(2.0, 0.0, POINT_DEPTH, V(-35, 0, -6), V(0, 0, -1)),
        cq.Solid.makeCylinder(3.3, 22, V(-15, -15, -21)),
        cq.Solid.makeCylinder(5.5, 5, V(-15, -15, -4)),
        cq.Solid.makeCylinder(2.75, 22, V(-15, 15, -21)),
        cq.Solid.makeCone(5.2, 2.75, 5.2 - 2.75, V(-15, 15, 0), V(0, 0, -1)),
        cq.Solid.makeCylinder(5.2, 1, V(-15, 15, 0)),
        cq.Solid.makeCylinder(2.0, 5, V(25, 15, 1)),
        cq.Solid.makeCylinder(2.0, 7, V(20, -31, -10), V(0, 1, 0)),
    ]
    cuts += [cq.Solid.makeCylinder(1.5, 6, V(*(p + N_TILT)), V(*(-N_TILT))) for p in (tilt_a, tilt_b)]
    if reverse:
        cuts = cuts[::-1]
    out = body
    for c in cuts:
        out = out.cut(c)
    return out.clean()


@pytest.fixture(scope="module")
def solid():
    return make_solid()


@pytest.fixture(scope="module")
def holes(solid):
    return extract_holes(solid, prefer_direction=(0.0, 0.0, 1.0))


def _by_name(holes):
    """Expected name -> extracted hole (pairing by centre within 1e-9 mm)."""
    centres, _, _ = holes_to_arrays(holes)
    out = {}
    for name, (c, *_rest) in EXPECTED.items():
        d = np.linalg.norm(centres - np.array(c), axis=1)
        i = int(np.argmin(d))
        assert d[i] <= 1e-9, f"{name}: nearest extracted centre is {d[i]:.3g} mm away"
        out[name] = holes[i]
    return out


def test_every_hole_exact(solid, holes):
    assert solid.isValid()
    assert len(holes) == len(EXPECTED), [h.centre for h in holes]
    found = _by_name(holes)
    for name, (_c, axis, radius, bore, depth, through, kind) in EXPECTED.items():
        h = found[name]
        np.testing.assert_allclose(h.axis, axis, atol=1e-12, err_msg=name)
        assert abs(h.radius_mm - radius) <= 1e-9, name
        assert abs(h.bore_radius_mm - bore) <= 1e-9, name
        assert abs(h.depth_mm - depth) <= 1e-9, (name, h.depth_mm, depth)
        assert (h.through, h.kind) == (through, kind), name


def test_bosses_fillets_pockets_are_not_holes(solid, holes):
    """Concave/convex partial cylinders (fillets, pocket corners) and the boss give no hole; the pocket and
    the boss footprint are keep-outs of the top face outline."""
    cylinders = [f for f in solid.Faces() if f.geomType() == "CYLINDER"]
    assert len(cylinders) > 9 + 4 + 4  # the hole walls plus 4 block fillets, 4 pocket corners, the boss
    top = _by_name(holes)["through"].outline
    assert top is not None and len(top.keepouts) == 2
    np.testing.assert_allclose(top.normal, [0, 0, 1], atol=1e-12)
    centroids = [k.mean(axis=0) for k in top.keepouts]  # ~uniformly sampled outlines: mean ≈ centroid
    for centre in ((25.0, 15.0, 0.0), (10.0, -17.5, 0.0)):  # boss footprint, pocket
        assert min(np.linalg.norm(c - top.to_face(np.array(centre))) for c in centroids) < 0.5
    found = _by_name(holes)
    for name, normal in (("tilt_a", N_TILT), ("side", SIDE), ("boss", UP)):
        assert found[name].outline is not None
        np.testing.assert_allclose(found[name].outline.normal, normal, atol=1e-12)
        assert abs((found[name].centre - found[name].outline.origin) @ found[name].outline.normal) < 1e-9


def test_through_entrance_rules(solid):
    """Without prefer_direction a plain through hole enters from the host face of larger outer area: the
    bottom face here (the top lost the tilted wedge); the counterbore/countersink side always wins."""
    plain = {tuple(np.round(h.centre, 6)): h for h in extract_holes(solid)}
    assert (-35.0, -15.0, -20.0) in plain
    np.testing.assert_allclose(plain[(-35.0, -15.0, -20.0)].axis, [0, 0, -1], atol=1e-12)
    assert (-15.0, -15.0, 0.0) in plain and (-15.0, 15.0, 0.0) in plain


@pytest.mark.parametrize(("bore_d", "rim_d", "angle", "kind"), [
    (0.125, 0.25, 82.0, "countersink"),          # cadquery's examples/Ex019 (a 4 x 2 x 0.5 plate)
    (1.8, 3.8, 90.0, "countersink"),             # lcr_gripper_moving_part.step's holes (truth: either)
    (3.4, 6.6, 90.0, "countersink"),             # M3
    (2.4, 4.4, 90.0, "plain, chamfered rim"),    # 1 x 45° on Ø2.4 (lcr_shoulder_to_elbow.step's truth)
    (4.0, 6.0, 90.0, "plain, chamfered rim"),    # 1 x 45° chamfer on Ø4
    (2.0, 3.6, 90.0, "plain, chamfered rim"),    # 0.8 x 45° on Ø2: the flagship's widest rim chamfer
    (8.0, 9.0, 90.0, "plain, chamfered rim"),    # 0.5 x 45° on Ø8
])
def test_a_countersink_that_doubles_a_small_bore_is_no_chamfer(bore_d, rim_d, angle, kind):
    """A cone is a chamfered rim when it widens the bore by at most max(1 mm, 0.35 × its radius), the 1 mm never
    more than 0.9 × the radius (a cone that about doubles a bore's diameter is a countersink's seat). Before: any
    cone widening a bore by up to 1 mm was a chamfer, so the countersinks of a small part (cadquery's Ex019: Ø0.25
    over Ø0.125) were "plain, chamfered rim"."""
    import cadquery as cq

    plate = cq.Workplane("XY").box(8 * rim_d, 8 * rim_d, 2 * rim_d).faces(">Z").workplane()
    (hole,) = extract_holes(plate.cskHole(bore_d, rim_d, angle).val(), prefer_direction=(0.0, 0.0, 1.0))
    assert hole.kind == kind
    assert (hole.radius_mm, hole.bore_radius_mm) == pytest.approx((rim_d / 2, bore_d / 2), abs=1e-9)


def test_deterministic_order(holes):
    again = extract_holes(make_solid(reverse=True), prefer_direction=(0.0, 0.0, 1.0))
    c1, a1, r1 = holes_to_arrays(holes)
    c2, a2, r2 = holes_to_arrays(again)
    np.testing.assert_allclose(c1, c2, atol=1e-9)
    np.testing.assert_allclose(a1, a2, atol=1e-12)
    np.testing.assert_allclose(r1, r2, atol=1e-9)
    np.testing.assert_array_equal(match_holes(holes, again, tol_mm=1e-6), np.arange(len(holes)))


def test_points_of_a_box_are_its_corners():
    import cadquery as cq

    box = cq.Solid.makeBox(3.0, 4.0, 5.0, cq.Vector(1.0, -2.0, 0.5))
    corners = np.array([(x, y, z) for x in (1.0, 4.0) for y in (-2.0, 2.0) for z in (0.5, 5.5)])
    np.testing.assert_allclose(extract_points(box), corners, atol=1e-12)  # lexicographic x, y, z


# ------------------------------------------------------------------------------ random plates (property)
_hole = st.tuples(st.floats(-40, 40), st.floats(-20, 20), st.floats(0.5, 3.0),
                  st.sampled_from(["through", "top", "bottom"]), st.floats(1.0, 6.0))


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(_hole, min_size=1, max_size=5))
def test_random_plate_holes_exact(spec):
    """Random holes (through, blind from the top, blind from the bottom) in a 100 × 60 × 8 plate: every
    extracted centre / axis / radius / depth equals the construction values (1e-9 mm)."""
    import cadquery as cq

    kept = []
    for x, y, r, kind, depth in spec:  # keep holes 1 mm apart
        if all(math.hypot(x - k[0], y - k[1]) > r + k[2] + 1.0 for k in kept):
            kept.append((x, y, r, kind, depth))
    plate = cq.Solid.makeBox(100, 60, 8, cq.Vector(-50, -30, -8))
    cuts, expected = [], []
    for x, y, r, kind, depth in kept:
        if kind == "through":
            cuts.append(cq.Solid.makeCylinder(r, 10, cq.Vector(x, y, -9)))
            expected.append(((x, y, 0.0), (0, 0, 1), r, 8.0, True))
        elif kind == "top":
            cuts.append(cq.Solid.makeCylinder(r, depth + 1, cq.Vector(x, y, -depth)))
            expected.append(((x, y, 0.0), (0, 0, 1), r, depth, False))
        else:
            cuts.append(cq.Solid.makeCylinder(r, depth + 1, cq.Vector(x, y, -8 - 1)))
            expected.append(((x, y, -8.0), (0, 0, -1), r, depth, False))
    holes = extract_holes(plate.cut(*cuts), prefer_direction=(0, 0, 1))
    assert len(holes) == len(expected)
    centres, axes, radii = holes_to_arrays(holes)
    for c, a, r, depth, through in expected:
        i = int(np.argmin(np.linalg.norm(centres - np.array(c), axis=1)))
        assert np.linalg.norm(centres[i] - np.array(c)) <= 1e-9
        np.testing.assert_allclose(axes[i], a, atol=1e-12)
        assert abs(radii[i] - r) <= 1e-9 and abs(holes[i].depth_mm - depth) <= 1e-9
        assert holes[i].through == through and holes[i].kind == "plain"
