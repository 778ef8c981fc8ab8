"""Pre-flight checks of a study: refuse, before any optimisation, a study that cannot mean anything
(docs/design.md, "Trust rules"), with one line naming the likely cause and the key to change.

``preflight(config, camera, trajectory, T_task_part, part_points, holes, scored)`` checks, in this order:

1. ``camera.fx``/``fy`` give a plausible field of view for the image size (0.5° … 150°; fx/fy within a
   factor 2) — fx = 12 "px" for a 1280 px image is a focal length typed in mm;
2. trajectory and part sizes agree in units: the median camera–part distance is neither inside the part
   (positions in metres: cameras within 0.3 mm of a 60 mm part) nor over 2000 part sizes away;
3. the part is in front of the camera and inside the image (within the lens's valid field) at a sensible
   share of the poses (``MIN_POSE_SHARE``); else the cause: the camera looks away (the part behind it at every
   pose), a CSV quaternion written w-first (if reading it w-first makes the part visible, say so), or the
   part outside the image (trajectory target / part_pose);
4. the scored holes are seen somewhere on the trajectory (``check_visibility``);
5. the camera's depth of field [D2, D1] overlaps the depths of the part along the trajectory (else
   ``camera.focus_distance_mm``); a focus distance outside the depth range but a depth of field reaching
   it is a warning;
6. with g_POSE among the objectives, its detection models for the study's cell have been confirmed against the
   physically based closed loop (a warning otherwise, ``design.pose_terms.model_confirmation``).

Optics the study did not give (focal length, f-number, focus distance: ``Camera`` defaults) are returned as
``assumptions`` (printed and shown in the report); a calibration whose fold-over radius lies inside the
image (``Camera.fold_inside_image``) is a warning.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation  # pyright: ignore[reportMissingTypeStubs]

from cadfeat.camera import MIN_DEPTH_MM, PRESETS, CameraError, read_opencv_calibration
from cadfeat.poses import cam_from_part
from cadfeat.study.schema import StudyError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.camera import Camera
    from cadfeat.measures.evaluate import Measures
    from cadfeat.study.schema import StudyConfig
    from cadfeat.trajectory import Trajectory

__all__ = ["MIN_POSE_SHARE", "Preflight", "check_visibility", "optics_assumptions", "preflight"]

MIN_POSE_SHARE = 0.1
"""Smallest share of the trajectory's poses at which some of the part must be in the image."""
FOV_RANGE_DEG = (0.5, 150.0)
OPTICS_KEYS = ("focal_length_mm", "f_number", "focus_distance_mm")


@dataclass
class Preflight:
    """What the pre-flight found (the study passed): ``assumptions`` (optics not given), ``warnings``,
    ``numbers`` (share of poses seeing the part, depth range, field of view)."""

    assumptions: list[str] = field(default_factory=list[str])
    warnings: list[str] = field(default_factory=list[str])
    numbers: dict[str, object] = field(default_factory=dict[str, object])

    def to_dict(self) -> dict[str, object]:
        return {"assumptions": list(self.assumptions), "warnings": list(self.warnings), **self.numbers}


def optics_assumptions(camera_table: Mapping[str, object], camera: Camera) -> list[str]:
    """The optics a study's ``[camera]`` did not set (neither directly nor through a preset or calibration
    file that defines them), as "key = value (assumed)" lines."""
    given = set(camera_table)
    if "preset" in camera_table:
        given |= set(PRESETS.get(str(camera_table["preset"]).strip().lower(), {}))
    if camera_table.get("calibration") is not None:  # its optics nodes, when it has them (cadfeat calibrate)
        try:
            given |= set(read_opencv_calibration(str(camera_table["calibration"])))
        except CameraError:
            pass
    if "aperture_mm" in given:
        given.add("f_number")
    out: list[str] = []
    for key in OPTICS_KEYS:
        if key not in given:
            out.append(f"camera.{key} = {getattr(camera, key):g} (not given: assumed; it drives the focus and "
                       "resolution measures)")
    return out


def check_visibility(measures: Measures, label: str, scored: np.ndarray | None = None,
                     names: Sequence[str] | None = None) -> str | None:
    """Raise ``StudyError`` if no (scored) hole is seen at any trajectory sample: ``measures.visible`` (in front,
    facing the camera, inside the image and the lens's valid field, not hidden) and inside the field of view.
    ``measures``: ``measures.Measures`` (L, N) of the original design; ``scored`` (N,) bool (default all).
    Holes that are in view but hidden by the part itself at every sample are a warning (returned), not an
    error: moving them out from behind the part is a meaningful redesign."""
    visible = np.asarray(measures.visible, bool)
    L, N = visible.shape
    cols = np.ones(N, bool) if scored is None else np.asarray(scored, bool)
    in_view = (np.asarray(measures.fov, float) >= 0.0) | (np.asarray(measures.fov_px, float) >= 0.0)
    seen = (visible & in_view)[:, cols]
    if seen.size == 0 or seen.any():
        return None
    which = ", ".join(np.asarray(names)[cols]) if names is not None else f"{int(cols.sum())} hole(s)"
    if not (np.asarray(measures.facing, float)[:, cols] > 0.0).any():
        cause = "at every sample the camera is behind the holes' faces (e.g. a camera below the part)"
    elif ((np.asarray(getattr(measures, "hidden", np.zeros_like(visible)), bool)
           & (np.asarray(measures.facing, float) > 0))[:, cols]).any():  # (hidden margins are made negative)
        return (f"the scored holes ({which}) are hidden by the part itself wherever they are in view at the "
                "starting design")
    else:
        cause = ("no scored hole is ever in front of the camera and inside its field of view; check [trajectory], "
                 "[part_pose] (mm) or objective.score")
    raise StudyError(f"{label}: the camera never sees the part: none of the scored holes ({which}) is seen at any of "
                     f"the {L} trajectory samples; {cause}. Nothing was optimised.")


def _in_image(camera: Camera, P: np.ndarray) -> np.ndarray:
    """(L, V) bool: points (L, V, 3) camera frame in front of the camera, within the lens's valid field, and
    projecting inside the image."""
    Z = P[..., 2]
    front = Z > MIN_DEPTH_MM
    z = np.where(front, Z, 1.0)
    ok = front & ~camera.folded(P[..., 0] / z, P[..., 1] / z)
    px = camera.project(np.where(front[..., None], P, [0.0, 0.0, 1.0]))
    inside = (px[..., 0] >= 0) & (px[..., 0] <= camera.width) & (px[..., 1] >= 0) & (px[..., 1] <= camera.height)
    return ok & inside


def _share(camera: Camera, T_cam_part: np.ndarray, pts: np.ndarray) -> float:
    P = np.einsum("lij,vj->lvi", T_cam_part[:, :3, :3], pts) + T_cam_part[:, None, :3, 3]
    return float(_in_image(camera, P).any(axis=1).mean())


def _w_first(T_task_cam: np.ndarray) -> np.ndarray:
    """The poses a CSV would give if its quaternion columns (read as qx, qy, qz, qw) were written w-first."""
    q = Rotation.from_matrix(T_task_cam[:, :3, :3]).as_quat()  # (x, y, z, w) as read = file columns 5-8
    T = T_task_cam.copy()
    T[:, :3, :3] = Rotation.from_quat(np.column_stack([q[:, 1], q[:, 2], q[:, 3], q[:, 0]])).as_matrix()
    return T


def preflight(config: StudyConfig, camera: Camera, trajectory: Trajectory, T_task_part: np.ndarray,
              part_points: np.ndarray, measures: Measures, scored: np.ndarray, names: Sequence[str]) -> Preflight:
    """Run the checks of the module docstring; raise ``StudyError`` (one line, cause and key) on the first
    that fails, else return the ``Preflight`` record. ``part_points`` (V, 3) part frame, mm (mesh vertices or
    hole centres); ``measures``: ``measures.Measures`` of the holes along ``trajectory``."""
    label = config.label
    out = Preflight()
    _check_field_of_view(label, camera, out)                                     # 1. plausible field of view
    pts = np.asarray(part_points, float).reshape(-1, 3)
    T_task_cam = np.asarray(trajectory.T_task_cam, float)
    T_cam_part = cam_from_part(T_task_cam, T_task_part)
    _check_units(label, pts, T_cam_part, out)                                    # 2. mm, not m
    _check_in_image(config, camera, pts, T_task_cam, T_task_part, T_cam_part, out)  # 3. in front, in the image
    hidden_warning = check_visibility(measures, label, scored, names)             # 4. scored holes seen somewhere
    if hidden_warning:
        out.warnings.append(hidden_warning)
    _check_focus(label, camera, pts, T_cam_part, out)                            # 5. depth of field
    _check_models(config, out)                                                   # 6. g_POSE's models confirmed
    out.assumptions = optics_assumptions(config.camera.table, camera)
    return out


def _check_models(config: StudyConfig, out: Preflight) -> None:
    """With g_POSE among the objectives, a warning when its models for the study's cell have not been confirmed
    against the physically based closed loop (``design.pose_terms.model_confirmation``)."""
    if "pose" not in config.objective.measures:
        return
    from cadfeat.design.pose_terms import model_confirmation  # lazy: the design layer's models

    warning = model_confirmation(config.cell)
    if warning is not None:
        out.warnings.append(warning)


def _check_field_of_view(label: str, camera: Camera, out: Preflight) -> None:
    """fx, fy give a plausible field of view (``FOV_RANGE_DEG``) and nearly square pixels (focal lengths in px)."""
    fov_x = 2 * np.degrees(np.arctan(0.5 * camera.width / camera.fx))
    fov_y = 2 * np.degrees(np.arctan(0.5 * camera.height / camera.fy))
    lo, hi = FOV_RANGE_DEG
    for key, f, size, fov in (("fx", camera.fx, camera.width, fov_x), ("fy", camera.fy, camera.height, fov_y)):
        if not lo <= fov <= hi:
            raise StudyError(f"{label}: camera.{key} = {f:g} px gives a {fov:.3g}° field of view across {size} px "
                             f"(plausible {lo:g}–{hi:g}°): {key} is the focal length in PIXELS (focal length / pixel "
                             f"pitch, e.g. 8 mm / 0.0048 mm = 1667 px){', not mm' if f < 100 else ''}; set "
                             f"camera.{key}")
    if not 0.5 <= camera.fx / camera.fy <= 2.0:
        raise StudyError(f"{label}: camera.fx / camera.fy = {camera.fx:g} / {camera.fy:g}: pixels are not that far "
                         "from square; check camera.fx and camera.fy (both in px)")
    out.numbers["field_of_view_deg"] = [float(fov_x), float(fov_y)]


def _check_units(label: str, pts: np.ndarray, T_cam_part: np.ndarray, out: Preflight) -> None:
    """Camera–part distances against the part's size: metres given for millimetres show as a camera inside the
    part or absurdly far from it."""
    centre_part = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    cams_part = (np.linalg.inv(T_cam_part) @ np.array([0.0, 0.0, 0.0, 1.0]))[:, :3]
    dist = float(np.median(np.linalg.norm(cams_part - centre_part, axis=1)))
    out.numbers.update(part_size_mm=size, median_camera_distance_mm=dist)
    if size > 0 and dist < 0.5 * size:
        raise StudyError(f"{label}: the camera is a median {dist:.3g} mm from the centre of a part {size:.3g} mm "
                         "across (inside it): trajectory positions look like metres (cadfeat uses mm); check "
                         "[trajectory] positions/start/end/centre (mm) and [part_pose].position_mm")
    if size > 0 and dist > 2000 * size:
        raise StudyError(f"{label}: the camera is a median {dist:.3g} mm from a part only {size:.3g} mm across: the "
                         "trajectory and the part disagree in units (both are mm); check [trajectory] and the part")


def _check_in_image(config: StudyConfig, camera: Camera, pts: np.ndarray, T_task_cam: np.ndarray,
                    T_task_part: np.ndarray, T_cam_part: np.ndarray, out: Preflight) -> None:
    """The part in front of the camera and inside the image at ``MIN_POSE_SHARE`` of the poses; else the
    likely cause (a w-first CSV quaternion, a camera looking away, a trajectory aimed elsewhere)."""
    share = _share(camera, T_cam_part, pts)
    out.numbers["pose_share_part_in_image"] = share
    if share >= MIN_POSE_SHARE:
        return
    P = np.einsum("lij,vj->lvi", T_cam_part[:, :3, :3], pts) + T_cam_part[:, None, :3, 3]
    kind = str(config.trajectory.table.get("kind", "csv"))
    w_share = _share(camera, cam_from_part(_w_first(T_task_cam), T_task_part), pts) if kind == "csv" else 0.0
    where = f"the part is in the image at {100 * share:.0f}% of the {len(T_cam_part)} poses (need ≥ " \
            f"{100 * MIN_POSE_SHARE:.0f}%)"
    if w_share >= max(MIN_POSE_SHARE, 2 * share):
        cause = (f"the CSV quaternion looks written w-first: read as (qw, qx, qy, qz) the part is in the image "
                 f"at {100 * w_share:.0f}% of the poses; write columns 5-8 scalar-last (qx, qy, qz, qw) in "
                 "[trajectory] file")
    elif not (P[..., 2] > 0).any():
        cause = ("the camera looks away from the part at every pose (the part is behind it); check the "
                 "trajectory's orientation (camera z forward, OpenCV frame: [trajectory] target/rotations) "
                 "and [part_pose]")
    else:
        cause = ("the part is not in the camera's field of view: the trajectory does not look at it; check "
                 "[trajectory] target/centre and [part_pose].position_mm (mm, part frame → task frame)")
    raise StudyError(f"{config.label}: the camera never sees the part: {where}: {cause}. Nothing was optimised.")


def _check_focus(label: str, camera: Camera, pts: np.ndarray, T_cam_part: np.ndarray, out: Preflight) -> None:
    """The depth of field (eq. 3.4-3.5) reaches the part's depths along the trajectory (else an error); the
    focus distance outside them, or a lens model folding inside the image, is a warning."""
    depth = (np.einsum("lj,vj->lv", T_cam_part[:, 2, :3], pts) + T_cam_part[:, None, 2, 3])
    zmin, zmax = float(np.percentile(depth[depth > 0], 1)), float(np.percentile(depth[depth > 0], 99))
    near, far = camera.depth_of_field_mm
    out.numbers.update(depth_range_mm=[zmin, zmax], depth_of_field_mm=[near, far])
    if far < zmin or near > zmax:
        raise StudyError(f"{label}: camera.focus_distance_mm = {camera.focus_distance_mm:g} mm: its depth of field "
                         f"{near:.4g}–{far:.4g} mm misses the part's depths {zmin:.4g}–{zmax:.4g} mm along the "
                         "trajectory; set camera.focus_distance_mm within that range")
    if not zmin <= camera.focus_distance_mm <= zmax:
        out.warnings.append(f"camera.focus_distance_mm = {camera.focus_distance_mm:g} mm lies outside the part's "
                            f"depths {zmin:.4g}–{zmax:.4g} mm along the trajectory (its depth of field reaches them)")
    if camera.fold_inside_image:
        out.warnings.append(f"the lens calibration folds over {camera.valid_field_deg:.3g}° off axis, inside the "
                            "image: points beyond it count as outside the image (Camera.fold_radius)")
