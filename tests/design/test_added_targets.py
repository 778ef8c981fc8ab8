"""Added target holes (issue 31): candidate sites, the batched objective, the lazy greedy and its exhaustive
reference — on a synthetic plate seen by the flagship's camera (no CAD: fast, exact geometry)."""

from __future__ import annotations

import numpy as np
import pytest

from cadfeat.cad.features import FaceOutline, Hole
from cadfeat.camera import Camera
from cadfeat.cell import Cell
from cadfeat.design.added_targets import (
    FaceRules,
    Movable,
    PoseScene,
    TargetObjective,
    conflicts,
    exhaustive,
    lazy_greedy,
    refine,
    site_margins,
    sites_on_faces,
)
from cadfeat.design.pose_terms import cell_models
from cadfeat.poses import cam_from_part
from cadfeat.study.pose_accuracy import predict
from cadfeat.trajectory import orbit_arc

W, H = 80.0, 60.0  # plate face z = 0, x in [-40, 40], y in [-30, 30], normal +z
OUTLINE = FaceOutline(origin=np.zeros(3), u=np.array([1.0, 0, 0]), v=np.array([0, 1.0, 0]),
                      outer=np.array([[-W / 2, -H / 2], [W / 2, -H / 2], [W / 2, H / 2], [-W / 2, H / 2]]))
R_RIM = 2.75


def _hole(x: float, y: float, r: float = 2.0, name: str = "") -> Hole:
    return Hole(centre=np.array([x, y, 0.0]), axis=np.array([0, 0, 1.0]), radius_mm=r, bore_radius_mm=r,
                depth_mm=2.0, through=False, kind="plain", host_face=0, outline=OUTLINE, name=name)


HOLES = [_hole(-25, -15, name="H1"), _hole(25, -15, name="H2"), _hole(0, 18, 4.0, name="H3")]


def _rules(boxes: np.ndarray | None = None) -> FaceRules:
    c = np.array([h.centre for h in HOLES])
    r = np.array([h.radius_mm for h in HOLES])
    return FaceRules(OUTLINE, c, r, np.zeros((0, 6)) if boxes is None else boxes, R_RIM, 3.0, 3.0, 3.0)


@pytest.fixture(scope="module")
def scene() -> PoseScene:
    camera = Camera.preset("basler-aca1300-200um-8mm")
    traj = orbit_arc(centre=[0, 0, 0], radius_mm=260, elevation_deg=55, azimuth_start_deg=-120,
                     azimuth_end_deg=-60, n=12)
    T = cam_from_part(traj.T_task_cam, np.eye(4))
    return PoseScene(camera, T, 50.0, "rms", cell_models(Cell()), float(Cell().noise_sigma_grey))


def _objective(scene: PoseScene, pitch: float) -> tuple[TargetObjective, object]:
    sites = sites_on_faces([_rules()], pitch)
    c = np.array([h.centre for h in HOLES])
    a = np.array([h.axis for h in HOLES])
    r = np.array([h.radius_mm for h in HOLES])
    base = (c, a, r, np.zeros(3, bool), np.full(3, 2.0))
    L = len(scene.T_cam_part)
    obj = TargetObjective(scene, base, ["plain"] * 3, np.zeros((L, 3)), R_RIM, 2.0, "plain", sites.centres,
                          sites.axes, np.zeros((L, len(sites))))
    return obj, sites


def test_sites_keep_every_requirement_exact_geometry() -> None:
    """Every site keeps the edge distance to the rectangle (exact: the distance to its nearest side), the ligament
    to every hole (exact circle distance) and stays out of the box; a site just outside is refused."""
    box = np.array([[10.0, -30.0, -5.0, 40.0, -10.0, 5.0]])
    sites = sites_on_faces([_rules(box)], 1.0)
    x, y = sites.centres[:, 0], sites.centres[:, 1]
    edge = np.minimum.reduce([x + W / 2, W / 2 - x, y + H / 2, H / 2 - y])
    assert len(sites) > 100
    assert np.all(edge >= R_RIM + 3.0 - 1e-9)
    for h in HOLES:
        assert np.all(np.hypot(x - h.centre[0], y - h.centre[1]) >= h.radius_mm + R_RIM + 3.0 - 1e-9)
    dx, dy = np.maximum.reduce([10 - x, 0 * x, x - 40]), np.maximum.reduce([-30 - y, 0 * y, y + 10])
    assert np.all(np.hypot(dx, dy) >= R_RIM + 3.0 - 1e-9)  # the box's footprint on the face (z = 0 inside it)
    assert np.any(np.hypot(dx, dy) < R_RIM + 4.0)
    m = site_margins(np.array([[W / 2 - R_RIM - 2.9, 0.0], [W / 2 - R_RIM - 3.1, 0.0]]), _rules())
    assert m["edge"][0] < 0 <= m["edge"][1]


def test_conflicts_are_the_ligament_between_rims() -> None:
    sites = sites_on_faces([_rules()], 4.0)
    clash = conflicts(sites, R_RIM, 3.0)
    d = np.linalg.norm(sites.centres[:, None] - sites.centres[None], axis=-1)
    assert np.array_equal(clash, d < 2 * R_RIM + 3.0)


def test_objective_is_the_study_prediction(scene: PoseScene) -> None:
    """The batched g_POSE of a design with two added holes equals ``pose_accuracy.predict`` of that design's
    holes (the study's prediction), one design at a time."""
    obj, sites = _objective(scene, 6.0)
    sets = np.array([[0, 5], [3, 17], [10, 30]])
    g = obj.of_sets(sets)
    for s, value in zip(sets, g, strict=True):
        holes = HOLES + [Hole(centre=sites.centres[i], axis=sites.axes[i], radius_mm=R_RIM, bore_radius_mm=R_RIM,
                              depth_mm=2.0, through=False, kind="plain", host_face=0, outline=OUTLINE) for i in s]
        info, _ = predict(scene.camera, scene.T_cam_part, holes, None, 50.0, cell=Cell())
        assert value == pytest.approx(-np.sqrt(np.mean(info.error_mm(50.0) ** 2)), rel=1e-10)


def test_greedy_within_two_percent_of_exhaustive(scene: PoseScene) -> None:
    """k = 2 over a coarse grid: the lazy greedy's error is within 2 % of the best pair found by evaluating
    every compatible pair."""
    obj, sites = _objective(scene, 8.0)
    clash = conflicts(sites, R_RIM, 3.0)
    res = lazy_greedy(obj.of_sets, clash, 2)
    best, g_best = exhaustive(obj.of_sets, clash, 2)
    assert len(sites) >= 30 and len(best) == 2
    assert -res.values[2] <= 1.02 * -g_best
    assert res.values[0] < res.values[1] < res.values[2]


def test_lazy_greedy_is_the_plain_greedy_on_a_submodular_function() -> None:
    """On a coverage function (exactly submodular) the lazy greedy chooses what the plain greedy chooses,
    evaluating fewer sets after the first step."""
    rng = np.random.default_rng(3)
    covers = rng.random((40, 60)) < 0.08
    weights = rng.random(60)

    def evaluate(sets: np.ndarray) -> np.ndarray:
        return np.array([weights[covers[list(s)].any(axis=0)].sum() if len(s) else 0.0 for s in sets])
    clash = np.eye(40, dtype=bool)
    res = lazy_greedy(evaluate, clash, 6, batch=4)
    chosen: list[int] = []
    for _ in range(6):
        rest = [i for i in range(40) if i not in chosen]
        chosen.append(rest[int(np.argmax(evaluate(np.array([chosen + [i] for i in rest]))))])
    assert res.order == chosen
    assert sum(res.evaluations[1:]) < 5 * 39


def test_exhaustive_skips_conflicting_pairs() -> None:
    """The best pair (0, 1) conflicts: the exhaustive search returns the best compatible one."""
    clash = np.eye(4, dtype=bool)
    clash[0, 1] = clash[1, 0] = True
    w = np.array([5.0, 4.0, 1.0, 0.0])
    best, g = exhaustive(lambda sets: w[sets].sum(axis=1), clash, 2)
    assert best == [0, 2] and g == 6.0


def test_refinement_never_worsens_and_keeps_requirements(scene: PoseScene) -> None:
    obj, sites = _objective(scene, 6.0)
    clash = conflicts(sites, R_RIM, 3.0)
    res = lazy_greedy(obj.of_sets, clash, 2)
    idx = np.array(res.order)
    L = len(scene.T_cam_part)
    out = refine(obj, [_rules()], sites.face[idx], sites.uv[idx], lambda c, *_: np.zeros((L, len(c))), step_mm=3.0)
    assert out.value >= out.value_before == pytest.approx(res.values[-1])
    m = site_margins(out.uv, _rules())
    assert all(np.all(v >= -1e-9) for v in m.values())
    assert np.linalg.norm(out.uv[0] - out.uv[1]) >= 2 * R_RIM + 3.0


def test_joint_refinement_moves_a_movable_hole_within_its_requirements(scene: PoseScene) -> None:
    """With the study's movable hole H1 (x = its centre's x, bounds [-30, -10] mm) refined jointly: the value
    never worsens, x stays in bounds, and every added hole keeps its requirements against H1 where it ends."""
    obj, sites = _objective(scene, 6.0)
    res = lazy_greedy(obj.of_sets, conflicts(sites, R_RIM, 3.0), 2)
    idx = np.array(res.order)
    c0 = np.array([h.centre for h in HOLES])
    a0 = np.array([h.axis for h in HOLES])
    r0 = np.array([h.radius_mm for h in HOLES])

    def holes(X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        c = np.repeat(c0[None], len(X), axis=0)
        c[:, 0, 0] = X[:, 0]
        return c, np.repeat(a0[None], len(X), axis=0), np.repeat(r0[None], len(X), axis=0)
    movable = Movable(np.array([-25.0]), np.array([0]), holes, lambda X: (X[:, 0] >= -30) & (X[:, 0] <= -10),
                      np.array([True, False, False]))
    L = len(scene.T_cam_part)
    out = refine(obj, [_rules()], sites.face[idx], sites.uv[idx], lambda c, *_: np.zeros((L, len(c))), step_mm=3.0,
                 movable=movable)
    assert out.value >= out.value_before and out.x is not None and -30 <= out.x[0] <= -10
    c = holes(out.x[None])[0][0]
    gap = np.linalg.norm(out.centres[:, None, :2] - c[None, :, :2], axis=-1) - r0[None] - R_RIM
    assert np.all(gap >= 3.0 - 1e-9)
