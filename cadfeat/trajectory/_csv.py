"""Trajectory CSV files: ``write_csv`` / ``read_csv`` (format: the package docstring)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from cadfeat.poses import make_T
from cadfeat.trajectory._core import (
    Trajectory,
    TrajectoryError,
)

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
