"""A study's ``[tracking]`` section run on its original and optimised designs (``cadfeat track``, ``cadfeat run``).

Glue between the study (camera, trajectory, part pose, ``[tracking]``) and ``cadfeat.vision.closed_loop``:
the ``[tracking]`` section IS the closed loop's ``TrackingConfig`` (``cadfeat.vision.config``), run in the study's
``[cell]`` (``TrackingConfig.in_cell``); runs the closed loop on both designs, and returns the results.json ``tracking``
section: the Monte-Carlo summaries and paired verdicts (``BeforeAfter.to_json``), per-frame error curves
(median and 10–90 % band over runs, for the report's error-against-time plot, thesis Fig. 6.7 style) and a few
frames drawn with detected vs predicted ellipses (PNG files under ``tracking/`` in the output folder).

``sweep`` reruns the loop while one setting varies (thesis §6.3.3, Figs. 6.3–6.11): the initial error, q, r,
the focal length the filters assume (the images keep the true camera), or the sample time (frame step).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np

from cadfeat.cad.export import import_step
from cadfeat.cad.features import Hole, extract_holes
from cadfeat.cad.features.identity import named
from cadfeat.cad.parts import load_part
from cadfeat.errors import CadfeatError
from cadfeat.poses import cam_from_part
from cadfeat.study.schema import StudyConfig, StudyError, TrackingSpec
from cadfeat.study.setup import camera_direction, load_scene
from cadfeat.vision.closed_loop import draw_frame, frame_image, report_frames
from cadfeat.vision.motion import so3_log

if TYPE_CHECKING:  # pragma: no cover
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.camera import Camera
    from cadfeat.results import JsonDict, SweepData, TrackingData
    from cadfeat.vision.closed_loop import BeforeAfter, DesignTracking, Observation
    from cadfeat.vision.config import TrackingConfig

Design = tuple["Shape", "Sequence[Hole]"]
"""A design the closed loop tracks: its solid (part frame, mm) and its holes."""
TrackArguments = tuple["Camera", np.ndarray, np.ndarray, "np.ndarray | None", Design, "TrackingConfig"]
"""The arguments of ``closed_loop.track_one`` (``track_arguments``): camera, tracked poses, times, screws, the
design, the configuration."""
Tracked = tuple["DesignTracking", "Observation", dict[str, float]]
"""What ``closed_loop.track_one`` gives: the design's tracking, its observation, wall-clock timings."""

#: Sweep kinds and their default values (thesis §6.3.3 ranges where they apply to this scene).
SWEEPS: dict[str, tuple[float, ...]] = {
    "initial_error": (5.0, 20.0, 40.0, 80.0, 160.0),            # mm (and 0.1 deg per mm)
    "q": (1e3, 10.0, 1e-1, 1e-3, 1e-5),                         # q_rate mm²/s² (q_omega = q·1e-5 rad²/s²)
    "r": (5e-2, 1e-1, 1.0, 10.0, 100.0),                        # px²
    "focal_length": (0.99, 0.995, 1.0, 1.005, 1.01),            # factor on fx, fy assumed by the estimators
    "sample_time": (1, 2, 4),                                   # frame step (sample time = step × dt)
}


def _scene(config: StudyConfig) -> tuple[Camera, np.ndarray, np.ndarray, np.ndarray]:
    camera, traj, T_task_part = load_scene(config)
    return camera, cam_from_part(traj.T_task_cam, T_task_part), np.asarray(traj.times_s), traj.velocity_screws()


def _check_frames(config: StudyConfig, spec: TrackingSpec, n_samples: int) -> None:
    frames = len(range(0, n_samples, spec.frame_step))
    if frames < spec.settle_frames + 3:
        raise StudyError(f"{config.label}: tracking.settle_frames: {spec.settle_frames} leaves fewer than 3 of the "
                         f"{frames} tracked frames (trajectory n = {n_samples}, tracking.frame_step = "
                         f"{spec.frame_step}); allowed: settle_frames <= {max(frames - 3, 0)} or a smaller frame_step")


#: Rotation between two tracked frames (deg) above which a constant-velocity filter cannot be expected to follow.
MAX_FRAME_ROTATION_DEG = 30.0


def _motion_warnings(T_cam_part: np.ndarray, times_s: np.ndarray) -> list[str]:
    """Warn when the trajectory turns more than ``MAX_FRAME_ROTATION_DEG`` between tracked frames (e.g. a
    look-at camera rolling as its view passes the up vector): the EKF/IEKF's constant-velocity model then
    cannot follow, whatever the design; solvePnP is per frame and unaffected."""
    R = T_cam_part[:, :3, :3]
    step = np.degrees(np.linalg.norm(so3_log(R[1:] @ np.swapaxes(R[:-1], -1, -2)), axis=-1))
    if step.size == 0 or step.max() <= MAX_FRAME_ROTATION_DEG:
        return []
    k = int(np.argmax(step))
    return [f"the camera turns {step[k]:.0f}° between tracked frames {k} and {k + 1} (t = {times_s[k]:.3g} s to "
            f"{times_s[k + 1]:.3g} s); the EKF/IEKF's constant-velocity model cannot follow such a jump (check the "
            f"trajectory, e.g. a look-at camera rolling about its axis; or track more frames), solvePnP is per frame"]


def _curves(result: BeforeAfter) -> JsonDict:
    """Per design and estimator: frame times and the median / 10 % / 90 % over runs of both errors."""
    out: JsonDict = {}
    for name, d in result.designs.items():
        design: JsonDict = {"times_s": [round(float(t), 6) for t in d.times_s]}
        for m, (et, er) in d.errors.items():
            entry: dict[str, dict[str, list[float]]] = {}
            for key, e in (("trans_mm", et), ("rot_deg", er)):
                with np.errstate(all="ignore"):
                    q = np.nanpercentile(np.where(np.isfinite(e), e, np.nan), [10, 50, 90], axis=0) \
                        if np.isfinite(e).any() else np.full((3, e.shape[1]), np.nan)
                entry[key] = {"p10": q[0].tolist(), "median": q[1].tolist(), "p90": q[2].tolist()}
            design[m] = entry
        out[name] = design
    return out


def _frames(result: BeforeAfter, camera: Camera, out_dir: Path | None, count: int = 3) -> list[JsonDict]:
    """Frames (first, middle, last) of run 0 of each design, drawn with detections and predictions, as PNGs."""
    if out_dir is None:
        return []
    entries: list[JsonDict] = []
    for name, d in result.designs.items():
        obs = result.observations[name]
        n = len(obs.optical)
        for k in report_frames(n, count):
            img = frame_image(camera, obs, k, result.config.sensor.noise_grey, result.config.seed * 1000)
            rgb = draw_frame(img, obs.predicted[k], d.first_detections[k], d.pixels[0, k])
            entries.append({"design": name, "frame": int(k), "time_s": float(d.times_s[k]),
                            "path": write_frame(out_dir, "tracking", f"{name}_frame_{k:03d}.png", rgb),
                            "detected": int(np.all(np.isfinite(d.pixels[0, k]), axis=-1).sum()),
                            "holes": int(d.pixels.shape[2])})
    return entries


def write_frame(out_dir: Path, folder: str, name: str, rgb: np.ndarray) -> str:
    """Write the RGB frame ``rgb`` as ``out_dir/folder/name`` (PNG); its path relative to ``out_dir`` (what
    results.json lists and the report embeds)."""
    import cv2

    path = Path(out_dir) / folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)):
        raise CadfeatError(f"cannot write {path}")
    return f"{folder}/{name}"


def _named(holes: Sequence[Hole]) -> list[Hole]:
    """The holes with the study's names: a hole without one is ``H<i+1>``, as in every other section."""
    return named(holes)


#: The exported designs ``cadfeat track`` reads: design name → STEP file in the output folder.
EXPORTED = {"before": "original.step", "after": "optimised.step"}


def exported_designs(config: StudyConfig, out: Path) -> dict[str, tuple[Shape, list[Hole]]]:
    """The designs a ``cadfeat run`` exported to ``out``, with the holes that run tracked (one closed loop).

    Shapes: ``original.step`` and ``optimised.step``. Holes: those of results.json ``holes.before`` /
    ``holes.after`` — the study's own holes (its extraction with its view direction, its names), exactly what
    ``cadfeat run`` passes to ``run_tracking``. Without them (an older output folder) the holes are extracted
    from the STEP files with the study's view direction (``design.view_direction``, the part script's
    ``VIEW_DIRECTION``, or the direction towards the trajectory's cameras), so through holes enter on the side
    the camera sees, and named ``H<i+1>``.
    """
    shapes: dict[str, Shape] = {}
    for name, file in EXPORTED.items():
        path = Path(out) / file
        if not path.is_file():
            raise CadfeatError(f"{config.label}: {path} not found; allowed: the output folder of `cadfeat run` "
                               f"(run `cadfeat run {config.label}` first, or give --out DIR)")
        shapes[name] = import_step(path)
    results_path = Path(out) / "results.json"
    holes: dict[str, list[Hole]] = {}
    if results_path.is_file():
        try:
            block: Mapping[str, object] = json.loads(results_path.read_text(encoding="utf-8")).get("holes") or {}
        except (ValueError, AttributeError) as exc:
            raise CadfeatError(f"{results_path}: not a results.json of `cadfeat run` ({exc})") from None
        entries = {k: cast("list[object]", v) for k in EXPORTED if isinstance(v := block.get(k), list) and v}
        if len(entries) == len(EXPORTED):
            holes = {k: [_hole_from_json(h, results_path, k, i) for i, h in enumerate(v)] for k, v in entries.items()}
    if not holes:
        view = _view_direction(config, Path(out) / EXPORTED["before"])

        holes = {k: extract_holes(shapes[k], prefer_direction=view) for k in EXPORTED}
    return {k: (shapes[k], _named(holes[k])) for k in EXPORTED}


def _number(value: object) -> float:
    """``float(value)`` of a number read from JSON (``TypeError`` as ``float`` gives it for anything else)."""
    if isinstance(value, int | float | str):
        return float(value)
    raise TypeError(f"float() argument must be a string or a real number, not '{type(value).__name__}'")


def _hole_from_json(entry: object, path: Path, key: str, i: int) -> Hole:
    """A ``Hole`` from a results.json hole entry (``study.outputs.hole_dict``). The closed loop uses the entrance
    rim only (centre, axis, radius, depth, through); the narrowest bore is not stored and is taken as the rim."""
    try:
        if not isinstance(entry, Mapping):
            raise TypeError(f"expected a table, got {entry!r}")
        h = cast("Mapping[str, object]", entry)
        return Hole(centre=np.asarray(h["centre_mm"], float), axis=np.asarray(h["axis"], float),
                    radius_mm=_number(h["radius_mm"]), bore_radius_mm=_number(h["radius_mm"]),
                    depth_mm=_number(h["depth_mm"]), through=bool(h["through"]), kind=str(h.get("kind", "plain")),
                    host_face=-1, outline=None, name=str(h.get("name") or ""))
    except (KeyError, TypeError, ValueError) as exc:
        raise CadfeatError(f"{path}: holes.{key}[{i}]: {exc!s}; allowed: a hole entry of `cadfeat run` "
                           "(centre_mm, axis, radius_mm, depth_mm, through)") from None


def _view_direction(config: StudyConfig, original_step: Path) -> np.ndarray | None:
    """The side the study's camera looks from (part frame), as the study's own extraction uses it."""
    if config.study.part_kind == "step":
        if config.design.view_direction is not None:
            return np.asarray(config.design.view_direction, float)

        _, traj, T_task_part = load_scene(config)
        return camera_direction(original_step, traj, T_task_part)

    own = load_part(config.study.part_path, config.study.build_timeout_s).view_direction
    if own is not None:
        return own
    _, traj, T_task_part = load_scene(config)  # as the study's set-up: towards the trajectory's cameras
    return camera_direction(original_step, traj, T_task_part)


def run_tracking(config: StudyConfig, designs: Mapping[str, Design], out_dir: Path | None = None,
                 spec: TrackingSpec | None = None, camera_override: Camera | None = None,
                 tracked: Mapping[str, Tracked] | None = None, pairs: Mapping[str, tuple[str, str]] | None = None
                 ) -> TrackingData:
    """The results.json ``tracking`` section for ``designs`` = {"before": (shape, holes), "after": (...)}.

    ``out_dir``: where the frame PNGs go (``tracking/``); None writes nothing. ``camera_override``: the camera
    the estimators assume (the images always use the study's camera) — for the focal-length sweep. ``tracked``:
    designs already tracked with ``spec`` (``closed_loop.track_one`` of ``track_arguments``, e.g. in a worker),
    not re-run. ``pairs``: more paired comparisons of ``designs`` (label → (before, after) names: the section's
    ``comparisons``); the main verdicts are always "after" against "before".
    """
    spec = spec or config.tracking_settings()
    designs = {k: (shape, _named(holes)) for k, (shape, holes) in designs.items()}
    camera, T_cam_part, times, screws = _scene(config)
    _check_frames(config, spec, len(T_cam_part))
    from cadfeat.vision.closed_loop import track_designs  # lazy: looked up per call (tests replace it)

    result = track_designs(camera, T_cam_part, times, screws, dict(designs), spec.in_cell(config.cell),
                           estimator_camera=camera_override, tracked=tracked, pairs=pairs)
    section = result.to_json()
    section["warnings"] = _motion_warnings(T_cam_part[result.frame_indices], times[result.frame_indices])
    section["curves"] = _curves(result)
    section["frames"] = _frames(result, camera, out_dir)
    return section


def track_arguments(config: StudyConfig, spec: TrackingSpec, design: Design) -> TrackArguments:
    """The arguments of ``closed_loop.track_one`` that track one design (shape, holes) of the study as
    ``run_tracking`` tracks it with ``spec`` (the same holes' names, frames and runs), for ``run_tracking``'s
    ``tracked``; plain arrays and dataclasses (picklable: the study's check tracks the original in a worker)."""
    from cadfeat.vision.closed_loop import tracked_frames  # lazy: scipy.optimize

    camera, T_cam_part, times, screws = _scene(config)
    _check_frames(config, spec, len(T_cam_part))
    _, T, t, sc = tracked_frames(T_cam_part, times, screws, spec.frame_step)
    return camera, T, t, sc, (design[0], _named(design[1])), spec.in_cell(config.cell)


def sweep(config: StudyConfig, designs: Mapping[str, Design], kind: str,
          values: Sequence[float] | None = None, spec: TrackingSpec | None = None) -> SweepData:
    """Thesis §6.3.3 sensitivity: the tracking summary per value of one setting (module docstring).

    Returns {"kind", "values", "rows": [{"value", design: {estimator: {trans_mm_rms, rot_deg_rms, convergence_s}}}]}.
    """
    if kind not in SWEEPS:
        raise StudyError(f"{config.label}: --sweep {kind!r} is not allowed; allowed: {', '.join(SWEEPS)}")
    base = spec or config.tracking_settings()
    rows: list[JsonDict] = []
    camera = _scene(config)[0]
    for value in (values or SWEEPS[kind]):
        s, cam = base, None
        if kind == "initial_error":
            s = base.replace(initial_error_mm=float(value), initial_error_deg=0.1 * float(value))
        elif kind == "q":
            s = base.replace(q_rate_mm2_s2=float(value), q_omega_rad2_s2=float(value) * 1e-5)
        elif kind == "r":
            s = base.replace(r_px2=float(value))
        elif kind == "focal_length":
            cam = camera.replace(fx=camera.fx * float(value), fy=camera.fy * float(value))
        elif kind == "sample_time":
            s = base.replace(frame_step=int(value), settle_frames=min(base.settle_frames, 2))
        section = run_tracking(config, designs, None, s, camera_override=cam)
        row: JsonDict = {"value": float(value)}
        for name, d in section["designs"].items():
            row[name] = {m: {k: e[k]["mean"] for k in ("trans_mm_rms", "rot_deg_rms", "convergence_s")}
                         for m, e in d["estimators"].items()}
        row["verdicts"] = {m: v["verdict"] for m, v in section["verdicts"].items()}
        rows.append(row)
    return {"kind": kind, "values": [float(v) for v in (values or SWEEPS[kind])], "rows": rows}


def pbr_seconds(config: StudyConfig, spec: TrackingSpec, design: Design) -> tuple[float, int]:
    """(seconds per frame, frames to render) of the physically based closed loop of one design: a frame at the
    middle tracked pose timed by ``PbrRenderer.estimate_seconds``; every run renders its own placement when the
    cell has a placement tolerance (``Cell.placement_sigma``)."""
    from cadfeat.render.pbr import PbrRenderer
    from cadfeat.vision.closed_loop import placed, tracked_frames

    camera, T_cam_part, times, screws = _scene(config)
    _, T, _, _ = tracked_frames(T_cam_part, times, screws, spec.frame_step)
    tc = spec.replace(renderer="pbr").in_cell(config.cell)
    with PbrRenderer(design[0], list(design[1]), camera, **tc.render_options()) as renderer:
        seconds = renderer.estimate_seconds(T[len(T) // 2])
    return seconds, len(T) * (spec.runs if placed(tc) else 1)


def pbr_announcement(config: StudyConfig, spec: TrackingSpec, designs: Mapping[str, Design]) -> str:
    """The expected time of a physically based closed loop on ``designs`` (one frame of the first design timed,
    ``pbr_seconds``), said before it starts."""
    per_frame, frames = pbr_seconds(config, spec, next(iter(designs.values())))
    n = len(designs)
    return (f"physically based closed loop (Mitsuba 3, {spec.spp} spp, {config.cell.light.kind} light, "
            f"{config.cell.material.name}): about {per_frame:.2g} s per frame x {frames} frames x {n} designs = "
            f"about {n * per_frame * frames / 60:.1f} min")
