"""Sub-command ``cadfeat calibrate IMAGES…``: the camera's intrinsics and distortion from board images (thesis
Appendix A), with the error analysis, written where a study's ``[camera] calibration = …`` reads them.

Writes the OpenCV FileStorage YAML ``--out`` (``image_width``, ``image_height``, ``camera_matrix``,
``distortion_coefficients``, plus the error analysis and optics as extra nodes), beside it ``<stem>_calibration.png``
(per-image error, residuals, coverage) and ``<stem>_report.json``, and with ``--ros`` a ROS ``camera_info`` YAML.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from cadfeat.cli.command import Command
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.calibration.solve import CalibrationReport

BOARD_CHOICES = ("chessboard", "charuco")


def _calibrate_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("images", metavar="IMAGES", nargs="+", help="board images (PNG/JPEG/TIFF/PGM, 8 or 16 bit) or "
                        "folders of them")
    parser.add_argument("--board", choices=BOARD_CHOICES, default="chessboard", help="the board printed")
    parser.add_argument("--inner-corners", metavar="COLSxROWS", default="9x6",
                        help="inner corners across and down (a 9x6 board has 10x7 squares; default 9x6)")
    parser.add_argument("--square-mm", type=float, required=True, metavar="MM", help="square side as printed, mm")
    parser.add_argument("--marker-mm", type=float, metavar="MM",
                        help="charuco: marker side, mm (default half the square)")
    parser.add_argument("--dictionary", default="DICT_4X4_250", metavar="NAME",
                        help="charuco: the ArUco dictionary (cv2.aruco DICT_* name; default DICT_4X4_250)")
    parser.add_argument("--fix-k3", action="store_true", help="keep k3 = 0 (Bouguet's default, the thesis's Table "
                        "A.1); use when the boards do not reach the image corners")
    parser.add_argument("--out", metavar="FILE", default="camera.yaml",
                        help="the calibration (OpenCV YAML/XML/JSON by extension; default camera.yaml)")
    parser.add_argument("--ros", metavar="FILE", help="also write a ROS camera_info YAML")
    parser.add_argument("--focal-length-mm", type=float, metavar="MM", help="the lens's focal length (focus measure)")
    parser.add_argument("--f-number", type=float, metavar="N", help="the lens's aperture f-number (focus measure)")
    parser.add_argument("--focus-mm", type=float, metavar="MM", help="the distance the lens is focused at, mm")


def _optics(args: argparse.Namespace) -> dict[str, float]:
    out = {}
    for key, value in (("focal_length_mm", args.focal_length_mm), ("f_number", args.f_number),
                       ("focus_distance_mm", args.focus_mm)):
        if value is not None:
            if not value > 0:
                raise CadfeatError(f"--{key.replace('_distance', '').replace('_', '-')}: {value} is not allowed; "
                                   "allowed: a number > 0")
            out[key] = float(value)
    return out


def calibrate(args: argparse.Namespace) -> int:
    """Calibrate the camera from board images: intrinsics, distortion, their uncertainty and coverage."""
    from cadfeat.calibration import BoardSpec, parse_corners, write_opencv, write_ros
    from cadfeat.calibration import calibrate as solve
    from cadfeat.calibration.plot import calibration_plot
    from cadfeat.study.outputs import write_json
    from cadfeat.vision.image_files import expand_image_paths

    cols, rows = parse_corners(args.inner_corners)
    board = BoardSpec(args.board, cols, rows, args.square_mm, args.marker_mm, args.dictionary)
    optics = _optics(args)
    paths = expand_image_paths(args.images)
    if not paths:
        raise CadfeatError(f"IMAGES: no image files in {', '.join(args.images)}; allowed: PNG, JPEG, TIFF or PGM files")
    result = solve(paths, board, fix_k3=args.fix_k3, optics=optics)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_opencv(result, out, optics)
    plot = calibration_plot(result, out.with_name(out.stem + "_calibration.png"))
    report = out.with_name(out.stem + "_report.json")
    write_json(report, result.to_json())
    if args.ros:
        write_ros(result.camera, args.ros)
    print("\n".join(summary_lines(result.to_json())))
    print(f"  outputs: {out}, {plot}, {report}" + (f", {args.ros}" if args.ros else ""))
    return 0


def summary_lines(report: CalibrationReport) -> list[str]:
    """The console summary of a calibration report (``CalibrationResult.to_json``)."""
    lines = [f"calibration: {report['board']}; {len(report['views'])} images used, {len(report['rejected'])} "
             f"rejected; reprojection RMS {report['rms_px']:.3f} px"]
    for name, p in report["parameters"].items():
        lines.append(f"  {name:<3} = {p['value']:>12.6g} ± {p['std']:.3g} (1 sigma)")
    lines.append(f"  distortion at the image edge: up to {report['edge_distortion_px']:.1f} px; board normals spread "
                 f"{report['normal_spread_deg']:.0f} deg; coverage {report['coverage']['grid_fraction']:.0%} of the "
                 f"image, {report['coverage']['radius_fraction']:.0%} of the corner radius")
    for v in report["views"]:
        lines.append(f"  {Path(v['image']).name}: RMS {v['rms_px']:.3f} px, {v['corners']} corners, tilt "
                     f"{v['tilt_deg']:.0f} deg")
    for r in report["rejected"]:
        lines.append(f"  rejected {Path(r['image']).name}: {r['reason']}")
    lines += [f"  warning: {w}" for w in report["warnings"]]
    return lines


COMMANDS = (Command("calibrate", _calibrate_args, calibrate),)
