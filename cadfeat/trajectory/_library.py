"""The parametric trajectory library (``TRAJECTORY_KINDS``) and the argument types a study file gives them."""

from __future__ import annotations

import inspect
import types
import typing
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated

import numpy as np
from numpy.typing import ArrayLike
from pydantic import Field
from scipy.spatial.transform import Rotation, Slerp

from cadfeat.poses import look_at, look_at_screws, make_T
from cadfeat.settings import Finite, Tuple
from cadfeat.trajectory._core import (
    Trajectory,
    TrajectoryError,
    _validate_poses,
)


# ---------------------------------------------------------------------- argument types of library kinds
@dataclass(frozen=True)
class ArgType:
    """How a study file gives a library-trajectory argument: its text (``cadfeat trajectories``, error messages)
    and its pydantic type (strict: a string is not a number, a float not an integer; arrays are TOML arrays),
    which ``cadfeat.trajectory.TrajectorySettings`` validates. ``array``: passed on as a float array."""

    description: str
    annotation: object
    """A runtime type (for pydantic), not an annotation of this module."""
    array: bool = False


def _shape(inner: object, n: int | None = None) -> object:
    """A TOML array of ``inner`` (a tuple), of exactly ``n`` items when ``n`` is given."""
    return Annotated[Tuple[inner], Field(min_length=n, max_length=n)] if n else Tuple[inner]


_VEC3 = _shape(Finite, 3)
_VEC3_LIST = _shape(_VEC3)

Float = Annotated[float, ArgType("number", Finite)]
Int = Annotated[int, ArgType("integer", int)]
Vec3 = Annotated[ArrayLike, ArgType("[x, y, z] (3 numbers)", _VEC3, True)]
Vec3List = Annotated[ArrayLike, ArgType("list of [x, y, z]", _VEC3_LIST, True)]
FloatList = Annotated[ArrayLike, ArgType("list of numbers", _shape(Finite), True)]
OneOrMoreVec3 = Annotated[ArrayLike, ArgType("[x, y, z] or list of [x, y, z]", _VEC3 | _VEC3_LIST, True)]
PoseList = Annotated[ArrayLike, ArgType("list of 4x4 matrices", _shape(_shape(_shape(Finite, 4), 4)), True)]


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
    default: object


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
