"""``cadfeat track STUDY --images DIR --poses CSV [--hand-eye T.yaml]``: a rendered sequence written as a robot
cell logs it (frame PNGs in 8 and 16 bit, grey and colour; a CSV of the poses rounded as a controller prints them)
replays to the closed loop's own numbers for the same frames (its detection and association on the same noisy
frames, its estimators from the same first pose), also when the robot logs its flange and the hand-eye transform
is given; a wrong hand-eye shows as a large error and an inconsistent NEES; a damaged recording (missing frames,
a corrupt image, a pose line that does not parse) finishes and reports each by name."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

cq = pytest.importorskip("cadquery")

import cv2  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from cadfeat.cli import main  # noqa: E402
from cadfeat.study.schema import load_study  # noqa: E402
from tests.study_helpers import write_toml  # noqa: E402

PART = (Path(__file__).parents[1] / "data" / "spread_plate.py").read_text()
"""The test's part script (a spread of four through holes), written beside each study."""
STUDY = {
    "study": {"name": "recorded", "part": "plate.py", "seed": 2},
    "camera": {"fx": 420.0, "fy": 420.0, "cx": 160.0, "cy": 120.0, "width": 320, "height": 240,
               "dist": [-0.05, 0.01, 0.0, 0.0, 0.0], "focus_distance_mm": 300.0},
    "trajectory": {"kind": "orbit_arc", "centre": [0, 0, 2.5], "radius_mm": 300.0, "elevation_deg": 70.0,
                   "azimuth_start_deg": -110.0, "azimuth_end_deg": -70.0, "n": 12, "duration_s": 1.2},
    "design": {"parameters": ["spread_mm"]},
    "tracking": {"runs": 1, "settle_frames": 3, "estimators": ["iekf", "pnp"], "r_px2": 0.05,
                 "q_rate_mm2_s2": 10.0, "q_omega_rad2_s2": 1e-4},
    "cell": {"noise_sigma_grey": 3.0},
}
NOISE_SEED = 5


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The study, its exported designs, and the optimised design's frames rendered by the closed loop (``observe``,
    ``frame_image``) with what the closed loop measures on them (``detect_sequence``, ``estimate_poses``)."""
    from cadfeat.cad.export import export_step
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.poses import cam_from_part
    from cadfeat.study.setup import load_scene
    from cadfeat.study.tracking import exported_designs
    from cadfeat.vision.closed_loop import detect_sequence, expected_visible, frame_image, observe
    from cadfeat.vision.estimate import estimate_poses
    from cadfeat.vision.metrics import pose_errors

    root = tmp_path_factory.mktemp("recorded")
    (root / "plate.py").write_text(PART)
    study = write_toml(root / "recorded.toml", STUDY)
    out = root / "out"
    out.mkdir()
    ns: dict = {}
    exec(PART, ns)  # noqa: S102 - the test's own part script
    export_step(ns["build"](8.0).val(), out / "original.step")
    export_step(ns["build"](38.0).val(), out / "optimised.step")
    config = load_study(study)
    shape, holes = exported_designs(config, out)["after"]
    camera, traj, T_task_part = load_scene(config)
    T = cam_from_part(traj.T_task_cam, T_task_part)
    tc = config.tracking_settings().in_cell(config.cell)
    obs = observe(shape, holes, camera, T, tc.sensor)
    frames = [frame_image(camera, obs, k, tc.sensor.noise_grey, NOISE_SEED) for k in range(len(T))]
    # the frames stand for a recording: detected as the replay detects a photograph's (not as point-sampled
    # raster renders, detectors.POINT_SAMPLED)
    pixels, _ = detect_sequence(obs, tc.sensor.noise_grey, NOISE_SEED, tc.gate_px, 1.0, tc.detector,
                                point_sampled=False)
    c, n, r = holes_to_arrays(holes)
    errors = {}
    for m in tc.estimators:
        track = estimate_poses(camera, c, pixels, traj.times_s, m, T[0], normals_part=n, radii_mm=r, tuning=tc.tuning)
        errors[m] = pose_errors(track.T_cam_part, T)
    expected = expected_visible(camera, obs, T)
    return dict(root=root, study=study, out=out, traj=traj, frames=frames, pixels=pixels, errors=errors,
                expected=expected, names=[h.name for h in holes])


def _write_log(folder: Path, frames: list[np.ndarray], traj, csv: Path, bad_line: int | None = None,
               exact: bool = False) -> None:
    """Frames as a camera saves them (frame 3 in 16 bit, frame 4 in colour) and the poses as a controller prints
    them: mm to 3 decimals, quaternions to 6, times to 3 (``exact``: 17 significant digits)."""
    folder.mkdir()
    for k, img in enumerate(frames):
        if k == 3:
            cv2.imwrite(str(folder / f"frame_{k:04d}.png"), img.astype(np.uint16) * 257)
        elif k == 4:
            cv2.imwrite(str(folder / f"frame_{k:04d}.png"), cv2.cvtColor(img, cv2.COLOR_GRAY2BGR))
        else:
            cv2.imwrite(str(folder / f"frame_{k:04d}.png"), img)
    q = Rotation.from_matrix(traj.T_task_cam[:, :3, :3]).as_quat()
    lines = ["time_s,x_mm,y_mm,z_mm,qx,qy,qz,qw"]
    for k, (t, p, qk) in enumerate(zip(traj.times_s, traj.T_task_cam[:, :3, 3], q, strict=True)):
        if k == bad_line:
            lines.append("1.2,abc,0,0,0,0,0,1")
        elif exact:
            lines.append(",".join(f"{v:.17g}" for v in (t, *p, *qk)))
        else:
            lines.append(f"{t:.3f},{p[0]:.3f},{p[1]:.3f},{p[2]:.3f},{qk[0]:.6f},{qk[1]:.6f},{qk[2]:.6f},{qk[3]:.6f}")
    csv.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("exact", [True, False], ids=["exact poses", "controller-rounded poses"])
def test_replay_gives_the_closed_loops_numbers(recording: dict, capsys: pytest.CaptureFixture[str],
                                               exact: bool) -> None:
    """Exact poses: the closed loop's pixels and pose errors (to 1e-3 mm). Rounded poses (1 µm, 1e-6): the rim
    detector takes the predicted rims at the reported pose as its prior, and its centres move by up to 0.08 px
    with that 1e-3 mm change of the prior (measured), so the per-frame errors agree to 0.05 mm / 0.06 deg (measured
    at worst 0.024 mm, 0.047 deg: single-frame PnP) and their RMS to 20 %."""
    rec = recording
    tag = "exact" if exact else "rounded"
    images, csv = rec["root"] / f"images_{tag}", rec["root"] / f"poses_{tag}.csv"
    _write_log(images, rec["frames"], rec["traj"], csv, exact=exact)
    assert main(["track", str(rec["study"]), "--out", str(rec["out"]), "--images", str(images), "--poses", str(csv),
                 "--design", "optimised"]) == 0
    text = capsys.readouterr().out
    assert "reference: the robot's reported poses" in text and "NEES" in text and "predicted (cadfeat" in text
    section = json.loads((rec["out"] / "tracking" / "recorded_optimised.json").read_text())
    assert section["frames_used"] == len(rec["frames"]) and section["problems"] == []
    found = np.all(np.isfinite(rec["pixels"]), axis=-1)
    rate = (found & rec["expected"]).sum(0) / np.maximum(rec["expected"].sum(0), 1)
    assert [section["detection_rate"][n] for n in rec["names"]] == pytest.approx(rate.tolist(), abs=1e-9)
    tol_mm, tol_deg = (1e-3, 1e-4) if exact else (0.05, 0.06)
    for m, (et, er) in rec["errors"].items():
        got_t = np.array([f[m]["trans_mm"] for f in section["frames"]], float)
        got_r = np.array([f[m]["rot_deg"] for f in section["frames"]], float)
        np.testing.assert_allclose(got_t, et, atol=tol_mm)
        np.testing.assert_allclose(got_r, er, atol=tol_deg)
        assert section["measured"][m]["trans_mm_rms"] == pytest.approx(np.sqrt(np.mean(et ** 2)), rel=0.2)
        assert section["measured"][m]["rot_deg_rms"] == pytest.approx(np.sqrt(np.mean(er ** 2)), rel=0.2)
        assert section["measured"][m]["nees_mean"] is not None
    assert section["predicted"]["trans_mm_rms"] > 0
    assert all(f["predicted_trans_mm"] > 0 for f in section["frames"])


def test_a_damaged_recording_finishes_and_names_each_problem(recording: dict,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    rec = recording
    images, csv = rec["root"] / "damaged", rec["root"] / "damaged.csv"
    _write_log(images, rec["frames"], rec["traj"], csv, bad_line=6)
    (images / "frame_0002.png").unlink()
    (images / "frame_0009.png").unlink()
    (images / "frame_0005.png").write_bytes(b"\x89PNG\r\n\x1a\n truncated")
    (images / "snapshot.png").write_bytes((images / "frame_0000.png").read_bytes())
    assert main(["track", str(rec["study"]), "--out", str(rec["out"]), "--images", str(images), "--poses", str(csv),
                 "--design", "optimised"]) == 0
    section = json.loads((rec["out"] / "tracking" / "recorded_optimised.json").read_text())
    problems = "\n".join(section["problems"])
    assert "damaged.csv line 8 (pose row 6): not numbers" in problems
    assert "frame_0006.png: unmatched (no parsed pose in row 6)" in problems
    assert "pose row 2: no image (missing frame)" in problems and "pose row 9: no image" in problems
    assert "frame_0005.png: not a readable image" in problems
    assert "snapshot.png: unmatched (no number in the name)" in problems
    assert section["frames_used"] == len(rec["frames"]) - 4
    assert "problem: frame_0005.png" in capsys.readouterr().out
    assert section["poses_parsed"] == len(rec["frames"]) - 1


#: The camera's hand-eye transform T_flange_cam of the test's robot (a camera on a bracket: offset and turned).
HAND_EYE = (np.array([0.2, -0.1, 1.4]), np.array([35.0, -60.0, 110.0]))
#: A wrong hand-eye: the true one with the camera off by 8 mm along its axis, 1 mm across and 0.3 deg of roll
#: (beyond the study's ±2 mm / ±1 deg mount bounds along the axis).
HAND_EYE_ERROR = (np.array([0.0, 0.0, np.radians(0.3)]), np.array([1.0, -1.0, 8.0]))


def _rigid(rotvec: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = t
    return T


def _write_hand_eye(path: Path, T: np.ndarray) -> Path:
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("T", T)
    fs.release()
    return path


def test_flange_poses_with_the_hand_eye_replay_as_camera_poses(recording: dict,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    """The robot logs its flange, T_task_flange = T_task_cam T_flange_cam⁻¹, with the camera's frames rendered at
    T_task_cam = T_task_flange T_flange_cam: ``--hand-eye`` replays them to the closed loop's numbers (as the
    camera poses given directly, to 1e-3 mm); a wrong hand-eye (8 mm along the axis, 0.3 deg roll) is seen as a
    large error against the reference and a NEES far above its band even with the reference's assumed
    covariance. Measured (IEKF / PnP): right 0.14 / 0.21 mm RMS, NEES 0.08 / 0.13 (0.47 / 0.55 with the reference
    taken as exact); wrong 8.06 / 8.02 mm, NEES 72 / 67 (674 / 580) against the band [4.2, 8.1]: overconfident."""
    from types import SimpleNamespace

    rec = recording
    T_fc = _rigid(*HAND_EYE)
    flange = SimpleNamespace(times_s=rec["traj"].times_s, T_task_cam=rec["traj"].T_task_cam @ np.linalg.inv(T_fc))
    images, csv = rec["root"] / "images_flange", rec["root"] / "flange.csv"
    _write_log(images, rec["frames"], flange, csv, exact=True)
    sections = {}
    for tag, T in (("right", T_fc), ("wrong", T_fc @ _rigid(*HAND_EYE_ERROR))):
        he = _write_hand_eye(rec["root"] / f"hand_eye_{tag}.yaml", T)
        assert main(["track", str(rec["study"]), "--out", str(rec["out"]), "--images", str(images),
                     "--poses", str(csv), "--hand-eye", str(he), "--design", "optimised"]) == 0
        sections[tag] = json.loads((rec["out"] / "tracking" / "recorded_optimised.json").read_text())
    capsys.readouterr()
    right, wrong = sections["right"], sections["wrong"]
    assert right["frames_used"] == wrong["frames_used"] == len(rec["frames"]) and right["problems"] == []
    for m, (et, er) in rec["errors"].items():
        np.testing.assert_allclose([f[m]["trans_mm"] for f in right["frames"]], et, atol=1e-3)
        np.testing.assert_allclose([f[m]["rot_deg"] for f in right["frames"]], er, atol=1e-4)
        got, bad = right["measured"][m], wrong["measured"][m]
        assert bad["trans_mm_rms"] > 5 * got["trans_mm_rms"] and bad["trans_mm_rms"] > 4.0
        assert bad["nees_mean"] > bad["nees_95"][1] and bad["consistency"].startswith("overconfident")
        assert bad["nees_filter_only_mean"] > 10 * got["nees_filter_only_mean"]
