"""Trajectories: velocity screws of known motions, analytic vs numeric screws of every library kind, the
point-velocity equation (eq. 4.3), geometry of the library, CSV round trips and bad input."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

from cadfeat.camera import Camera
from cadfeat.errors import CadfeatError
from cadfeat.poses import hat, invert_T, make_T, points_in_frames
from cadfeat.trajectory import (
    TRAJECTORY_KINDS,
    Trajectory,
    TrajectoryError,
    helical_approach,
    numerical_velocity_screws,
    orbit_arc,
    raster_scan,
    read_csv,
    straight_approach,
    trajectory_from_dict,
    waypoints,
    write_csv,
)

pytestmark = pytest.mark.numerics  # run again under another BLAS kernel (Makefile: test)

RNG = np.random.default_rng(42)
T0 = make_T(Rotation.from_euler("xyz", [20, -35, 110], degrees=True).as_matrix(), [120.0, -40.0, 300.0])


def _twist_matrix(xi: np.ndarray) -> np.ndarray:
    M = np.zeros((4, 4))
    M[:3, :3] = hat(xi[3:])
    M[:3, 3] = xi[:3]
    return M


def _vee(M: np.ndarray) -> np.ndarray:
    return np.concatenate([M[..., :3, 3], M[..., [2, 0, 1], [1, 2, 0]]], axis=-1)


def _jittered_times(n: int, duration: float) -> np.ndarray:
    h = duration / (n - 1)
    t = np.linspace(0, duration, n) + np.random.default_rng(n).uniform(-0.3, 0.3, n) * h
    t[0], t[-1] = 0.0, duration
    return t


# ---------------------------------------------------------------------- numerical screws
@pytest.mark.parametrize("xi", [
    np.array([30.0, -12.0, 55.0, 0.4, -0.25, 0.9]),
    np.array([0.0, 0.0, -80.0, 0.0, 0.0, 0.0]),
    np.array([5.0, 1.0, 0.0, 1e-7, 0.0, -2e-7]),     # tiny rotation rate
    np.array([10.0, 20.0, 30.0, 2.0, 1.5, -1.0]),    # 0.5 rad per sample
])
@pytest.mark.parametrize("uniform", [True, False])
def test_constant_twist_is_recovered_exactly(xi, uniform):
    """T_k = T_0 exp(ξ t_k) (expm of the twist matrix) has the constant body screw ξ."""
    t = np.linspace(0.0, 2.0, 9) if uniform else _jittered_times(9, 2.0)
    T = T0 @ np.array([expm(_twist_matrix(xi) * tk) for tk in t])
    screws = Trajectory(T, t).velocity_screws()
    np.testing.assert_allclose(screws, np.tile(xi, (len(t), 1)), rtol=0, atol=1e-9 * (1 + np.abs(xi).max()))


def _product_motion(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """T(t) = T0 exp(A t) exp(B t²) and its body screw Ad(exp(−B t²)) a + 2 t b, all with matrices."""
    a = np.array([40.0, -10.0, 25.0, 0.6, 0.2, -0.5])
    b = np.array([-8.0, 15.0, 3.0, 0.1, -0.4, 0.3])
    A, B = _twist_matrix(a), _twist_matrix(b)
    E = np.array([expm(B * tk * tk) for tk in t])
    T = T0 @ np.array([expm(A * tk) for tk in t]) @ E
    screws = _vee(np.linalg.inv(E) @ A @ E) + 2 * t[:, None] * b
    return T, screws


def test_numerical_screws_are_second_order_on_non_uniform_samples():
    errors = []
    for n in (81, 161, 321):
        t = _jittered_times(n, 1.5)
        T, truth = _product_motion(t)
        errors.append(np.abs(numerical_velocity_screws(T, t) - truth).max())
    assert errors[-1] < 1e-3  # screw entries up to 40 mm/s
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.6), (errors, orders)


def test_two_samples_use_the_one_step_twist():
    xi = np.array([1.0, 2.0, 3.0, 0.1, 0.2, 0.3])
    T = np.stack([T0, T0 @ expm(_twist_matrix(xi) * 0.5)])
    np.testing.assert_allclose(Trajectory(T, [1.0, 1.5]).velocity_screws(), [xi, xi], atol=1e-12)


# ---------------------------------------------------------------------- the library
LIBRARY = {
    "straight_approach": lambda n: straight_approach([300, 100, 200], [60, 20, 90], [0, 0, 0], n, 4.0),
    "orbit_arc": lambda n: orbit_arc([10, 20, 0], 250.0, 35.0, -30.0, 120.0, n, 6.0),
    "orbit_arc_target": lambda n: orbit_arc([0, 0, 0], 200.0, -20.0, 90.0, 10.0, n, 3.0, target=[5, -10, 20],
                                            up=[0, 1, 1]),
    "helical_approach": lambda n: helical_approach([0, 0, 0], 300.0, 80.0, 250.0, 60.0, 1.5, n, 8.0, 20.0),
    "raster_scan": lambda n: raster_scan([5, -5, 10], 100.0, 60.0, 200.0, 4, n, 10.0),
    "waypoints": lambda n: waypoints([0.0, 1.0, 3.0, 4.0], n, positions=[[300, 0, 100], [200, 200, 150],
                                                                        [0, 250, 100], [-100, 100, 200]],
                                     targets=[0, 0, 0]),
}


def _smooth_samples(traj: Trajectory) -> np.ndarray:
    """Samples whose 3-point stencil does not straddle a kink (raster corners, waypoint keys): there the
    analytic screw jumps, by far more than its usual change between neighbours."""
    s = traj.velocity_screws()
    step = np.abs(np.diff(s, axis=0)).max(axis=1)
    jump = step > 50 * np.median(step) + 1e-9 * np.abs(s).max()
    near = np.zeros(len(s), bool)
    for shift in (-2, -1, 0, 1, 2):
        near |= np.roll(np.concatenate([jump, [False]]), shift)
    return ~near


@pytest.mark.parametrize("kind", sorted(LIBRARY))
def test_analytic_screws_agree_with_numeric(kind):
    traj = LIBRARY[kind](1601)
    assert traj.has_analytic_screws
    analytic = traj.velocity_screws()
    numeric = numerical_velocity_screws(traj.T_task_cam, traj.times_s)
    ok = _smooth_samples(traj)
    assert ok.sum() > 0.9 * len(traj)
    # relative to the largest linear (mm/s) and angular (rad/s) speed on the path
    scale = np.repeat([np.abs(analytic[:, :3]).max(), max(np.abs(analytic[:, 3:]).max(), 1e-9)], 3)
    np.testing.assert_allclose(analytic[ok] / scale, numeric[ok] / scale, rtol=0, atol=1e-4)
    interior = ok & np.isin(np.arange(len(traj)), [0, len(traj) - 1], invert=True)
    np.testing.assert_allclose(analytic[interior] / scale, numeric[interior] / scale, rtol=0, atol=2e-5)


@pytest.mark.parametrize("kind", ["orbit_arc", "helical_approach", "waypoints", "raster_scan"])
def test_screws_predict_the_velocity_of_task_points(kind):
    """Eq. 4.3: a point fixed in the task frame moves in the camera frame as Ṗ = −v − ω × P."""
    traj = LIBRARY[kind](2001)
    P = np.array([[0.0, 0.0, 0.0], [30.0, -20.0, 15.0], [-25.0, 40.0, -10.0]])
    P_cam = points_in_frames(invert_T(traj.T_task_cam), P)               # (L, 3, 3)
    t = traj.times_s
    dP = (P_cam[2:] - P_cam[:-2]) / (t[2:] - t[:-2])[:, None, None]     # central differences in time
    s = traj.velocity_screws()[1:-1, None, :]
    predicted = -s[..., :3] - np.cross(s[..., 3:], P_cam[1:-1])
    ok = _smooth_samples(traj)[1:-1]
    scale = np.abs(predicted).max()
    np.testing.assert_allclose(dP[ok] / scale, predicted[ok] / scale, rtol=0, atol=1e-5)


@pytest.mark.parametrize("kind, target", [("straight_approach", [0, 0, 0]), ("orbit_arc", [10, 20, 0]),
                                          ("orbit_arc_target", [5, -10, 20]), ("helical_approach", [0, 0, 0])])
def test_aimed_kinds_keep_the_target_at_the_principal_point(kind, target):
    cam = Camera.preset("basler-aca1300-200um-8mm")
    traj = LIBRARY[kind](30)
    uv = cam.project(points_in_frames(invert_T(traj.T_task_cam), np.array([target], float)))[:, 0]
    np.testing.assert_allclose(uv, np.tile([cam.cx, cam.cy], (30, 1)), atol=1e-6)


def test_orbit_arc_geometry():
    traj = orbit_arc([10, 20, 5], 250.0, 30.0, 0.0, 90.0, n=7, duration_s=3.0)
    rel = traj.positions - [10, 20, 5]
    np.testing.assert_allclose(np.linalg.norm(rel, axis=1), 250.0)
    np.testing.assert_allclose(rel[:, 2], 125.0)
    np.testing.assert_allclose(np.degrees(np.arctan2(rel[:, 1], rel[:, 0])), np.linspace(0, 90, 7), atol=1e-12)
    np.testing.assert_allclose(traj.times_s, np.linspace(0, 3, 7))
    np.testing.assert_allclose(np.einsum("li,li->l", traj.view_directions, -rel / 250.0), 1.0)


def test_helical_approach_geometry():
    traj = helical_approach([0, 0, 10], 300.0, 100.0, 200.0, 50.0, 2.0, n=9, duration_s=4.0)
    rel = traj.positions - [0, 0, 10]
    np.testing.assert_allclose(np.hypot(rel[:, 0], rel[:, 1]), np.linspace(300, 100, 9), atol=1e-9)
    np.testing.assert_allclose(rel[:, 2], np.linspace(200, 50, 9), atol=1e-9)
    np.testing.assert_allclose(rel[[0, 4, 8], 1], 0.0, atol=1e-9)  # two full turns: back on the +x axis


def test_raster_scan_geometry():
    traj = raster_scan([0, 0, 0], 100.0, 60.0, 200.0, lines=3, n=261, duration_s=26.0)
    # path: 3 lines of 100 mm + 2 steps of 30 mm = 360 mm → samples every 360/260 mm
    np.testing.assert_allclose(traj.view_directions, np.tile([0.0, 0.0, -1.0], (261, 1)), atol=1e-12)
    np.testing.assert_allclose(traj.positions[:, 2], 200.0)
    np.testing.assert_allclose(traj.positions[0], [-50, -30, 200], atol=1e-9)
    np.testing.assert_allclose(traj.positions[-1], [50, 30, 200], atol=1e-9)
    speed = np.linalg.norm(traj.velocity_screws()[:, :3], axis=1)
    np.testing.assert_allclose(speed, 360.0 / 26.0)
    np.testing.assert_allclose(traj.velocity_screws()[:, 3:], 0.0)
    y_lines = traj.positions[np.isclose(traj.positions[:, 1], 0.0), 0]
    assert np.all(np.diff(y_lines) < 0)  # the middle line runs back along −x (boustrophedon)


def test_waypoints_pass_through_key_poses():
    keys = np.stack([T0, T0 @ expm(_twist_matrix(np.array([50, 0, 10, 0.3, -0.2, 0.8]))),
                     T0 @ expm(_twist_matrix(np.array([-20, 30, 0, -0.5, 0.1, 1.5])))])
    traj = waypoints([0.0, 2.0, 3.0], n=31, poses=keys)
    np.testing.assert_allclose(traj.T_task_cam[[0, 20, 30]], keys, atol=1e-10)
    # halfway between keys: position average, rotation the geodesic midpoint (scipy rotvec, independent of Slerp)
    mid = traj.T_task_cam[10]
    np.testing.assert_allclose(mid[:3, 3], keys[:2, :3, 3].mean(axis=0), atol=1e-10)
    half = Rotation.from_matrix(keys[0, :3, :3]) * Rotation.from_rotvec(
        0.5 * (Rotation.from_matrix(keys[0, :3, :3]).inv() * Rotation.from_matrix(keys[1, :3, :3])).as_rotvec())
    np.testing.assert_allclose(mid[:3, :3], half.as_matrix(), atol=1e-12)


# ---------------------------------------------------------------------- Trajectory object
def test_properties_in_part_frame_and_subsample():
    traj = LIBRARY["helical_approach"](101)
    assert len(traj) == 101 and traj.positions.shape == (101, 3) and traj.view_directions.shape == (101, 3)
    T_task_part = make_T(Rotation.from_euler("zyx", [40, 10, -5], degrees=True).as_matrix(), [15, -20, 5])
    moved = traj.in_part_frame(T_task_part)
    np.testing.assert_allclose(T_task_part[None] @ moved.T_task_cam, traj.T_task_cam, atol=1e-9)
    np.testing.assert_allclose(moved.velocity_screws(), traj.velocity_screws())
    # camera-frame screws do not depend on the world frame: numeric screws agree too
    np.testing.assert_allclose(numerical_velocity_screws(moved.T_task_cam, moved.times_s),
                               numerical_velocity_screws(traj.T_task_cam, traj.times_s), atol=1e-8)
    sub = traj.subsample(7)
    idx = list(range(0, 101, 7)) + [100]
    np.testing.assert_array_equal(sub.times_s, traj.times_s[idx])
    np.testing.assert_allclose(sub.velocity_screws(), traj.velocity_screws()[idx])
    numeric_only = Trajectory(traj.T_task_cam, traj.times_s)
    np.testing.assert_allclose(numeric_only.subsample(10).velocity_screws(),
                               numeric_only.velocity_screws()[list(range(0, 101, 10))])
    with pytest.raises(TrajectoryError, match="step"):
        traj.subsample(0)
    with pytest.raises(ValueError):
        traj.T_task_cam[0, 0, 0] = 2.0  # read-only


@pytest.mark.parametrize("build, fragment", [
    (lambda: Trajectory(np.eye(4)[None].repeat(3, 0)[:, :3], [0, 1, 2]), r"shape \(L, 4, 4\)"),
    (lambda: Trajectory(np.eye(4)[None], [0.0]), "at least 2 samples"),
    (lambda: Trajectory(np.eye(4)[None].repeat(3, 0), [0, 1]), r"times_s must have shape \(3,\)"),
    (lambda: Trajectory(np.eye(4)[None].repeat(3, 0), [0, 2, 2], name="probe"), "'probe'.*sample 2"),
    (lambda: Trajectory(make_T(np.eye(3)[None] * [[[1.001]], [[1]]], np.zeros(3)), [0, 1]), "pose 0: rotation"),
    (lambda: Trajectory(np.eye(4)[None].repeat(2, 0) * 2, [0, 1]), r"pose 0: last row must be \[0, 0, 0, 1\]"),
    (lambda: Trajectory(np.diag([1.0, 1.0, -1.0, 1.0])[None].repeat(2, 0), [0, 1]), "proper rotation"),
    (lambda: Trajectory(np.full((2, 4, 4), np.nan), [0, 1]), "non-finite"),
    (lambda: Trajectory(np.eye(4)[None].repeat(2, 0), [0, 1], screws=np.zeros((2, 5))), "screws must have"),
])
def test_bad_trajectories(build, fragment):
    with pytest.raises(TrajectoryError, match=fragment):
        build()


@pytest.mark.parametrize("call, fragment", [
    (lambda: orbit_arc([0, 0, 0], -1.0, 10.0, 0.0, 90.0), "orbit_arc: radius_mm must be > 0"),
    (lambda: orbit_arc([0, 0, 0], 100.0, 90.0, 0.0, 90.0), r"elevation_deg must be in \(-90, 90\)"),
    (lambda: straight_approach([0, 0, 10], [0, 0, -10], [0, 0, 0]), "passes through the target"),
    (lambda: raster_scan([0, 0, 0], 10.0, 10.0, 50.0, 0), "lines must be ≥ 1"),
    (lambda: helical_approach([0, 0, 0], 1.0, 1.0, 1.0, 1.0, 1.0, n=1), "n must be ≥ 2"),
    (lambda: waypoints([0.0, 1.0], positions=[[0, 0, 1], [0, 1, 1]]), "needs poses, or positions and targets"),
    (lambda: waypoints([1.0, 0.0], positions=[[0, 0, 1], [0, 1, 1]], targets=[0, 0, 0]), "increase strictly"),
])
def test_bad_library_arguments(call, fragment):
    with pytest.raises(CadfeatError, match=fragment):
        call()


# ---------------------------------------------------------------------- CSV
@pytest.mark.parametrize("rotation", ["quaternion", "rotvec"])
@pytest.mark.parametrize("include_screws", [False, True])
def test_csv_round_trip(tmp_path, rotation, include_screws):
    traj = LIBRARY["waypoints"](25)
    path = tmp_path / "path.csv"
    write_csv(traj, path, rotation=rotation, include_screws=include_screws)
    header = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")][0]
    assert header.startswith("time_s,x_mm,y_mm,z_mm," + ("qx" if rotation == "quaternion" else "rx_rad"))
    back = read_csv(path)
    assert back.name == "path" and len(back) == 25
    np.testing.assert_allclose(back.T_task_cam, traj.T_task_cam, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.times_s, traj.times_s)
    assert back.has_analytic_screws == include_screws
    if include_screws:
        np.testing.assert_array_equal(back.velocity_screws(), traj.velocity_screws())


def test_csv_written_by_hand(tmp_path):
    """A file written by another tool: a 90° turn about task z, as quaternion and as rotation vector."""
    s = np.sqrt(0.5)
    (tmp_path / "q.csv").write_text(f"# from a robot log\ntime_s, x_mm, y_mm, z_mm, qx, qy, qz, qw\n"
                                    f"0.0,1,2,3,0,0,0,1\n\n0.5,4,5,6,0,0,{s},{s}\n")
    (tmp_path / "r.csv").write_text(f"time_s,x_mm,y_mm,z_mm,rx_rad,ry_rad,rz_rad\n0,1,2,3,0,0,0\n"
                                    f"0.5,4,5,6,0,0,{np.pi / 2}\n")
    expected = np.array([[0.0, -1.0, 0.0, 4.0], [1.0, 0.0, 0.0, 5.0], [0.0, 0.0, 1.0, 6.0], [0, 0, 0, 1]])
    for name in ("q.csv", "r.csv"):
        traj = read_csv(tmp_path / name)
        np.testing.assert_allclose(traj.T_task_cam[1], expected, atol=1e-15)
        # two samples: the constant twist that carries pose 0 to pose 1 in 0.5 s
        step = expm(_twist_matrix(traj.velocity_screws()[0]) * 0.5)
        np.testing.assert_allclose(traj.T_task_cam[0] @ step, traj.T_task_cam[1], atol=1e-12)
        np.testing.assert_allclose(traj.velocity_screws()[0, 3:], [0, 0, np.pi], atol=1e-12)


@pytest.mark.parametrize("text, fragment", [
    ("", "empty trajectory CSV"),
    ("t,x,y,z\n0,0,0,0\n", "line 1: unknown header 't,x,y,z'; allowed: 'time_s,x_mm"),
    ("time_s,x_mm,y_mm,z_mm,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n1,0,0,0,0,0,1\n", "line 3: expected 8 columns"),
    ("time_s,x_mm,y_mm,z_mm,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n1,0,abc,0,0,0,0,1\n",
     r"line 3, column 3 \(y_mm\): expected a finite number, got 'abc'"),
    ("time_s,x_mm,y_mm,z_mm,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n1,0,0,nan,0,0,0,1\n", r"line 3, column 4 \(z_mm\)"),
    ("# c\ntime_s,x_mm,y_mm,z_mm,rx_rad,ry_rad,rz_rad\n0,0,0,0,0,0,0\n0,1,0,0,0,0,0\n",
     r"line 4, column 1 \(time_s\): times must increase strictly"),
    ("time_s,x_mm,y_mm,z_mm,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n1,0,0,0,0,0,0,0.5\n", "line 3, columns 5-8.*norm 0.5"),
    ("time_s,x_mm,y_mm,z_mm,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n", "needs at least 2 samples, got 1"),
])
def test_bad_csv(tmp_path, text, fragment):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(TrajectoryError, match=fragment) as info:
        read_csv(path)
    assert str(path) in str(info.value)


def test_missing_csv_and_bad_rotation_option(tmp_path):
    with pytest.raises(TrajectoryError, match="cannot read"):
        read_csv(tmp_path / "none.csv")
    with pytest.raises(TrajectoryError, match="rotation must be one of quaternion, rotvec"):
        write_csv(LIBRARY["orbit_arc"](3), tmp_path / "x.csv", rotation="euler")


# ---------------------------------------------------------------------- study-file tables
def test_every_kind_builds_from_plain_data():
    specs = {
        "straight_approach": {"start": [300, 100, 200], "end": [60, 20, 90], "target": [0, 0, 0], "n": 20,
                              "duration_s": 4},
        "orbit_arc": {"centre": [10, 20, 0], "radius_mm": 250, "elevation_deg": 35, "azimuth_start_deg": -30,
                      "azimuth_end_deg": 120, "n": 20, "duration_s": 6.0},
        "helical_approach": {"centre": [0, 0, 0], "radius_start_mm": 300, "radius_end_mm": 80,
                             "height_start_mm": 250, "height_end_mm": 60, "turns": 1.5, "n": 20,
                             "duration_s": 8, "azimuth_start_deg": 20},
        "raster_scan": {"centre": [5, -5, 10], "width_mm": 100, "length_mm": 60, "standoff_mm": 200, "lines": 4,
                        "n": 20, "duration_s": 10},
        "waypoints": {"times_s": [0, 1, 3, 4], "n": 20, "positions": [[300, 0, 100], [200, 200, 150],
                                                                      [0, 250, 100], [-100, 100, 200]],
                      "targets": [0, 0, 0]},
    }
    assert set(specs) == set(TRAJECTORY_KINDS)
    for kind, args in specs.items():
        traj = trajectory_from_dict({"kind": kind, "name": f"my {kind}", **args}, origin="s.toml [trajectory]")
        direct = LIBRARY[kind](20)
        assert traj.name == f"my {kind}"
        np.testing.assert_allclose(traj.T_task_cam, direct.T_task_cam, atol=1e-12)
        np.testing.assert_allclose(traj.velocity_screws(), direct.velocity_screws(), atol=1e-12)


def test_csv_spec_relative_to_base_dir(tmp_path):
    write_csv(LIBRARY["orbit_arc"](10), tmp_path / "orbit.csv")
    traj = trajectory_from_dict({"csv": "orbit.csv"}, origin="s.toml [trajectory]", base_dir=tmp_path)
    assert len(traj) == 10 and traj.name == "orbit"
    with pytest.raises(TrajectoryError, match=r"s.toml \[trajectory\]: trajectory.csv: .*missing.csv: cannot read"):
        trajectory_from_dict({"csv": "missing.csv"}, origin="s.toml [trajectory]", base_dir=tmp_path)


ORBIT = {"kind": "orbit_arc", "centre": [0, 0, 0], "radius_mm": 100, "elevation_deg": 30, "azimuth_start_deg": 0,
         "azimuth_end_deg": 90}


@pytest.mark.parametrize("spec, fragment", [
    ([1, 2], "trajectory: expected a table"),
    ({"n": 3}, "trajectory: neither kind nor csv given; allowed: kind = one of .*orbit_arc.*, or csv"),
    ({"kind": "orbit_arc", "csv": "a.csv"}, "trajectory: kind and csv given together"),
    ({"kind": "spiral"}, "trajectory.kind: 'spiral' is not allowed; allowed: straight_approach, orbit_arc"),
    ({**ORBIT, "radius": 5}, r"trajectory.radius: unknown key; allowed: keys of \[trajectory\]: .*centre, radius_mm"),
    ({k: v for k, v in ORBIT.items() if k != "radius_mm"}, "trajectory.radius_mm: missing; allowed: number"),
    ({**ORBIT, "radius_mm": "100"}, "trajectory.radius_mm: '100' is not allowed; allowed: number"),
    ({**ORBIT, "n": 20.0}, "trajectory.n: 20.0 is not allowed; allowed: integer"),
    ({**ORBIT, "n": True}, "trajectory.n: True is not allowed"),
    ({**ORBIT, "centre": [0, 0]}, r"trajectory.centre: \[0, 0\] is not allowed; allowed: \[x, y, z\] \(3 numbers\)"),
    ({**ORBIT, "centre": ["a", 0, 0]}, "trajectory.centre: .* is not allowed"),
    ({**ORBIT, "radius_mm": -5}, "trajectory: orbit_arc: radius_mm must be > 0, got -5.0; allowed: arguments"),
    ({**ORBIT, "name": 3}, "trajectory.name: 3 is not allowed; allowed: a string"),
    ({"kind": "waypoints", "times_s": [0, 1], "positions": [[0, 0, 1], [1, 2]], "targets": [0, 0, 0]},
     "trajectory.positions: .* is not allowed; allowed: list of"),
    ({"csv": "a.csv", "n": 3}, r"trajectory.n: unknown key; allowed: keys of \[trajectory\]: name, csv"),
])
def test_bad_specs_name_origin_key_and_allowed(spec, fragment):
    with pytest.raises(TrajectoryError, match=fragment) as info:
        trajectory_from_dict(spec, origin="study.toml")
    assert str(info.value).startswith("study.toml: trajectory") and "\n" not in str(info.value)


def test_cli_lists_the_kinds():
    out = subprocess.run([sys.executable, "-m", "cadfeat.cli", "trajectories"], capture_output=True, text=True,
                         check=True).stdout
    for kind in TRAJECTORY_KINDS:
        assert f"{kind}:" in out
    assert "radius_mm" in out and "required" in out and "default [0, 0, 1]" in out
