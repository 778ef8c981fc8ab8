"""Benchmark: the user's own cell (issue 30) — ``cadfeat calibrate`` and ``cadfeat track --images --poses``.

Calibration: 20 chessboard images of 1280×1024 (9×6 inner corners, 25 mm squares) rendered exactly through a
known lens (``tests/board_render.py``: per sub-pixel ray tracing through OpenCV's model, fx 1667, k1 −0.12) and
calibrated from the files by ``cadfeat.calibration.calibrate`` (read, find the board, refine, solve, error analysis)
and by the whole ``cadfeat calibrate`` command (plus the YAML, the report and the figure). Baselines measured in
the same run on the same files: OpenCV's own sample pipeline (``imread``, ``findChessboardCorners``,
``cornerSubPix`` 11×11, ``calibrateCamera``) and ``cv2.calibrateCamera`` alone on those corners. OpenCV's real
sample photographs (``tests/data/opencv_left``, 13 × 640×480) are timed the same way.

Replay: the flagship study (NEMA 17 mount, Basler 1280×1024) along its arc resampled to 200 poses; the optimised
(a fixed example) design's frames rendered by the closed loop (``observe``, ``frame_image``) and written as a cell
logs them (PNG per frame, ``poses.csv`` to 6 decimals); ``cadfeat track STUDY --images --poses`` replays them
(read, detect with the predicted rims as prior, associate, EKF/IEKF/PnP, NEES, the prediction at those poses).
Per-frame time of the whole command and of its parts; the baseline is the closed loop's own detection of the same
frames in memory (``detect_sequence``: the image made and searched, no file).
"""

from __future__ import annotations

import contextlib
import io
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT / "tests"))

from benchutil import load as _load
from benchutil import median_s as _median_s
from benchutil import save_section

SIZE = (1280, 1024)
VIEWS = 20
FRAMES = 200
#: The flagship's fixed example redesign (as bench_vision): both target holes moved and enlarged.
AFTER = {"target_face_x_mm": 30.0, "target_face_z_mm": 12.0, "target_base_x_mm": 14.0, "target_base_y_mm": 63.0,
         "target_radius_mm": 3.0}


def _opencv_pipeline(paths: list[Path], pattern: tuple[int, int], square_mm: float):
    """OpenCV's sample calibration (the baseline): (total s, calibrateCamera s, rms px, K)."""
    import cv2
    import numpy as np

    start = time.perf_counter()
    board = np.zeros((pattern[0] * pattern[1], 3), np.float32)
    board[:, :2] = np.mgrid[0:pattern[0], 0:pattern[1]].T.reshape(-1, 2) * square_mm
    corners, size = [], None
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.001)
    for p in paths:
        grey = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
        size = grey.shape[::-1]
        found, c = cv2.findChessboardCorners(grey, pattern)
        if found:
            corners.append(cv2.cornerSubPix(grey, c, (11, 11), (-1, -1), criteria))
    solve_start = time.perf_counter()
    rms, K, _, _, _ = cv2.calibrateCamera([board] * len(corners), corners, size, None, None)
    end = time.perf_counter()
    return end - start, end - solve_start, float(rms), K


def _calibration_rows(folder: Path, quick: bool) -> tuple[list[tuple[str, ...]], str]:
    import cv2
    import numpy as np
    from board_render import random_poses, ray_map, render

    from cadfeat.calibration import BoardSpec, calibrate
    from cadfeat.camera import Camera
    from cadfeat.cli import main as cli

    truth = Camera(fx=1667.0, fy=1667.0, cx=645.0, cy=508.0, width=SIZE[0], height=SIZE[1],
                   dist=(-0.12, 0.08, 0.0005, -0.0003, 0.0), name="truth")
    board = BoardSpec("chessboard", 9, 6, 25.0)
    start = time.perf_counter()
    rays = ray_map(truth.K, truth.dist_coeffs, SIZE)
    poses = random_poses(truth.K, truth.dist_coeffs, SIZE, board.size_mm, VIEWS, seed=1, distance_mm=(500, 900))
    tex = board.board_image(100)
    paths = []
    for k, (r, t) in enumerate(poses):
        paths.append(folder / f"board_{k:02d}.png")
        cv2.imwrite(str(paths[-1]), render(rays, tex, board.square_mm, 100, r, t, seed=k))
    del rays
    render_s = time.perf_counter() - start
    repeats = 1 if quick else 3
    result = calibrate(paths, board)
    ours = _median_s(lambda: calibrate(paths, board), repeats)
    with contextlib.redirect_stdout(io.StringIO()):  # the command's report (its time is what counts here)
        cmd = _median_s(lambda: cli(["calibrate", *map(str, paths), "--square-mm", "25",
                                     "--out", str(folder / "camera.yaml")]), 1)
    base = [_opencv_pipeline(paths, (9, 6), 25.0) for _ in range(repeats)]
    base_total = float(np.median([b[0] for b in base]))
    base_solve = float(np.median([b[1] for b in base]))
    cam = result.camera
    rows = [
        (f"`calibrate()`, {VIEWS} × 1280×1024 chessboards", f"{ours:.2f} s", f"{1e3 * ours / VIEWS:.0f} ms",
         f"{ours / base_total:.2f}× OpenCV's pipeline, {ours / base_solve:.1f}× `calibrateCamera` alone"),
        ("`cadfeat calibrate` command (+ YAML, report, figure)", f"{cmd:.2f} s", f"{1e3 * cmd / VIEWS:.0f} ms",
         f"{cmd / base_total:.2f}× OpenCV's pipeline"),
        ("baseline: OpenCV's pipeline (findChessboardCorners, cornerSubPix 11×11, calibrateCamera)",
         f"{base_total:.2f} s", f"{1e3 * base_total / VIEWS:.0f} ms", "1"),
        ("baseline: `cv2.calibrateCamera` alone", f"{base_solve:.2f} s", f"{1e3 * base_solve / VIEWS:.0f} ms", "—"),
    ]
    real = sorted((ROOT / "tests" / "data" / "opencv_left").glob("left*.jpg"))
    real_result = calibrate(real, board)
    real_ours = _median_s(lambda: calibrate(real, board), repeats)
    real_base = [_opencv_pipeline(real, (9, 6), 25.0) for _ in range(repeats)]
    real_total = float(np.median([b[0] for b in real_base]))
    rows.append((f"`calibrate()`, OpenCV's {len(real)} real 640×480 photographs", f"{real_ours:.2f} s",
                 f"{1e3 * real_ours / len(real):.0f} ms", f"{real_ours / real_total:.2f}× OpenCV's pipeline "
                 f"({real_total:.2f} s)"))
    pp = float(np.hypot(cam.cx - truth.cx, cam.cy - truth.cy))
    accuracy = (f"Recovered (rendered set): fx {100 * (cam.fx / truth.fx - 1):+.3f} %, fy "
                f"{100 * (cam.fy / truth.fy - 1):+.3f} %, principal point {pp:.2f} px off, RMS {result.rms_px:.3f} px "
                f"(OpenCV's pipeline {base[0][2]:.3f} px, fx "
                f"{100 * (base[0][3][0, 0] / truth.fx - 1):+.3f} %). Real photographs: RMS {real_result.rms_px:.3f} px "
                f"(OpenCV's pipeline {real_base[0][2]:.3f} px). Rendering the 20 boards (not timed above): "
                f"{render_s:.0f} s.")
    return rows, accuracy


def _replay_rows(folder: Path) -> tuple[list[tuple[str, ...]], str]:
    import cv2
    from scipy.spatial.transform import Rotation

    from cadfeat.cad.export import export_step
    from cadfeat.cad.parts import load_part
    from cadfeat.cli import main as cli
    from cadfeat.poses import cam_from_part
    from cadfeat.study.schema import TrackingSpec, load_study
    from cadfeat.study.setup import load_scene
    from cadfeat.study.tracking import exported_designs
    from cadfeat.vision.closed_loop import detect_sequence, frame_image, observe

    text = (ROOT / "studies" / "nema17_mount.toml").read_text()
    text = text.replace('part = "../parts/nema17_mount.py"', f'part = "{ROOT / "parts" / "nema17_mount.py"}"')
    text = text.replace("n = 40\nduration_s = 4.0", f"n = {FRAMES}\nduration_s = {FRAMES / 10:.1f}")
    study = folder / "nema17_200.toml"
    study.write_text(text)
    out = folder / "out"
    out.mkdir()
    part = load_part(ROOT / "parts" / "nema17_mount.py")
    export_step(part.build(), out / "original.step")
    export_step(part.build(**AFTER), out / "optimised.step")
    config = load_study(study)
    shape, holes = exported_designs(config, out)["after"]
    camera, traj, T_task_part = load_scene(config)
    assert len(traj.times_s) == FRAMES
    T = cam_from_part(traj.T_task_cam, T_task_part)
    tc = (config.tracking or TrackingSpec()).in_cell(config.cell)
    start = time.perf_counter()
    obs = observe(shape, holes, camera, T, tc.sensor)
    render_s = time.perf_counter() - start
    images = folder / "rec"
    images.mkdir()
    start = time.perf_counter()
    for k in range(FRAMES):
        cv2.imwrite(str(images / f"frame_{k:04d}.png"), frame_image(camera, obs, k, tc.sensor.noise_grey, 5))
    write_s = time.perf_counter() - start
    q = Rotation.from_matrix(traj.T_task_cam[:, :3, :3]).as_quat()
    lines = ["time_s,x_mm,y_mm,z_mm,qx,qy,qz,qw"] + [
        ",".join(f"{v:.6f}" for v in (t, *p, *qk)) for t, p, qk in zip(traj.times_s, traj.T_task_cam[:, :3, 3], q,
                                                                       strict=True)]
    (folder / "poses.csv").write_text("\n".join(lines) + "\n")
    # the whole command, then its parts
    args = ["track", str(study), "--out", str(out), "--images", str(images), "--poses", str(folder / "poses.csv"),
            "--design", "optimised"]
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        assert cli(args) == 0
    total = time.perf_counter() - start
    parts = _replay_parts(config, out, images, folder / "poses.csv", tc)
    base = _median_s(lambda: detect_sequence(obs, tc.sensor.noise_grey, 5, tc.gate_px, 1.0, tc.detector), 1)
    rows = [(f"`cadfeat track --images --poses`, {FRAMES} frames 1280×1024, {'/'.join(tc.estimators)}",
             f"{total:.1f} s", f"{1e3 * total / FRAMES:.0f} ms", f"{total / base:.1f}×")]
    for name, seconds in parts.items():
        rows.append((f"  of which {name}", f"{seconds:.2f} s", f"{1e3 * seconds / FRAMES:.1f} ms",
                     f"{seconds / base:.2f}×"))
    rows.append(("baseline: the closed loop's detection of the same frames in memory (`detect_sequence`)",
                 f"{base:.2f} s", f"{1e3 * base / FRAMES:.1f} ms", "1"))
    note = (f"Making the recording (not timed above): rendering the {FRAMES} poses {render_s:.0f} s, writing the PNGs "
            f"{write_s:.1f} s ({sum(p.stat().st_size for p in images.iterdir()) / 1e6:.0f} MB).")
    return rows, note


def _replay_parts(config, out: Path, images: Path, poses: Path, tc) -> dict[str, float]:
    """The command's stages timed one by one (``study.recorded.track_recording``'s steps)."""
    import numpy as np

    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.poses import cam_from_part
    from cadfeat.study.pose_accuracy import predict
    from cadfeat.study.recorded import _exclusions
    from cadfeat.study.setup import load_scene
    from cadfeat.study.tracking import exported_designs
    from cadfeat.vision.estimate import estimate_poses
    from cadfeat.vision.image_files import read_grey
    from cadfeat.vision.replay import detect_frames, match_images, predicted_rims, read_reported_poses

    clock: dict[str, float] = {}

    def timed(name, func):
        start = time.perf_counter()
        value = func()
        clock[name] = clock.get(name, 0.0) + time.perf_counter() - start
        return value

    shape, holes = timed("loading the design (STEP) and scene", lambda: exported_designs(config, out)["after"])
    camera, _, T_task_part = timed("loading the design (STEP) and scene", lambda: load_scene(config))
    reported = timed("reading poses.csv, matching images", lambda: read_reported_poses(poses))
    files, _ = timed("reading poses.csv, matching images", lambda: match_images(images, reported.rows))
    T_ref = cam_from_part(reported.T, T_task_part)
    exclude, hidden, mesh = timed("rim occlusion at the reference poses", lambda: _exclusions(shape, list(holes),
                                                                                               camera, T_ref))
    timed("reading the images (PNG → grey)", lambda: [read_grey(p) for p in files if p is not None])
    c, n, r = holes_to_arrays(holes)
    predicted, _ = predicted_rims(camera, T_ref, c, n, r)
    pixels, used, _ = timed("detection + association (reading included)",
                            lambda: detect_frames(camera, files, predicted, tc.detector, tc.gate_px))
    pixels[exclude] = np.nan
    for m in tc.estimators:
        timed(f"estimation: {m}", lambda m=m: estimate_poses(
            camera, c, pixels, reported.times_s, m, T_ref[0], normals_part=n if tc.rim_model else None,
            radii_mm=r if tc.rim_model else None, tuning=tc.tuning))
    timed("prediction at the recorded poses (`pose_accuracy.predict`)", lambda: predict(
        camera, T_ref, holes, mesh, float(config.objective.pose_rotation_length_mm), occlusion=hidden,
        cell=config.cell))
    return clock


def main(quick: bool = False) -> str:
    import os

    machine = _load("run_all", HERE / "run_all.py").machine_description()
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        cal_rows, accuracy = _calibration_rows(Path(tmp), quick)
    with tempfile.TemporaryDirectory() as tmp:
        rep_rows, note = _replay_rows(Path(tmp))
    lines = [
        "## In your own cell: calibrate and replay (issue 30)", "",
        f"Machine: {machine}; load average {load:.1f} at the start (2 shared cores).", "",
        "| calibration | time | per image | ratio |", "|---|---|---|---|",
        *[f"| {' | '.join(r)} |" for r in cal_rows], "",
        accuracy, "",
        "| replay | time | per frame | ratio to the baseline |", "|---|---|---|---|",
        *[f"| {' | '.join(r)} |" for r in rep_rows], "",
        note, "",
    ]
    return save_section("bench_real_cell", "\n".join(lines))


if __name__ == "__main__":
    print(main(quick="--quick" in sys.argv))
