"""``cadfeat track STUDY --images DIR --poses poses.csv``: a recorded sequence of the real part replayed through the
closed loop (``vision.replay``), beside cadfeat's prediction for exactly those poses (``pose_accuracy.predict``).

The reference is T_cam_part from the robot's reported camera poses (with the hand-eye transform, when the robot
reports its flange) and the study's part placement ``[part_pose]``. It is not truth: its assumed accuracy is the
study's ``[cell]`` — the camera mount and the part placement bounds, each taken as σ = 0.4 × bound per axis (as
``Cell.placement_sigma``) — and the NEES is computed with that covariance added to the filter's.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, TypedDict

import numpy as np

from cadfeat.cell import Cell
from cadfeat.poses import cam_from_part
from cadfeat.study.schema import StudyConfig, TrackingSpec
from cadfeat.study.setup import load_scene

if TYPE_CHECKING:  # pragma: no cover
    import trimesh
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.camera import Camera
    from cadfeat.measures.pose_information import PoseInformation
    from cadfeat.results import JsonDict
    from cadfeat.vision.replay import Replay, ReportedPoses

class MeasuredData(TypedDict):
    """One estimator on the recording (``measured.<m>``): RMS errors against the reference, lost frames, the NEES
    (mean, expected, 95 % band, with the reference taken as exact) and its verdict."""

    trans_mm_rms: float | None
    rot_deg_rms: float | None
    frames_lost: int
    nees_mean: float | None
    nees_filter_only_mean: float | None
    nees_expected: float
    nees_95: list[float]
    consistency: str


class PredictedData(TypedDict):
    """cadfeat's predicted RMS errors at the recorded poses (``predicted``) and the model that gave them."""

    trans_mm_rms: float | None
    rot_deg_rms: float | None
    model: str


class RecordedData(TypedDict):
    """``tracking/recorded.json`` (``track_recording``): the recording replayed, measured against predicted."""

    design: str
    poses_parsed: int
    frames_used: int
    reference: str
    predicted: PredictedData
    measured: dict[str, MeasuredData]
    detection_rate: dict[str, float | None]
    predicted_detection: dict[str, float | None]
    frames: list[JsonDict]
    problems: list[str]


#: The designs a recording may be of, and their key in ``tracking.exported_designs``.
DESIGN_KEYS = {"original": "before", "optimised": "after"}


def reference_sigma(cell: Cell) -> tuple[np.ndarray, np.ndarray]:
    """(σ mm (3,), σ rad (3,)) per axis assumed for the reference pose: camera mount and part placement bounds,
    σ = 0.4 × bound each (``Cell.placement_sigma``), combined in quadrature."""
    from cadfeat.cell.model import PLACEMENT_SIGMA_PER_TOLERANCE as k
    from cadfeat.cell.model import triple

    mm = k * np.hypot(triple(cell.camera_position_mm), triple(cell.placement_position_mm))
    deg = k * np.hypot(triple(cell.camera_angle_deg), triple(cell.placement_angle_deg))
    return np.asarray(mm, float), np.radians(np.asarray(deg, float))


def _exclusions(shape: Shape, holes: list[Hole], camera: Camera, T: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, trimesh.Trimesh]:
    """(exclude (F, N), rim hidden (F, N), mesh): the closed loop's rules at the reference poses."""
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.measures.pose_models import hole_geometry
    from cadfeat.vision.closed_loop import not_associated, part_mesh, rim_hidden

    c, n, r = holes_to_arrays(holes)
    mesh = part_mesh(shape)
    hidden = rim_hidden(mesh, holes, T, c, n, r)
    gap = hole_geometry(camera, T, c, n, r).rim_gap_px(hidden)
    assert gap is not None  # (hole_geometry computes the rims)
    return not_associated(hidden, gap), hidden, mesh


def track_recording(config: StudyConfig, out: Path, images: Path, poses: Path, hand_eye: Path | None,
                    design: str, spec: TrackingSpec) -> RecordedData:
    """Replay the recording and return the ``tracking/recorded.json`` section (module docstring)."""
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.study.pose_accuracy import predict
    from cadfeat.study.tracking import exported_designs
    from cadfeat.vision.replay import match_images, read_hand_eye, read_reported_poses, replay

    shape, holes = exported_designs(config, out)[DESIGN_KEYS[design]]
    camera, _, T_task_part = load_scene(config)
    reported = read_reported_poses(poses)
    T_task_cam = reported.T @ read_hand_eye(hand_eye) if hand_eye is not None else reported.T
    T_ref = cam_from_part(T_task_cam, T_task_part)
    files, problems = match_images(images, reported.rows)
    exclude, hidden, mesh = _exclusions(shape, list(holes), camera, T_ref)
    tc = spec.in_cell(config.cell)
    sig_mm, sig_rad = reference_sigma(config.cell)
    c, n, r = holes_to_arrays(holes)
    rep = replay(camera, c, n, r, T_ref, reported.times_s, files, detector=tc.detector, gate_px=tc.gate_px,
                 estimators=tc.estimators, tuning=tc.tuning, ref_cov=np.diag(np.concatenate([sig_mm, sig_rad]) ** 2),
                 rim_model=tc.rim_model, exclude=exclude)
    used = np.flatnonzero(rep.used)
    info, _ = predict(camera, T_ref[used], holes, mesh, float(config.objective.pose_rotation_length_mm),
                      occlusion=hidden[used], cell=config.cell)
    names = [h.name for h in holes]
    return _section(rep, reported, files, used, info, names, design, sig_mm, sig_rad,
                    reported.problems + problems + rep.problems, tc.estimators)


def _section(rep: Replay, reported: ReportedPoses, files: list[Path | None], used: np.ndarray,
             info: PoseInformation, names: list[str], design: str, sig_mm: np.ndarray, sig_rad: np.ndarray,
             problems: list[str], estimators: tuple[str, ...]) -> RecordedData:
    """The JSON section: per frame (image, time, errors, NEES, predicted error), per hole detection rate, summary."""
    from scipy.stats import chi2  # pyright: ignore[reportMissingTypeStubs]

    frames: list[JsonDict] = []
    pred_t, pred_r = np.asarray(info.error_translation_mm), np.asarray(info.error_rotation_deg)
    for j, k in enumerate(used):
        file = files[int(k)]
        row: JsonDict = {"image": file.name if file else None,
                         "time_s": float(reported.times_s[k]), "csv_line": reported.lines[k],
                         "holes_found": int(np.all(np.isfinite(rep.pixels[k]), axis=-1).sum()),
                         "predicted_trans_mm": float(pred_t[j]), "predicted_rot_deg": float(pred_r[j])}
        for m in estimators:
            row[m] = {"trans_mm": _num(rep.errors[m][0][k]), "rot_deg": _num(rep.errors[m][1][k]),
                      "nees": _num(rep.nees[m][k])}
        frames.append(row)
    summary: dict[str, MeasuredData] = {}
    for m in estimators:
        e_t, e_r, ne, nf = (np.asarray(a)[used] for a in (*rep.errors[m], rep.nees[m], rep.nees_filter[m]))
        ok = np.isfinite(ne)
        lo, hi = chi2.ppf(  # pyright: ignore[reportUnknownMemberType] (scipy.stats has no stubs)
            [0.025, 0.975], 6 * max(int(ok.sum()), 1)) / max(int(ok.sum()), 1)
        mean = float(np.nanmean(ne)) if ok.any() else float("nan")
        summary[m] = {"trans_mm_rms": _rms(e_t), "rot_deg_rms": _rms(e_r),
                      "frames_lost": int((~np.isfinite(e_t)).sum()),
                      "nees_mean": _num(mean), "nees_filter_only_mean": _num(np.nanmean(nf)) if ok.any() else None,
                      "nees_expected": 6.0, "nees_95": [float(lo), float(hi)],
                      "consistency": _consistency(mean, lo, hi)}
    return {
        "design": design, "poses_parsed": len(reported.T), "frames_used": len(used),
        "reference": ("the robot's reported poses with the study's [part_pose] (and the hand-eye transform): not "
                      f"truth; assumed σ per axis {_fmt(sig_mm)} mm, {_fmt(np.degrees(sig_rad))} deg ([cell] camera "
                      "mount and placement bounds, σ = 0.4 × bound, in quadrature)"),
        "predicted": {"trans_mm_rms": _rms(pred_t), "rot_deg_rms": _rms(pred_r),
                      "model": "study.pose_accuracy.predict at the recorded poses (single-frame error)"},
        "measured": summary,
        "detection_rate": {nm: _num(v) for nm, v in zip(names, rep.detection_rate, strict=True)},
        "predicted_detection": {nm: _num(v) for nm, v in zip(names, np.asarray(info.probability).mean(axis=0),
                                                             strict=True)},
        "frames": frames,
        "problems": problems,
    }


def _consistency(mean: float, lo: float, hi: float) -> str:
    """The NEES verdict: inside its 95 % band, below (covariances larger than the errors) or above."""
    if not np.isfinite(mean):
        return "no estimate"
    if mean > hi:
        return "overconfident: the errors exceed the filter's and the reference's covariance"
    if mean < lo:
        return "pessimistic: the errors are smaller than the covariances (the reference may be better than assumed)"
    return "consistent"


def _num(x: float | np.floating | np.ndarray) -> float | None:
    return float(x) if np.isfinite(x) else None


def _rms(v: np.ndarray) -> float | None:
    v = np.asarray(v, float)
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v ** 2))) if v.size else None


def _fmt(v: np.ndarray) -> str:
    return "/".join(f"{x:.2g}" for x in np.asarray(v))
