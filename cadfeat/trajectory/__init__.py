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

The package: ``_core`` (the ``Trajectory`` class and its checks), ``_library`` (the parametric kinds and their
argument types), ``_csv`` (CSV files), ``_tables`` (the ``[trajectory]`` models, generated from the kinds'
signatures); everything public is re-exported here.
"""

from __future__ import annotations

from cadfeat.trajectory._core import ROTATION_TOL, Trajectory, TrajectoryError, numerical_velocity_screws
from cadfeat.trajectory._csv import (
    POSITION_COLUMNS,
    QUATERNION_COLUMNS,
    QUATERNION_NORM_TOL,
    ROTVEC_COLUMNS,
    SCREW_COLUMNS,
    read_csv,
    write_csv,
)
from cadfeat.trajectory._library import (
    TRAJECTORY_KINDS,
    ArgType,
    Float,
    FloatList,
    Int,
    KindArgument,
    OneOrMoreVec3,
    PoseList,
    Vec3,
    Vec3List,
    helical_approach,
    kind_arguments,
    orbit_arc,
    raster_scan,
    straight_approach,
    waypoints,
)
from cadfeat.trajectory._tables import (
    CsvTrajectory,
    TrajectorySettings,
    trajectory_from_dict,
    trajectory_model,
    validate_trajectory,
)

__all__ = [
    "ArgType", "CsvTrajectory", "Float", "FloatList", "Int", "KindArgument", "OneOrMoreVec3", "POSITION_COLUMNS",
    "PoseList", "QUATERNION_COLUMNS", "QUATERNION_NORM_TOL", "ROTATION_TOL", "ROTVEC_COLUMNS", "SCREW_COLUMNS",
    "TRAJECTORY_KINDS", "Trajectory", "TrajectoryError", "TrajectorySettings", "Vec3", "Vec3List", "helical_approach",
    "kind_arguments", "numerical_velocity_screws", "orbit_arc", "raster_scan", "read_csv", "straight_approach",
    "trajectory_from_dict", "trajectory_model", "validate_trajectory", "waypoints", "write_csv",
]
