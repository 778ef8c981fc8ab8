"""The unseen-hole rule of every measure (issue 17; the objectives' rule, ``design.unseen``, since issue 32 item 7),
checked against an independent occlusion: a segment-box slab test on the rim points of a hole behind a wall, not
the implementation's ray casts or depth maps.

Rule: a hole facing the camera scores f + (1 − h)(v − f) in FOV (cone and image), focus and resolution (v its
value as if seen, f the floor, h its rim's hidden fraction); g_DIR weighs each hole's Jacobian rows by 1 − h;
g_POSE gives a hidden rim no information. So a hidden hole gains nothing by shrinking, by moving further into
hiding or by vanishing, and a partly hidden one scores between seen and hidden. ``measures.evaluate`` itself
reports the thesis's margins (and h, ``hidden``, ``folded``); the objectives apply the rule."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from cadfeat import measures
from cadfeat.camera import Camera
from cadfeat.design.objectives import ObjectiveConfig, objective_values
from cadfeat.design.unseen import UNSEEN_KEYS, scored_measures, unseen_floors
from cadfeat.errors import CadfeatError
from cadfeat.measures.depth import DepthMaps
from cadfeat.measures.pose_information import pose_information
from cadfeat.measures.unseen import RIM_SAMPLES
from cadfeat.poses import invert_T, look_at

WALL_LO, WALL_HI = np.array([10.0, -20.0, 5.0]), np.array([16.0, 20.0, 20.0])  # the wall (box), part frame, mm
CAMERA = Camera.preset("basler-aca1300-200um-8mm").replace(focus_distance_mm=200.0)
EYES = np.column_stack([np.full(12, -150.0), np.zeros(12), np.linspace(160.0, 100.0, 12)])
T_CAM_PART = invert_T(look_at(EYES, [22.0, 0.0, 5.0]))
SCREWS = np.tile([0.0, 0.0, 20.0, 0.0, 0.0, 0.0], (12, 1))  # approaching along the optical axis, mm/s
OTHERS = np.array([[-40.0, 12.0, 5.0], [-40.0, -12.0, 5.0], [-20.0, 0.0, 5.0]])  # seen holes (g_DIR's rank)
UP = np.array([0.0, 0.0, 1.0])
MIN_AXIS_PX = 5.0


def _mesh() -> trimesh.Trimesh:
    plate = trimesh.creation.box(bounds=[[-50.0, -20.0, 0.0], [50.0, 20.0, 5.0]])
    return trimesh.util.concatenate([plate, trimesh.creation.box(bounds=[WALL_LO, WALL_HI])])


MESH = _mesh()
MAPS = DepthMaps(MESH, CAMERA, T_CAM_PART)


def _slab_hidden(points: np.ndarray) -> np.ndarray:
    """(L, M) bool: the segment from each point (M, 3) to each camera centre crosses the wall (slab test)."""
    a, d = points[None], EYES[:, None] - points[None]
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (WALL_LO - a) / d, (WALL_HI - a) / d
    inside = (a > WALL_LO) & (a < WALL_HI)
    lo = np.where(d != 0, np.minimum(t1, t2), np.where(inside, -np.inf, np.inf)).max(axis=-1)
    hi = np.where(d != 0, np.maximum(t1, t2), np.where(inside, np.inf, -np.inf)).min(axis=-1)
    return (lo < hi) & (hi > 1e-6) & (lo < 1 - 1e-6)


def _rim(x: float, r: float, k: int = RIM_SAMPLES) -> np.ndarray:
    """k points on the rim of the hole at (x, 0, 5) (axis +z), at the phases (i + ½)/k of a turn."""
    phi = 2 * np.pi * (np.arange(k) + 0.5) / k
    return np.column_stack([x - r * np.sin(phi), r * np.cos(phi), np.full(k, 5.0)])


def _slab_fraction(x: float, r: float, k: int = RIM_SAMPLES) -> np.ndarray:
    return _slab_hidden(_rim(x, r, k)).mean(axis=-1)


def _raw(x: float, r: float, occlusion, with_others: bool = True) -> measures.Measures:
    centres = np.vstack([[[x, 0.0, 5.0]], OTHERS]) if with_others else np.array([[x, 0.0, 5.0]])
    radii = np.r_[r, np.full(len(centres) - 1, 2.0)]
    return measures.evaluate(CAMERA, T_CAM_PART, SCREWS, centres, np.tile(UP, (len(centres), 1)), radii,
                             min_axis_px=MIN_AXIS_PX, occlusion_mesh=occlusion)


def _evaluate(x: float, r: float, occlusion, with_others: bool = True) -> measures.Measures:
    """The measures as the objectives score them (``design.unseen.scored_measures``)."""
    return scored_measures(_raw(x, r, occlusion, with_others), CAMERA, MIN_AXIS_PX)


def test_rim_hidden_fraction_agrees_with_the_slab_test():
    for x in (25.0, 36.0, 40.0, 44.0):
        truth = _slab_fraction(x, 1.5)
        exact = _evaluate(x, 1.5, MESH).rim_hidden[:, 0]
        np.testing.assert_array_equal(exact, truth)  # the same rim points, ray casts vs slab: equal
        # the depth maps err towards hidden near a silhouette (a cell straddling the wall's edge holds the wall's
        # depth), by at most two cells: between the dense rim's fraction here and two cells' footprint on the
        # plate (cell · depth / cos of the view angle) closer to the wall
        fast = _evaluate(x, 1.5, MAPS).rim_hidden[:, 0]
        depth = np.linalg.norm(EYES - [x, 0.0, 5.0], axis=-1)
        cells = 2 * MAPS.cell * depth / _evaluate(x, 1.5, None).facing[:, 0]
        assert np.all(fast >= _slab_fraction(x, 1.5, 256) - 0.02)
        closer = np.array([_slab_fraction(x - c, 1.5, 256)[k] for k, c in enumerate(cells)])
        assert np.all(fast <= closer + 0.02), (x, fast, closer)
    partly = _slab_fraction(40.0, 1.5)
    assert ((partly > 0) & (partly < 1)).sum() >= 2 and (partly == 0).any() and (partly == 1).any()


@pytest.mark.parametrize("occlusion", [MESH, MAPS], ids=["mesh", "depth maps"])
@pytest.mark.parametrize("key", UNSEEN_KEYS)
def test_a_hidden_hole_gains_nothing_per_measure(key, occlusion):
    floor = unseen_floors(CAMERA, MIN_AXIS_PX)[key]

    def value(x: float, r: float) -> np.ndarray:
        return getattr(_evaluate(x, r, occlusion), key)[:, 0]

    # wholly hidden at every pose (slab test): the floor, whatever the size and position
    assert _slab_hidden(_rim(30.0, 1.5, 256)).all()
    base = value(30.0, 1.5)
    np.testing.assert_array_equal(base, floor)
    for x, r in ((30.0, 0.75), (30.0, 0.01), (26.0, 1.5), (22.0, 1.5), (22.0, 0.5)):  # shrink, hide, vanish
        np.testing.assert_array_equal(value(x, r), base)
    # partly hidden: between the floor and the same hole seen (no occlusion), never above it
    free = getattr(_evaluate(40.0, 1.5, None), key)[:, 0]
    v40 = value(40.0, 1.5)
    h = _slab_fraction(40.0, 1.5)
    # f + (1 − h)(v − f): with the mesh h is the slab test's; the depth maps' h (checked against the slab test
    # above) errs towards hidden
    h_used = h if occlusion is MESH else _evaluate(40.0, 1.5, occlusion).rim_hidden[:, 0]
    assert np.all(v40 <= free) and np.all(v40 >= floor)
    np.testing.assert_array_equal(v40[h_used == 0], free[h_used == 0])
    np.testing.assert_array_equal(v40[h_used == 1], floor)
    np.testing.assert_allclose(v40, floor + (1 - h_used) * (free - floor), rtol=1e-12, atol=1e-12 * abs(floor))
    assert np.all(v40[(h_used > 0) & (h_used < 1)] < free[(h_used > 0) & (h_used < 1)])
    # further into hiding (at least one more rim point hidden, slab test): not better
    more = _slab_fraction(38.5, 1.5) >= h + 1 / RIM_SAMPLES
    assert more.sum() >= 3
    assert np.all(value(38.5, 1.5)[more] <= v40[more])
    # shrinking or vanishing where the centre is hidden (slab test): not better
    centre_hidden = _slab_hidden(np.array([[40.0, 0.0, 5.0]]))[:, 0] & (h < 1)
    assert centre_hidden.any()
    for r in (0.75, 0.01):
        assert np.all(value(40.0, r)[centre_hidden] <= v40[centre_hidden])


@pytest.mark.parametrize("measure", ["fov", "fov image", "focus", "resolution"])
def test_no_objective_improves_while_its_hole_is_hidden(measure):
    """The aggregated objectives (sum over the poses, the target hole scored) of a hole hidden at every pose
    are equal whatever its size and position, and below those of the same hole partly seen."""
    key, fov = (measure.split()[0], "image" if "image" in measure else "cone")
    cfg = ObjectiveConfig(measures=(key,), fov_measure=fov)
    mask = np.array([True, False, False, False])

    def g(x: float, r: float) -> float:
        return next(iter(objective_values(_evaluate(x, r, MAPS), cfg, feature_mask=mask).values()))

    hidden = [g(x, r) for x, r in ((30.0, 1.5), (30.0, 0.75), (26.0, 1.5), (22.0, 0.01))]
    assert hidden == [hidden[0]] * 4
    assert g(36.0, 1.5) > hidden[0] and g(40.0, 1.5) > g(36.0, 1.5)  # coming out of hiding pays
    # ``objective_values`` applies the rule itself to ``evaluate``'s measures, given the camera (issue 32 item 7)
    raw = _raw(40.0, 1.5, MAPS)
    assert objective_values(raw, cfg, feature_mask=mask, camera=CAMERA) == \
        objective_values(_evaluate(40.0, 1.5, MAPS), cfg, feature_mask=mask)
    with pytest.raises(CadfeatError, match="camera"):
        objective_values(raw, cfg, feature_mask=mask)


def test_evaluate_reports_the_equations_and_the_flags_the_rule_reads():
    """``evaluate`` leaves the margins of a hidden hole as the equations give them (the same as without the part)
    and reports h, ``hidden`` and ``facing``: the rule is the objectives' (issue 32 item 7)."""
    for x in (30.0, 40.0):
        with_part, free = _raw(x, 1.5, MESH), _raw(x, 1.5, None)
        for key in UNSEEN_KEYS:
            np.testing.assert_array_equal(getattr(with_part, key), getattr(free, key), err_msg=key)
        np.testing.assert_array_equal(with_part.visible, free.visible & ~with_part.hidden)
        assert with_part.rim_hidden[:, 0].max() == 1.0 and with_part.hidden[:, 0].any()
        assert not np.array_equal(_evaluate(x, 1.5, MESH).fov, free.fov)  # scored: the rule bites here


def test_g_dir_weighs_a_hole_by_its_rim_seen():
    """Λ weighs each hole's rows by the seen fraction of its rim: a hole hidden whole at every pose (slab test)
    leaves Λ as the other holes give it alone — shrinking, moving or removing it changes nothing —, a partly
    hidden one adds less image motion than the same hole seen, a wholly seen one as much."""
    assert _slab_hidden(np.vstack([_rim(30.0, 1.5, 256), _rim(22.0, 1.5, 256)])).all()
    alone = measures.evaluate(CAMERA, T_CAM_PART, SCREWS, OTHERS, np.tile(UP, (3, 1)), np.full(3, 2.0)).resolvability
    assert np.all(alone > 0)
    for occlusion in (MESH, MAPS):
        for x, r in ((30.0, 1.5), (30.0, 0.2), (22.0, 1.5)):
            np.testing.assert_allclose(_evaluate(x, r, occlusion).resolvability, alone, rtol=1e-12)
    h = _slab_fraction(44.0, 1.5)
    part, seen, hidden = (h > 0) & (h < 1), h == 0, h == 1
    assert seen.sum() >= 6 and part.sum() >= 2 and hidden.any()
    lam, free = _evaluate(44.0, 1.5, MESH).resolvability, _evaluate(44.0, 1.5, None).resolvability
    np.testing.assert_allclose(lam[seen], free[seen], rtol=1e-12)
    np.testing.assert_allclose(lam[hidden], alone[hidden], rtol=1e-12)
    assert np.all(lam[part] > alone[part]) and np.all(lam[part] < free[part])
    # the weight is the seen fraction: Λ² = ‖J γ̇‖² (full rank) adds (1 − h)² of the hole's own image speed²
    np.testing.assert_allclose(lam[part] ** 2, alone[part] ** 2 + (1 - h[part]) ** 2 * (free[part] ** 2
                                                                                       - alone[part] ** 2), rtol=1e-9)


def test_g_pose_gives_a_hidden_rim_no_information():
    """g_POSE's information with the target's rim hidden at every pose (slab test's fraction) equals the other
    holes' alone; a partly hidden rim gives less than a seen one."""
    centres = np.vstack([[[30.0, 0.0, 5.0]], OTHERS])
    normals, radii = np.tile(UP, (4, 1)), np.r_[1.5, np.full(3, 2.0)]
    occ = np.zeros((12, 4))
    occ[:, 0] = _slab_fraction(30.0, 1.5)
    assert np.all(occ[:, 0] == 1)
    alone = pose_information(CAMERA, T_CAM_PART, OTHERS, normals[1:], radii[1:]).information
    for x, r in ((30.0, 1.5), (22.0, 0.5)):
        centres[0, 0], radii[0] = x, r
        info = pose_information(CAMERA, T_CAM_PART, centres, normals, radii, occlusion=occ).information
        np.testing.assert_allclose(info, alone, rtol=1e-9, atol=1e-12 * np.abs(alone).max())
    centres[0, 0], radii[0] = 44.0, 1.5
    occ[:, 0] = _slab_fraction(44.0, 1.5)
    part = (occ[:, 0] > 0) & (occ[:, 0] < 1)
    assert part.any()
    seen = pose_information(CAMERA, T_CAM_PART, centres, normals, radii).information
    partly = pose_information(CAMERA, T_CAM_PART, centres, normals, radii, occlusion=occ).information
    assert np.all(np.trace(partly[part], axis1=1, axis2=2) <= np.trace(seen[part], axis1=1, axis2=2))


def test_compiled_rim_pass_equals_the_point_lookups():
    """``DepthMaps.circle_hidden_fraction`` (compiled) is the mean of ``hidden_fraction`` over the rim points,
    also for tiled maps seen from displaced cameras (the robustness draws)."""
    rng = np.random.default_rng(5)
    M, K = 300, RIM_SAMPLES
    poses = rng.integers(0, 12, M)
    C = np.einsum("mij,mj->im", T_CAM_PART[poses, :3, :3],
                  np.column_stack([rng.uniform(0, 50, M), rng.uniform(-20, 20, M), np.full(M, 5.0)])) \
        + T_CAM_PART[poses, :3, 3].T
    U, V = rng.normal(0, 2.0, (3, M)), rng.normal(0, 2.0, (3, M))
    phi = 2 * np.pi * (np.arange(K) + 0.5) / K
    X, Y, Z = (C[k, :, None] + U[k, :, None] * np.cos(phi) + V[k, :, None] * np.sin(phi) for k in range(3))
    shift = np.tile(np.eye(4), (24, 1, 1))
    shift[12:, :3, 3] = [0.4, -0.3, 0.2]  # the second copy's cameras displaced
    for maps, rows in ((MAPS, poses), (MAPS.tile(2, shift), poses + 12)):
        expected = maps.hidden_fraction(X, Y, Z, poses=rows).mean(axis=-1)
        assert (expected == 0).any() and (expected == 1).any() and ((expected > 0) & (expected < 1)).sum() > 20
        np.testing.assert_allclose(maps.circle_hidden_fraction(C, U, V, K, rows), expected, atol=1e-12)


def test_the_depth_maps_visibility_term_slopes_out_of_hiding():
    """With the depth maps, h is continuous in the hole's position (no step where the centre's ray clears the wall)
    and, moving away from the wall, falls from 1 to 0 with no flat step in between: a slope to follow."""
    xs = np.arange(30.0, 46.0, 0.02)
    centres = np.column_stack([xs, np.zeros_like(xs), np.full_like(xs, 5.0)])
    m = scored_measures(measures.evaluate(CAMERA, T_CAM_PART, SCREWS, centres, np.tile(UP, (len(xs), 1)),
                                          np.full(len(xs), 1.5), min_axis_px=MIN_AXIS_PX, occlusion_mesh=MAPS),
                        CAMERA, MIN_AXIS_PX)
    h = m.rim_hidden  # (12 poses, positions)
    assert np.abs(np.diff(h, axis=1)).max() < 0.05  # the centre-ray test jumps by 1 between two such positions
    assert np.abs(np.diff(m.hidden.astype(float), axis=1)).max() == 1.0
    for k in range(len(h)):
        part = (h[k] > 0) & (h[k] < 1)
        if part.any():
            assert np.all(np.diff(h[k][part]) < 0)  # strictly decreasing while partly hidden
            assert np.all(np.diff(m.fov[k][part]) > 0)  # and the FOV margin rises with it
    assert sum(((h[k] > 0) & (h[k] < 1)).any() for k in range(len(h))) >= 8
