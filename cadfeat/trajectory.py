"""Camera trajectories: L poses ``T_task_cam`` with times, velocity screws, a parametric library, CSV I/O.

A ``Trajectory`` is the thesis's Γ = {γ_1 … γ_L} (§4.2.1): the camera pose in the task (part) frame at
each sample, with its velocity screw γ̇_k = (v, ω) — the camera's linear (mm/s) and angular (rad/s)
velocity expressed in the camera frame at sample k (eq. 4.3). The library trajectories know their
screws analytically; otherwise they come from the SE(3) logarithm of neighbouring poses.

Library kinds (``TRAJECTORY_KINDS``; ``cadfeat trajectories`` lists their arguments): ``straight_approach``,
``orbit_arc``, ``helical_approach``, ``raster_scan``, ``waypoints``. All but ``raster_scan`` (looking straight
down) and ``waypoints`` (interpolated key poses) aim the camera at a target with ``poses.look_at``.
Samples are uniform in time over ``[0, duration_s]`` and the motion has constant parameter speed.

Study files give a trajectory as a table (``trajectory_from_dict``)::

    {"kind": "orbit_arc", "centre": [0, 0, 0], "radius_mm": 300, ...}    # a library kind + its arguments
    {"csv": "path/to/poses.csv"}                                         # or a CSV file

CSV format (``write_csv`` / ``read_csv``): comma-separated, one header line, then one sample per line;
blank lines and lines starting with ``#`` are ignored. The pose is the camera pose ``T_task_cam``
(position of the camera centre in the task frame, mm, and the rotation camera → task), either as a
scalar-last unit quaternion or as a rotation vector (axis · angle, rad)::

    time_s,x_mm,y_mm,z_mm,qx,qy,qz,qw
    time_s,x_mm,y_mm,z_mm,rx_rad,ry_rad,rz_rad

Either header may be followed by six optional columns with known velocity screws (camera frame):
``vx_mm_s,vy_mm_s,vz_mm_s,wx_rad_s,wy_rad_s,wz_rad_s``. Times must increase strictly.
"""

from __future__ import annotations

import csv
import inspect
import math
import types
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation, Slerp

from cadfeat.errors import CadfeatError
from cadfeat.poses import invert_T, look_at, look_at_screws, make_T, rotation_error, twist_between

#: Largest deviation of a pose's rotation block from a proper rotation (‖RᵀR − I‖_max, |det R − 1|).
ROTATION_TOL = 1e-6


class TrajectoryError(CadfeatError):
    """A trajectory definition, CSV file or study-file table is invalid."""


# ---------------------------------------------------------------------- the Trajectory
class Trajectory:
    """L camera poses ``T_task_cam`` (L, 4, 4) at strictly increasing ``times_s`` (L,), L ≥ 2.

    ``screws`` (L, 6), optional, are known velocity screws (v mm/s, ω rad/s, camera frame); without
    them ``velocity_screws`` differentiates the poses numerically. The arrays are read-only copies.
    """

    def __init__(self, T_task_cam: ArrayLike, times_s: ArrayLike, name: str = "",
                 screws: ArrayLike | None = None) -> None:
        self.name = str(name)
        self.T_task_cam = _readonly(_validate_poses(T_task_cam, self._label))
        self.times_s = _readonly(_validate_times(times_s, len(self.T_task_cam), self._label))
        self.screws = None if screws is None else _readonly(_validate_screws(screws, len(self), self._label))

    @property
    def _label(self) -> str:
        return f"trajectory '{self.name}'" if self.name else "trajectory"

    def __len__(self) -> int:
        return int(self.T_task_cam.shape[0])

    def __repr__(self) -> str:
        return (f"Trajectory({self.name!r}, L={len(self)}, {self.duration_s:g} s, "
                f"screws={'analytic' if self.screws is not None else 'numeric'})")

    @property
    def positions(self) -> np.ndarray:
        """Camera centres in the task frame, (L, 3), mm."""
        return self.T_task_cam[:, :3, 3]

    @property
    def rotations(self) -> np.ndarray:
        """Camera orientations R_task_cam, (L, 3, 3)."""
        return self.T_task_cam[:, :3, :3]

    @property
    def view_directions(self) -> np.ndarray:
        """Unit optical axes ν_C (camera z axis) in the task frame, (L, 3) (eq. 3.1, 3.6)."""
        return self.T_task_cam[:, :3, 2]

    @property
    def duration_s(self) -> float:
        return float(self.times_s[-1] - self.times_s[0])

    @property
    def has_analytic_screws(self) -> bool:
        return self.screws is not None

    def velocity_screws(self) -> np.ndarray:
        """γ̇_k = (v, ω), (L, 6): camera velocity in the camera frame at each sample (eq. 4.3).

        The stored analytic screws when known, else ``numerical_velocity_screws`` of the poses.
        """
        if self.screws is not None:
            return np.array(self.screws)
        return numerical_velocity_screws(self.T_task_cam, self.times_s)

    def in_part_frame(self, T_task_part: ArrayLike) -> Trajectory:
        """The same motion with poses ``T_part_cam = T_task_part⁻¹ T_task_cam`` (a fixed part pose).

        Camera-frame screws do not change under a fixed change of the world frame, so they are kept.
        """
        T_task_part = _validate_poses(np.asarray(T_task_part, dtype=float)[None], "T_task_part")[0]
        return Trajectory(invert_T(T_task_part) @ self.T_task_cam, self.times_s, self.name, self.screws)

    def subsample(self, step: int) -> Trajectory:
        """Every ``step``-th sample (and always the last). Screws are those of the full trajectory
        at the kept samples (analytic, or numeric on the dense poses — more accurate than re-deriving)."""
        if isinstance(step, bool) or not isinstance(step, int | np.integer) or step < 1:
            raise TrajectoryError(f"{self._label}: subsample step must be an integer ≥ 1, got {step!r}")
        idx = np.unique(np.append(np.arange(0, len(self), step), len(self) - 1))
        return Trajectory(self.T_task_cam[idx], self.times_s[idx], self.name, self.velocity_screws()[idx])


def numerical_velocity_screws(T_task_cam: ArrayLike, times_s: ArrayLike) -> np.ndarray:
    """Velocity screws (L, 6) from poses by second-order differences on SE(3).

    Interior samples: with ξ± = log(T_k⁻¹ T_k±1) and steps h+ = t_k+1 − t_k, h− = t_k − t_k−1,
    γ̇_k = (h−² ξ+ − h+² ξ−) / (h+ h− (h+ + h−)) — for uniform steps the central difference
    [log(T_k⁻¹T_k+1) − log(T_k⁻¹T_k−1)] / (t_k+1 − t_k−1). The ends use the one-sided second-order
    formula on the two nearest neighbours (first order when L = 2). Exact for a constant twist.
    Assumes neighbouring samples rotate by much less than π.
    """
    T = np.asarray(T_task_cam, dtype=float)
    t = np.asarray(times_s, dtype=float)
    if len(t) == 2:
        xi = twist_between(T[0], T[1]) / (t[1] - t[0])
        return np.stack([xi, xi])
    interior = _three_point(twist_between(T[1:-1], T[2:]), t[2:] - t[1:-1],
                            twist_between(T[1:-1], T[:-2]), t[:-2] - t[1:-1])
    ends = _three_point(twist_between(T[[0, -1]], T[[1, -2]]), t[[1, -2]] - t[[0, -1]],
                        twist_between(T[[0, -1]], T[[2, -3]]), t[[2, -3]] - t[[0, -1]])
    return np.concatenate([ends[:1], interior, ends[1:]])


def _three_point(xi1: np.ndarray, h1: np.ndarray, xi2: np.ndarray, h2: np.ndarray) -> np.ndarray:
    """Derivative at 0 of ξ(h) with ξ(0) = 0 from ξ(h1), ξ(h2) (signed steps): exact for quadratics."""
    return (h2[:, None] ** 2 * xi1 - h1[:, None] ** 2 * xi2) / (h1 * h2 * (h2 - h1))[:, None]


# ---------------------------------------------------------------------- validation
def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


def _validate_poses(T: ArrayLike, label: str) -> np.ndarray:
    T = np.asarray(T, dtype=float)
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise TrajectoryError(f"{label}: poses must have shape (L, 4, 4), got {T.shape}")
    bad = ~np.all(np.isfinite(T), axis=(1, 2))
    if np.any(bad):
        raise TrajectoryError(f"{label}: pose {int(np.argmax(bad))} has non-finite entries")
    bad = np.abs(T[:, 3] - [0.0, 0.0, 0.0, 1.0]).max(axis=1) > 1e-12
    if np.any(bad):
        raise TrajectoryError(f"{label}: pose {int(np.argmax(bad))}: last row must be [0, 0, 0, 1]")
    err = rotation_error(T[:, :3, :3])
    if np.any(err > ROTATION_TOL):
        k = int(np.argmax(err > ROTATION_TOL))
        raise TrajectoryError(f"{label}: pose {k}: rotation block is not a proper rotation "
                              f"(error {err[k]:.2g} > {ROTATION_TOL:g})")
    return T


def _validate_times(times_s: ArrayLike, L: int, label: str) -> np.ndarray:
    t = np.asarray(times_s, dtype=float)
    if t.shape != (L,):
        raise TrajectoryError(f"{label}: times_s must have shape ({L},) like the poses, got {t.shape}")
    if L < 2:
        raise TrajectoryError(f"{label}: needs at least 2 samples, got {L}")
    if not np.all(np.isfinite(t)):
        raise TrajectoryError(f"{label}: times_s must be finite")
    bad = np.diff(t) <= 0
    if np.any(bad):
        k = int(np.argmax(bad)) + 1
        raise TrajectoryError(f"{label}: times_s must increase strictly; sample {k} has {t[k]:g} s "
                              f"after {t[k - 1]:g} s")
    return t


def _validate_screws(screws: ArrayLike, L: int, label: str) -> np.ndarray:
    s = np.asarray(screws, dtype=float)
    if s.shape != (L, 6):
        raise TrajectoryError(f"{label}: screws must have shape ({L}, 6), got {s.shape}")
    if not np.all(np.isfinite(s)):
        raise TrajectoryError(f"{label}: screws must be finite")
    return s


# ---------------------------------------------------------------------- argument types of library kinds
@dataclass(frozen=True)
class ArgType:
    """How a library-trajectory argument is read from plain data (study files): text and converter."""

    description: str
    convert: Callable[[Any], Any]


def _is_number(x: Any) -> bool:
    return isinstance(x, int | float | np.integer | np.floating) and not isinstance(x, bool | np.bool_)


def _to_float(value: Any) -> float:
    if not _is_number(value) or not math.isfinite(float(value)):
        raise TypeError("expected a finite number")
    return float(value)


def _to_int(value: Any) -> int:
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | np.integer):
        raise TypeError("expected an integer")
    return int(value)


def _to_array(value: Any, shape: tuple[int | None, ...], what: str) -> np.ndarray:
    try:
        a = np.asarray(value)
    except ValueError as exc:  # ragged nesting
        raise TypeError(f"expected {what}") from exc
    ok_shape = a.ndim == len(shape) and all(s is None or s == n for s, n in zip(shape, a.shape, strict=True))
    if not ok_shape or a.dtype == bool or not (np.issubdtype(a.dtype, np.integer) or
                                                np.issubdtype(a.dtype, np.floating)):
        raise TypeError(f"expected {what}")
    a = a.astype(float)
    if not np.all(np.isfinite(a)):
        raise TypeError(f"expected {what} with finite numbers")
    return a


def _to_one_or_more_vec3(value: Any) -> np.ndarray:
    what = "[x, y, z] or a list of [x, y, z] triples"
    try:
        return _to_array(value, (3,), what)
    except TypeError:
        return _to_array(value, (None, 3), what)


Float = Annotated[float, ArgType("number", _to_float)]
Int = Annotated[int, ArgType("integer", _to_int)]
Vec3 = Annotated[ArrayLike, ArgType("[x, y, z] (3 numbers)", lambda v: _to_array(v, (3,), "3 numbers [x, y, z]"))]
Vec3List = Annotated[ArrayLike, ArgType("list of [x, y, z]",
                                        lambda v: _to_array(v, (None, 3), "a list of [x, y, z] triples"))]
FloatList = Annotated[ArrayLike, ArgType("list of numbers", lambda v: _to_array(v, (None,), "a list of numbers"))]
OneOrMoreVec3 = Annotated[ArrayLike, ArgType("[x, y, z] or list of [x, y, z]", _to_one_or_more_vec3)]
PoseList = Annotated[ArrayLike, ArgType("list of 4x4 matrices",
                                        lambda v: _to_array(v, (None, 4, 4), "a list of 4x4 matrices"))]


def _check(kind: str, ok: bool, message: str) -> None:
    if not ok:
        raise TrajectoryError(f"{kind}: {message}")


def _check_common(kind: str, n: int, duration_s: float) -> np.ndarray:
    """Validate the sample count and duration; return the sample times (n,), s."""
    _check(kind, n >= 2, f"n must be ≥ 2, got {n}")
    _check(kind, duration_s > 0, f"duration_s must be > 0, got {duration_s}")
    return np.linspace(0.0, duration_s, n)


def _aimed(name: str, positions: np.ndarray, velocities: np.ndarray, target: np.ndarray,
           up: np.ndarray, times: np.ndarray) -> Trajectory:
    """A look-at trajectory at a fixed target with analytic screws from the position derivative."""
    if np.any(np.linalg.norm(positions - target, axis=-1) < 1e-9):
        raise TrajectoryError(f"{name}: the camera passes through the target {target.tolist()}")
    T = look_at(positions, target, up)
    return Trajectory(T, times, name, look_at_screws(positions, target, velocities, up=up))


# ---------------------------------------------------------------------- the library
def straight_approach(start: Vec3, end: Vec3, target: Vec3, n: Int = 50, duration_s: Float = 5.0,
                      up: Vec3 = (0.0, 0.0, 1.0)) -> Trajectory:
    """Straight line from ``start`` to ``end`` (mm) at constant speed, looking at ``target``."""
    times = _check_common("straight_approach", n, duration_s)
    start, end, target = (np.asarray(a, dtype=float) for a in (start, end, target))
    seg = end - start
    closest = start + np.clip((target - start) @ seg / max(seg @ seg, 1e-300), 0.0, 1.0) * seg
    _check("straight_approach", np.linalg.norm(target - closest) > 1e-9,
           f"the line from start to end passes through the target {target.tolist()}")
    s = times / duration_s
    positions = start + s[:, None] * (end - start)
    velocity = np.broadcast_to((end - start) / duration_s, positions.shape)
    return _aimed("straight_approach", positions, velocity, target, np.asarray(up, dtype=float), times)


def orbit_arc(centre: Vec3, radius_mm: Float, elevation_deg: Float, azimuth_start_deg: Float,
              azimuth_end_deg: Float, n: Int = 50, duration_s: Float = 5.0, target: Vec3 | None = None,
              up: Vec3 = (0.0, 0.0, 1.0)) -> Trajectory:
    """Circular arc at ``radius_mm`` around ``centre`` at a fixed elevation above its xy plane.

    Position ``centre + r (cos e cos φ, cos e sin φ, sin e)`` with the azimuth φ (from task +x towards +y)
    going linearly from start to end; the camera looks at ``target`` (default ``centre``).
    """
    times = _check_common("orbit_arc", n, duration_s)
    _check("orbit_arc", radius_mm > 0, f"radius_mm must be > 0, got {radius_mm}")
    _check("orbit_arc", abs(elevation_deg) < 90, f"elevation_deg must be in (-90, 90), got {elevation_deg}")
    centre = np.asarray(centre, dtype=float)
    e = np.radians(elevation_deg)
    phi0, phi1 = np.radians(azimuth_start_deg), np.radians(azimuth_end_deg)
    phi = phi0 + (phi1 - phi0) * times / duration_s
    rho, phi_dot = radius_mm * np.cos(e), (phi1 - phi0) / duration_s
    positions = centre + np.stack([rho * np.cos(phi), rho * np.sin(phi), np.full_like(phi, radius_mm * np.sin(e))], 1)
    velocities = rho * phi_dot * np.stack([-np.sin(phi), np.cos(phi), np.zeros_like(phi)], 1)
    aim = centre if target is None else np.asarray(target, dtype=float)
    return _aimed("orbit_arc", positions, velocities, aim, np.asarray(up, dtype=float), times)


def helical_approach(centre: Vec3, radius_start_mm: Float, radius_end_mm: Float, height_start_mm: Float,
                     height_end_mm: Float, turns: Float, n: Int = 50, duration_s: Float = 5.0,
                     azimuth_start_deg: Float = 0.0, target: Vec3 | None = None,
                     up: Vec3 = (0.0, 0.0, 1.0)) -> Trajectory:
    """Helix around the vertical axis through ``centre``: radius and height (above ``centre``, mm) change
    linearly while the azimuth turns ``turns`` times (negative: clockwise from above); looks at ``target``
    (default ``centre``)."""
    times = _check_common("helical_approach", n, duration_s)
    _check("helical_approach", radius_start_mm >= 0 and radius_end_mm >= 0, "radii must be ≥ 0")
    centre = np.asarray(centre, dtype=float)
    s = times / duration_s
    r = radius_start_mm + (radius_end_mm - radius_start_mm) * s
    h = height_start_mm + (height_end_mm - height_start_mm) * s
    phi = np.radians(azimuth_start_deg) + 2.0 * np.pi * turns * s
    r_dot = (radius_end_mm - radius_start_mm) / duration_s
    h_dot = (height_end_mm - height_start_mm) / duration_s
    phi_dot = 2.0 * np.pi * turns / duration_s
    c, sn = np.cos(phi), np.sin(phi)
    positions = centre + np.stack([r * c, r * sn, h], 1)
    velocities = np.stack([r_dot * c - r * phi_dot * sn, r_dot * sn + r * phi_dot * c, np.full_like(r, h_dot)], 1)
    aim = centre if target is None else np.asarray(target, dtype=float)
    return _aimed("helical_approach", positions, velocities, aim, np.asarray(up, dtype=float), times)


def raster_scan(centre: Vec3, width_mm: Float, length_mm: Float, standoff_mm: Float, lines: Int,
                n: Int = 50, duration_s: Float = 5.0) -> Trajectory:
    """Boustrophedon over a ``width_mm`` (x) × ``length_mm`` (y) rectangle centred on ``centre``, camera
    ``standoff_mm`` above it looking straight down (task −z; task +y is image up), constant speed.

    ``lines`` passes along x, evenly spaced in y (one pass along the centre line when ``lines`` = 1),
    joined by steps along y. Screws are analytic (ω = 0); at a corner sample the outgoing segment's.
    """
    times = _check_common("raster_scan", n, duration_s)
    _check("raster_scan", lines >= 1, f"lines must be ≥ 1, got {lines}")
    _check("raster_scan", width_mm > 0, f"width_mm must be > 0, got {width_mm}")
    _check("raster_scan", length_mm >= 0, f"length_mm must be ≥ 0, got {length_mm}")
    _check("raster_scan", standoff_mm > 0, f"standoff_mm must be > 0, got {standoff_mm}")
    centre = np.asarray(centre, dtype=float)
    ys = np.linspace(-length_mm / 2, length_mm / 2, lines) if lines > 1 else np.zeros(1)
    xs = np.where(np.arange(lines) % 2 == 0, 1.0, -1.0)[:, None] * np.array([-width_mm / 2, width_mm / 2])
    corners = np.stack([xs.ravel(), np.repeat(ys, 2), np.zeros(2 * lines)], 1) + centre + [0.0, 0.0, standoff_mm]
    seg = np.diff(corners, axis=0)
    seg = seg[np.linalg.norm(seg, axis=1) > 0]
    corners = np.concatenate([corners[:1], corners[:1] + np.cumsum(seg, axis=0)])
    seg_len = np.linalg.norm(seg, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    arc = cum[-1] * times / duration_s
    i = np.clip(np.searchsorted(cum, arc, side="right") - 1, 0, len(seg) - 1)
    positions = corners[i] + (arc - cum[i])[:, None] * seg[i] / seg_len[i, None]
    velocity_task = seg[i] / seg_len[i, None] * (cum[-1] / duration_s)
    T = look_at(positions, positions - [0.0, 0.0, 1.0])
    v_cam = np.einsum("lji,lj->li", T[:, :3, :3], velocity_task)
    return Trajectory(T, times, "raster_scan", np.concatenate([v_cam, np.zeros_like(v_cam)], 1))


def waypoints(times_s: FloatList, n: Int = 50, poses: PoseList | None = None, positions: Vec3List | None = None,
              targets: OneOrMoreVec3 | None = None, up: Vec3 = (0.0, 0.0, 1.0)) -> Trajectory:
    """Interpolate K key poses at ``times_s`` (K,): linear in position, scipy ``Slerp`` in rotation.

    Key poses are ``poses`` (K, 4, 4) ``T_task_cam``, or ``positions`` (K, 3) with ``targets`` (K, 3, or
    one [x, y, z] for all) aimed by ``look_at``. The n samples are uniform over [t_0, t_K−1]. Screws are
    analytic: constant per segment (body ω = log(R_iᵀ R_i+1)/Δt_i, v = Rᵀ Δp/Δt_i); at a key time the
    outgoing segment's.
    """
    key_t = np.asarray(times_s, dtype=float)
    _check("waypoints", key_t.ndim == 1 and len(key_t) >= 2, "times_s needs at least 2 key times")
    _check("waypoints", bool(np.all(np.diff(key_t) > 0)), "times_s must increase strictly")
    keys = _key_poses(key_t, poses, positions, targets, up)
    times = _check_common("waypoints", n, float(key_t[-1] - key_t[0])) + key_t[0]
    times[-1] = key_t[-1]
    rot = Rotation.from_matrix(keys[:, :3, :3])
    R = Slerp(key_t, rot)(times).as_matrix()
    i = np.clip(np.searchsorted(key_t, times, side="right") - 1, 0, len(key_t) - 2)
    dt = np.diff(key_t)
    alpha = (times - key_t[i]) / dt[i]
    p_key = keys[:, :3, 3]
    p = p_key[i] + alpha[:, None] * (p_key[i + 1] - p_key[i])
    omega = ((rot[:-1].inv() * rot[1:]).as_rotvec() / dt[:, None])[i]
    v_task = (np.diff(p_key, axis=0) / dt[:, None])[i]
    v_cam = np.einsum("lji,lj->li", R, v_task)
    return Trajectory(make_T(R, p), times, "waypoints", np.concatenate([v_cam, omega], 1))


def _key_poses(key_t: np.ndarray, poses: ArrayLike | None, positions: ArrayLike | None,
               targets: ArrayLike | None, up: ArrayLike) -> np.ndarray:
    K = len(key_t)
    if poses is not None:
        _check("waypoints", positions is None and targets is None, "give poses or positions + targets, not both")
        keys = np.asarray(poses, dtype=float)
        _check("waypoints", keys.shape == (K, 4, 4), f"poses must have shape ({K}, 4, 4) like times_s")
        return _validate_poses(keys, "waypoints: poses")
    _check("waypoints", positions is not None and targets is not None, "needs poses, or positions and targets")
    pos = np.asarray(positions, dtype=float)
    tgt = np.broadcast_to(np.asarray(targets, dtype=float), pos.shape) if np.ndim(targets) == 1 else \
        np.asarray(targets, dtype=float)
    _check("waypoints", pos.shape == (K, 3) and tgt.shape == (K, 3),
           f"positions and targets must have shape ({K}, 3) like times_s")
    _check("waypoints", bool(np.all(np.linalg.norm(tgt - pos, axis=1) > 0)), "a position equals its target")
    return look_at(pos, tgt, up)


#: The parametric trajectories a study file can name with ``kind``.
TRAJECTORY_KINDS: dict[str, Callable[..., Trajectory]] = {
    "straight_approach": straight_approach,
    "orbit_arc": orbit_arc,
    "helical_approach": helical_approach,
    "raster_scan": raster_scan,
    "waypoints": waypoints,
}


@dataclass(frozen=True)
class KindArgument:
    """One argument of a library kind: name, type text, whether required, default."""

    name: str
    arg_type: ArgType
    required: bool
    default: Any


def kind_arguments(kind: str) -> list[KindArgument]:
    """The arguments of a library kind, from its signature and ``Annotated`` argument types."""
    func = TRAJECTORY_KINDS[kind]
    hints = typing.get_type_hints(func, include_extras=True)
    args = []
    for p in inspect.signature(func).parameters.values():
        hint = hints[p.name]
        if typing.get_origin(hint) in (typing.Union, types.UnionType):
            hint = next(h for h in typing.get_args(hint) if h is not type(None))
        arg_type = next(m for m in hint.__metadata__ if isinstance(m, ArgType))
        required = p.default is inspect.Parameter.empty
        args.append(KindArgument(p.name, arg_type, required, None if required else p.default))
    return args


# ---------------------------------------------------------------------- study-file tables
def trajectory_from_dict(spec: Mapping[str, Any], origin: str = "trajectory",
                         base_dir: str | Path | None = None) -> Trajectory:
    """Build a trajectory from plain data: ``{"kind": name, **arguments}`` or ``{"csv": path}``.

    Either form may add ``name``. ``origin`` names the source (e.g. ``"study.toml [trajectory]"``) in
    error messages; a relative CSV path is resolved against ``base_dir`` (the study file's folder).
    Raises one ``TrajectoryError`` naming origin, key and the allowed values.
    """
    if not isinstance(spec, Mapping):
        raise TrajectoryError(f"{origin}: expected a table with 'kind' or 'csv', got {type(spec).__name__}")
    spec = dict(spec)
    name = spec.pop("name", None)
    if name is not None and not isinstance(name, str):
        raise TrajectoryError(f"{origin}: name: expected a string, got {name!r}")
    if ("kind" in spec) == ("csv" in spec):
        raise TrajectoryError(f"{origin}: give exactly one of 'kind' (one of {', '.join(TRAJECTORY_KINDS)}) "
                              f"or 'csv' (a CSV file of poses)")
    if "csv" in spec:
        traj = _from_csv_spec(spec, origin, base_dir)
    else:
        traj = _from_kind_spec(spec, origin)
    return traj if name is None else Trajectory(traj.T_task_cam, traj.times_s, name, traj.screws)


def _from_csv_spec(spec: dict[str, Any], origin: str, base_dir: str | Path | None) -> Trajectory:
    extra = sorted(set(spec) - {"csv"})
    if extra:
        raise TrajectoryError(f"{origin}: unknown key(s) {', '.join(extra)} with 'csv'; allowed: csv, name")
    if not isinstance(spec["csv"], str | Path):
        raise TrajectoryError(f"{origin}: csv: expected a file path, got {spec['csv']!r}")
    path = Path(spec["csv"])
    if base_dir is not None and not path.is_absolute():
        path = Path(base_dir) / path
    try:
        return read_csv(path)
    except TrajectoryError as exc:
        raise TrajectoryError(f"{origin}: csv: {exc}") from exc


def _from_kind_spec(spec: dict[str, Any], origin: str) -> Trajectory:
    kind = spec.pop("kind")
    if not isinstance(kind, str) or kind not in TRAJECTORY_KINDS:
        raise TrajectoryError(f"{origin}: kind: unknown trajectory kind {kind!r}; "
                              f"allowed: {', '.join(TRAJECTORY_KINDS)}")
    args = kind_arguments(kind)
    allowed = ", ".join(a.name for a in args)
    unknown = sorted(set(spec) - {a.name for a in args})
    if unknown:
        raise TrajectoryError(f"{origin}: unknown key(s) {', '.join(unknown)} for kind '{kind}'; "
                              f"allowed: kind, name, {allowed}")
    missing = [a.name for a in args if a.required and a.name not in spec]
    if missing:
        raise TrajectoryError(f"{origin}: kind '{kind}' needs {', '.join(missing)}; arguments: {allowed}")
    values = {}
    for a in args:
        if a.name in spec:
            try:
                values[a.name] = a.arg_type.convert(spec[a.name])
            except TypeError as exc:
                raise TrajectoryError(f"{origin}: {a.name}: {exc}, got {spec[a.name]!r}; "
                                      f"allowed: {a.arg_type.description}") from exc
    try:
        return TRAJECTORY_KINDS[kind](**values)
    except CadfeatError as exc:
        raise TrajectoryError(f"{origin}: {exc}") from exc


# ---------------------------------------------------------------------- CSV
POSITION_COLUMNS = ("time_s", "x_mm", "y_mm", "z_mm")
QUATERNION_COLUMNS = ("qx", "qy", "qz", "qw")
ROTVEC_COLUMNS = ("rx_rad", "ry_rad", "rz_rad")
SCREW_COLUMNS = ("vx_mm_s", "vy_mm_s", "vz_mm_s", "wx_rad_s", "wy_rad_s", "wz_rad_s")
#: Accepted |‖q‖ − 1| of a CSV quaternion (it is then normalised).
QUATERNION_NORM_TOL = 1e-3
_HEADERS = {
    "quaternion": POSITION_COLUMNS + QUATERNION_COLUMNS,
    "rotvec": POSITION_COLUMNS + ROTVEC_COLUMNS,
}


def write_csv(traj: Trajectory, path: str | Path, rotation: str = "quaternion",
              include_screws: bool = False) -> None:
    """Write ``traj`` as CSV (format in the module docstring); ``rotation`` is "quaternion" or "rotvec".

    ``include_screws`` appends the velocity screws (analytic, or numeric when the trajectory has none).
    Numbers are written with 17 significant digits, so a read-back is exact to rounding.
    """
    if rotation not in _HEADERS:
        raise TrajectoryError(f"write_csv: rotation must be one of {', '.join(_HEADERS)}, got {rotation!r}")
    rot = Rotation.from_matrix(traj.rotations)
    cols = [traj.times_s[:, None], traj.positions, rot.as_quat() if rotation == "quaternion" else rot.as_rotvec()]
    header = _HEADERS[rotation]
    if include_screws:
        cols.append(traj.velocity_screws())
        header = header + SCREW_COLUMNS
    table = np.concatenate(cols, axis=1)
    with open(path, "w", newline="") as fh:
        fh.write(f"# cadfeat trajectory {traj.name!r}: camera poses T_task_cam (mm, task frame)\n")
        fh.write(",".join(header) + "\n")
        for row in table:
            fh.write(",".join(f"{v:.17g}" for v in row) + "\n")


def read_csv(path: str | Path, name: str | None = None) -> Trajectory:
    """Read a CSV trajectory (format in the module docstring); ``name`` defaults to the file stem.

    Errors name the file, the line and the column.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise TrajectoryError(f"{path}: cannot read trajectory CSV ({exc.strerror or exc})") from exc
    rows = [(i + 1, r) for i, r in enumerate(csv.reader(text.splitlines()))
            if r and "".join(r).strip() and not r[0].lstrip().startswith("#")]
    if not rows:
        raise TrajectoryError(f"{path}: empty trajectory CSV; first line must be a header: "
                              f"{_allowed_headers()}")
    header_line, header = rows[0]
    columns = tuple(c.strip() for c in header)
    base = next((k for k, h in _HEADERS.items() if columns in (h, h + SCREW_COLUMNS)), None)
    if base is None:
        raise TrajectoryError(f"{path}: line {header_line}: unknown header {','.join(columns)!r}; "
                              f"allowed: {_allowed_headers()}")
    table = _parse_rows(path, rows[1:], columns)
    if len(table) < 2:
        raise TrajectoryError(f"{path}: needs at least 2 samples, got {len(table)}")
    lines = [ln for ln, _ in rows[1:]]
    _check_csv_times(path, table[:, 0], lines)
    n_rot = len(QUATERNION_COLUMNS) if base == "quaternion" else len(ROTVEC_COLUMNS)
    rot_values = table[:, 4:4 + n_rot]
    if base == "quaternion":
        rot = _csv_quaternions(path, rot_values, lines)
    else:
        rot = Rotation.from_rotvec(rot_values)
    screws = table[:, 4 + n_rot:] if len(columns) > 4 + n_rot else None
    return Trajectory(make_T(rot.as_matrix(), table[:, 1:4]), table[:, 0], name or path.stem, screws)


def _allowed_headers() -> str:
    return " or ".join(repr(",".join(h)) for h in _HEADERS.values()) + \
        f" (optionally followed by {','.join(SCREW_COLUMNS)})"


def _parse_rows(path: Path, rows: list[tuple[int, list[str]]], columns: tuple[str, ...]) -> np.ndarray:
    table = np.empty((len(rows), len(columns)))
    for r, (line, fields) in enumerate(rows):
        if len(fields) != len(columns):
            raise TrajectoryError(f"{path}: line {line}: expected {len(columns)} columns "
                                  f"({','.join(columns)}), got {len(fields)}")
        for c, field in enumerate(fields):
            try:
                value = float(field)
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise TrajectoryError(f"{path}: line {line}, column {c + 1} ({columns[c]}): "
                                      f"expected a finite number, got {field.strip()!r}")
            table[r, c] = value
    return table


def _check_csv_times(path: Path, t: np.ndarray, lines: list[int]) -> None:
    bad = np.diff(t) <= 0
    if np.any(bad):
        k = int(np.argmax(bad)) + 1
        raise TrajectoryError(f"{path}: line {lines[k]}, column 1 (time_s): times must increase strictly "
                              f"({t[k]:g} s after {t[k - 1]:g} s)")


def _csv_quaternions(path: Path, q: np.ndarray, lines: list[int]) -> Rotation:
    norm = np.linalg.norm(q, axis=1)
    bad = np.abs(norm - 1.0) > QUATERNION_NORM_TOL
    if np.any(bad):
        k = int(np.argmax(bad))
        raise TrajectoryError(f"{path}: line {lines[k]}, columns 5-8 (qx,qy,qz,qw): quaternion norm "
                              f"{norm[k]:.6g}; expected a unit quaternion (±{QUATERNION_NORM_TOL:g})")
    return Rotation.from_quat(q / norm[:, None])
