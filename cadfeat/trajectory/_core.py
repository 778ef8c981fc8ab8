"""The ``Trajectory`` (camera poses T_task_cam, times, velocity screws; thesis §4.2.1) and its input checks."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.errors import CadfeatError
from cadfeat.poses import invert_T, rotation_error, twist_between

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
