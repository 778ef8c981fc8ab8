"""Camera calibration in the user's own cell (the thesis's Appendix A): boards, the solve with its error analysis,
calibration files (OpenCV and ROS) and the calibration figure. ``cadfeat calibrate`` is the command."""

from __future__ import annotations

from cadfeat.calibration.boards import BOARD_KINDS, BoardError, BoardSpec, parse_corners
from cadfeat.calibration.files import read_camera, read_ros, write_opencv, write_ros
from cadfeat.calibration.solve import (
    MIN_NORMAL_SPREAD_DEG,
    MIN_VIEWS,
    PARAMETERS,
    CalibrationError,
    CalibrationResult,
    Coverage,
    Rejected,
    View,
    calibrate,
    edge_displacement_px,
    image_coverage,
    normal_spread_deg,
)

__all__ = [
    "BOARD_KINDS", "MIN_NORMAL_SPREAD_DEG", "MIN_VIEWS", "PARAMETERS", "BoardError", "BoardSpec", "CalibrationError",
    "CalibrationResult", "Coverage", "Rejected", "View", "calibrate", "edge_displacement_px", "image_coverage",
    "normal_spread_deg", "parse_corners", "read_camera", "read_ros", "write_opencv", "write_ros",
]
