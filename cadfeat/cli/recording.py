"""Sub-command ``cadfeat plan-recording STUDY --out DIR``: what to send the robot and print before recording the
real part in the user's cell, and the steps from calibration to replay.

Writes into DIR: ``poses.csv`` (the study's trajectory, camera poses T_task_cam: ``time_s,x_mm,y_mm,z_mm,qx,qy,qz,qw``
— the format ``cadfeat track --poses`` reads back), ``poses_4x4.csv`` (time, then the 4x4 matrix row by row),
``board.pdf`` (the calibration board at 1:1, square size printed, a 100 mm check line) and ``checklist.md``
(calibrate, hand-eye, lighting as the study's ``[cell]``, record, replay).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.cli.command import Command

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.calibration.boards import BoardSpec
    from cadfeat.study.recorded import RecordedData
    from cadfeat.study.schema import StudyConfig, TrackingSpec

#: Decimals of the poses written (mm and quaternion components; 1 µm, ~1e-6 rad: below any robot's repeatability).
POSE_DECIMALS = 6
DESIGNS = ("original", "optimised")


def _plan_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("study", metavar="STUDY", help="study file (TOML)")
    parser.add_argument("--out", metavar="DIR", required=True, help="folder for poses, board and checklist")
    parser.add_argument("--design", choices=DESIGNS, default="optimised", help="the part design to record "
                        "(its STEP from `cadfeat run`; default optimised)")
    parser.add_argument("--board", choices=("chessboard", "charuco"), default="charuco", help="board to print")
    parser.add_argument("--inner-corners", metavar="COLSxROWS", default="9x6", help="the board's inner corners")
    parser.add_argument("--square-mm", type=float, default=20.0, metavar="MM", help="square side (default 20 mm)")


def write_pose_files(T_task_cam: np.ndarray, times_s: np.ndarray, folder: Path) -> tuple[Path, Path]:
    """``poses.csv`` (time, position mm, quaternion x y z w) and ``poses_4x4.csv`` (time, 16 numbers row-major) of
    the camera poses (L, 4, 4) at times (L,) s, with ``POSE_DECIMALS`` decimals."""
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(T_task_cam[:, :3, :3]).as_quat()
    q *= np.where(q[:, 3:] < 0, -1.0, 1.0)  # w >= 0: one sign per rotation
    quat = np.column_stack([times_s, T_task_cam[:, :3, 3], q])
    mats = np.column_stack([times_s, T_task_cam.reshape(len(T_task_cam), 16)])
    fmt = f"%.{POSE_DECIMALS}f"
    csv = folder / "poses.csv"
    np.savetxt(csv, quat, fmt=fmt, delimiter=",", header="time_s,x_mm,y_mm,z_mm,qx,qy,qz,qw", comments="")
    four = folder / "poses_4x4.csv"
    head = "time_s," + ",".join(f"T{i}{j}" for i in range(4) for j in range(4))
    np.savetxt(four, mats, fmt=fmt, delimiter=",", header=head, comments="")
    return csv, four


def checklist(config: StudyConfig, args: argparse.Namespace, board: BoardSpec, paper: str, n_poses: int,
              duration_s: float) -> str:
    """The recording checklist (markdown) for the study ``config``."""
    cam, cell = config.camera.build(), config.cell
    light = cell.light
    study = config.file.name if config.file is not None else "STUDY.toml"
    corners = f"--board {board.kind} --inner-corners {board.cols}x{board.rows} --square-mm {board.square_mm:g}" + (
        f" --marker-mm {board.marker_mm:g}" if board.kind == "charuco" else "")
    return f"""# Recording checklist: {config.study.name} ({args.design} design)

1. **Calibrate the camera.** Print `board.pdf` on {paper} at 100 % (actual size); measure the 100 mm line and a
   square, and use what you measure. Glue it flat. Take 15-25 images with the board tilted 20-45 deg about different
   axes, covering the whole image, the corners included, at the working distance and focus, then run
   `cadfeat calibrate IMAGES... {corners} --f-number {cam.f_number:g} --focus-mm {cam.focus_distance_mm:g}
   --focal-length-mm {cam.focal_length_mm:g} --out camera.yaml` (the lens values are the study's; use your lens's).
   Check the reprojection RMS (< 0.3 px is good), the warnings (uncovered corners) and the rejected images; then set
   `[camera] calibration = "camera.yaml"` in the study. The study assumes {cam.width}x{cam.height} px,
   fx = {cam.fx:.1f} px.
2. **Hand-eye.** The robot reports its flange; the camera sits at T_flange_cam. Calibrate it (e.g. OpenCV's
   `cv2.calibrateHandEye` with board views) and save it as a 4x4 matrix (`T.yaml`, FileStorage node `T`).
   Send the robot the flange poses T_task_flange = T_task_cam · T_flange_cam⁻¹ of `poses.csv`, or set the camera
   as its tool frame. The study's `[cell]` assumes the mount known to ±{_fmt(cell.camera_position_mm)} mm /
   ±{_fmt(cell.camera_angle_deg)} deg and the part placed to ±{_fmt(cell.placement_position_mm)} mm /
   ±{_fmt(cell.placement_angle_deg)} deg.
3. **Lighting and part as the study's `[cell]`.** Light: {light.kind}; part: {cell.material.name}
   ({args.design} design: `{args.design}.step` from `cadfeat run`); hole ends {cell.hole_ends}. Expose so the
   part's median grey is mid-scale without clipping; the study assumes sensor noise σ {cell.noise_sigma_grey:g}
   grey levels.
4. **Record.** Send `poses.csv` ({n_poses} poses over {duration_s:.2f} s; `poses_4x4.csv` is the same as
   matrices, in the study's task frame: place the part at its `[part_pose]`). For each image save
   `frame_NNNN.png` (NNNN = the pose's row, from 0000; PNG/TIFF 8 or 16 bit, or JPEG) and log the pose the robot
   reports at the exposure: one CSV line `time_s,x_mm,y_mm,z_mm,qx,qy,qz,qw` (or time and 12 numbers of a 3x4
   matrix) per image, in the order of the frames.
5. **Replay.** `cadfeat track {study} --images DIR --poses reported.csv [--hand-eye T.yaml] --design {args.design}`
   reports the pose error per frame against the robot's poses (the robot's accuracy is the reference's, not truth),
   each hole's detection rate, the filter's consistency (NEES) and cadfeat's prediction for the same poses.
"""


def _fmt(value: float | Sequence[float]) -> str:
    return ", ".join(f"{v:g}" for v in np.atleast_1d(np.asarray(value, dtype=float)))


def plan_recording(args: argparse.Namespace) -> int:
    """Write the robot's poses, the board to print and the recording checklist for a study."""
    from cadfeat.calibration import BoardSpec, parse_corners
    from cadfeat.calibration.printable import board_pdf
    from cadfeat.study.schema import load_study

    config = load_study(args.study)
    trajectory = config.trajectory.build()
    cols, rows = parse_corners(args.inner_corners)
    board = BoardSpec(args.board, cols, rows, args.square_mm)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    csv, four = write_pose_files(np.asarray(trajectory.T_task_cam), np.asarray(trajectory.times_s), out)
    paper, _, _ = board_pdf(board, out / "board.pdf")
    text = checklist(config, args, board, paper, len(trajectory), float(trajectory.duration_s))
    (out / "checklist.md").write_text(text, encoding="utf-8")
    print(f"plan-recording {config.study.name} ({args.design}): {len(trajectory)} poses; board {board.describe()} "
          f"on {paper}")
    print(f"  outputs: {csv}, {four}, {out / 'board.pdf'}, {out / 'checklist.md'}")
    return 0


def track_recorded(config: StudyConfig, spec: TrackingSpec, out: Path, args: argparse.Namespace) -> int:
    """``cadfeat track STUDY --images DIR --poses CSV``: replay a recording (``study.recorded``); writes
    ``tracking/recorded_<design>.json`` in the study's output folder and prints the summary."""
    from cadfeat.errors import CadfeatError
    from cadfeat.study.outputs import write_json
    from cadfeat.study.recorded import track_recording

    if not (args.images and args.poses):
        raise CadfeatError("--images and --poses go together; allowed: both (a folder of frame images and the CSV of "
                           "the robot's poses per image)")
    section = track_recording(config, out, Path(args.images), Path(args.poses),
                              Path(args.hand_eye) if args.hand_eye else None, args.design, spec)
    folder = out / "tracking"
    folder.mkdir(parents=True, exist_ok=True)
    path = write_json(folder / f"recorded_{args.design}.json", section)
    print("\n".join(recorded_lines(section)))
    print(f"  outputs: {path}")
    return 0


def recorded_lines(section: RecordedData) -> list[str]:
    """Console summary of a replayed recording: measured vs predicted, NEES, detection rates, problems."""
    p = section["predicted"]
    lines = [f"recorded {section['design']} design: {section['frames_used']} of {section['poses_parsed']} poses "
             f"with an image used; reference: {section['reference']}",
             f"  predicted (cadfeat, these poses): translation RMS {_g(p['trans_mm_rms'])} mm, rotation RMS "
             f"{_g(p['rot_deg_rms'])} deg"]
    for m, s in section["measured"].items():
        lines.append(f"  measured {m:<4}: translation RMS {_g(s['trans_mm_rms'])} mm, rotation RMS "
                     f"{_g(s['rot_deg_rms'])} deg, {s['frames_lost']} lost; NEES {_g(s['nees_mean'])} (6 expected, "
                     f"95 % [{s['nees_95'][0]:.2f}, {s['nees_95'][1]:.2f}]: {s['consistency']}; "
                     f"{_g(s['nees_filter_only_mean'])} with the reference taken as exact)")
    for name, rate in section["detection_rate"].items():
        lines.append(f"  {name}: detected {_g(rate)} (predicted {_g(section['predicted_detection'][name])})")
    lines += [f"  problem: {q}" for q in section["problems"]]
    return lines


def _g(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.3g}"


COMMANDS = (Command("plan-recording", _plan_args, plan_recording),)
