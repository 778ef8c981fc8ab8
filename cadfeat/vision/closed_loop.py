"""The closed loop for one design and for before vs after: images → detection → pose tracking → errors.

``observe`` renders a design once along the trajectory and blurs it (``images``), keeping only each frame's
region around the part (the background is black; noise there cannot make a hole, since holes are dark
regions *enclosed* by the lit part). ``track_design`` then runs the Monte-Carlo runs: per run seed, noise
and 8-bit quantisation (``images.sensor_images``), detection and association to the model's holes at the
nominal pose (``detection``; the robot knows its commanded trajectory and the nominal part placement), and
every estimator from the same perturbed initial pose (``estimate.estimate_poses``). ``compare`` gives the
paired verdict per estimator (``metrics.paired_verdict``) on the same per-run RMS errors, where a frame without
an estimate counts at the error of the last estimate before it (``metrics.hold_last``). Run r uses the same
noise seed, initial error, placement and illumination for both designs, which is what makes the test paired.

**What varies from run to run** (as in a real cell; ``TrackingConfig``): the pixel noise (a new draw per run and
frame), the initial pose error (a random direction per run), the illumination (a gain 1 + N(0, ``gain_sigma``²) on
the optical image per run) and the part's placement in the cell (a rigid error per run, N(0, ``placement_mm``²)
per axis in translation and N(0, ``placement_deg``²) per axis in rotation, in the part frame; the truth of run r
is T_cam_part · δ_r and the images are rendered again at it). The placement draw moves each rim by a fraction of
a pixel to a few pixels, so the rendered rim's pixel-grid ("aliasing") offset is a fresh random draw per run
instead of one fixed offset per design: the Monte-Carlo mean is then the expectation the measurement model's
σ term predicts (``measures.pose_models``). Placement jitter re-renders every run (cost ∝ runs); 0 turns it off.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, cast

import numpy as np

from cadfeat.cad.export import mesh_from_shape
from cadfeat.cad.features import holes_to_arrays
from cadfeat.camera import Camera
from cadfeat.measures import hole_ellipse
from cadfeat.measures.ellipse import Ellipse as _E
from cadfeat.measures.pose_models import RIM_GAP_MIN_PX as _RIM_GAP_MIN_PX
from cadfeat.measures.pose_models import hole_geometry
from cadfeat.measures.rim_occlusion import rim_occlusion
from cadfeat.vision.config import RenderOptions, TrackingConfig
from cadfeat.vision.detection import Detections, associate
from cadfeat.vision.detectors import detect
from cadfeat.vision.estimate import estimate_poses
from cadfeat.vision.images import SensorModel, apply_optics, optics_kernels, render_sequence, sensor_images
from cadfeat.vision.metrics import aggregate_runs, hold_last, paired_verdict, pose_errors, run_summary
from cadfeat.vision.motion import so3_exp

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

    from cadfeat.cad.features import Hole, ShapeLike
    from cadfeat.measures.ellipse import Ellipse
    from cadfeat.results import ComparisonData, DesignTrackingData, EstimatorVerdictData, TrackingData

#: Pixels around the part kept per frame (blur and the contour tracer need a margin of background).
ROI_MARGIN_PX = 12
#: Grey level above which a clean-render pixel belongs to the lit part.
PART_LEVEL = 20.0
#: A hole whose rim the part hides by more than this fraction at the predicted pose is not associated.
RIM_HIDDEN_MAX = 0.03
#: A hole whose predicted rim comes closer than this (px) to another hole's rim is not associated
#: (``measures.pose_models.RIM_GAP_MIN_PX``: a neighbouring edge inside the surround ring shifts the centre).
RIM_GAP_MIN_PX = _RIM_GAP_MIN_PX


@dataclass
class Observation:
    """One design seen along the trajectory: per frame the blurred noiseless ROI image (float32), its
    top-left offset (u0, v0) px, the holes' predicted ellipses at the nominal pose, the model arrays and
    ``rim_hidden`` (F, N): the fraction of each rim the part hides at the nominal pose (``measures.rim_occlusion``;
    None = not computed). A hole with more than ``RIM_HIDDEN_MAX`` hidden is not associated (association with
    the predicted occlusion: a cut rim is never measured as if whole)."""

    optical: list[np.ndarray]
    offsets: np.ndarray
    predicted: list[Ellipse]
    centres: np.ndarray
    normals: np.ndarray
    radii: np.ndarray
    names: list[str]
    rim_hidden: np.ndarray | None = None
    # (shape, holes, sensor, screws)
    scene: tuple[ShapeLike, Sequence[Hole], SensorModel, np.ndarray | None] | None = None
    rim_gap: np.ndarray | None = None  # (F, N) px to the nearest other rim at the nominal pose (None: not computed)
    camera: Camera | None = None  # the detector undistorts the rims' edges with it (``detection.undistorted_centre``)
    renderer: str = "raster"  # the renderer kind and options that made the images (placement re-renders use them)
    render_options: RenderOptions = field(default_factory=lambda: RenderOptions())


@dataclass
class DesignTracking:
    """Result of ``track_design``: ``errors[est]`` = (trans_mm (R, F), rot_deg (R, F)), a lost frame at the error of
    the last estimate before it (``metrics.hold_last``: lost frames count against a design); ``summaries[est]`` per
    run dicts; ``pixels`` (R, F, N, 2); ``detection_rate`` (N,) detected / expected; ``expected`` (F, N)."""

    errors: dict[str, tuple[np.ndarray, np.ndarray]]
    summaries: dict[str, list[dict[str, float]]]
    pixels: np.ndarray
    expected: np.ndarray
    names: list[str]
    times_s: np.ndarray
    first_detections: list[Detections]

    @property
    def detection_rate(self) -> np.ndarray:
        found = np.all(np.isfinite(self.pixels), axis=-1)                      # (R, F, N)
        expected = np.broadcast_to(self.expected, found.shape)
        n_exp = expected.sum(axis=(0, 1))
        return np.where(n_exp > 0, (found & expected).sum(axis=(0, 1)) / np.maximum(n_exp, 1), np.nan)


def observe(shape: ShapeLike, holes: Sequence[Hole], camera: Camera, T_cam_part: np.ndarray, sensor: SensorModel,
            screws: np.ndarray | None = None, predict_occlusion: bool = True,
            frames: Sequence[int] | None = None, renderer: str = "raster",
            render_options: RenderOptions | None = None) -> Observation:
    """Render + blur once (module docstring). T_cam_part (F, 4, 4) mm, screws (F, 6) for motion blur;
    ``predict_occlusion``: the rims' hidden fractions at these poses (``Observation.rim_hidden``); ``frames``:
    render only these frame indices (the others' images are empty, 1 x 1 black at (0, 0): for runs that render
    their own placement, ``placed_observations``), None = all; ``renderer`` / ``render_options``: the renderer
    kind and its options (``TrackingConfig.render_options``)."""
    centres, normals, radii = holes_to_arrays(holes)
    T = np.asarray(T_cam_part, dtype=float)
    keep = np.arange(len(T)) if frames is None else np.unique(np.asarray(frames, dtype=int))
    clean = render_sequence(shape, holes, camera, T[keep], renderer, **(render_options or {}))
    kernels = optics_kernels(camera, T, centres, sensor, screws)
    some, some_offsets = _regions(camera, clean, apply_optics(clean, [kernels[k] for k in keep]))
    optical = [np.zeros((1, 1), np.float32) for _ in range(len(T))]
    offsets = np.zeros((len(T), 2), dtype=int)
    for j, k in enumerate(keep):
        optical[k], offsets[k] = some[j], some_offsets[j]
    c_cam = np.einsum("fij,nj->fni", T[:, :3, :3], centres) + T[:, None, :3, 3]
    n_cam = np.einsum("fij,nj->fni", T[:, :3, :3], normals)
    ell = hole_ellipse(camera, c_cam, n_cam, radii)

    predicted = [_E(ell.centre_px[k], ell.axes_px[k], ell.angle_rad[k], ell.valid[k]) for k in range(len(T))]
    names = [h.name or f"hole{j}" for j, h in enumerate(holes)]
    hidden = _rim_hidden(shape, holes, T, centres, normals, radii) if predict_occlusion else None

    gap = hole_geometry(camera, T, centres, normals, radii).rim_gap_px(hidden)
    return Observation(optical, offsets, predicted, centres, normals, radii, names, hidden,
                       (shape, list(holes), sensor, screws), gap, camera, renderer,
                       RenderOptions(**(render_options or {})))


def _regions(camera: Camera, clean: np.ndarray, blurred: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """Per frame the blurred region around the lit part (ROI_MARGIN_PX of background) and its (u0, v0) px."""
    optical, offsets = [], np.zeros((len(clean), 2), dtype=int)
    for k in range(len(clean)):
        rows = np.flatnonzero((clean[k] > PART_LEVEL).any(axis=1))
        cols = np.flatnonzero((clean[k] > PART_LEVEL).any(axis=0))
        if rows.size == 0:
            optical.append(np.zeros((1, 1), np.float32))
            continue
        v0, v1 = max(rows[0] - ROI_MARGIN_PX, 0), min(rows[-1] + ROI_MARGIN_PX + 1, camera.height)
        u0, u1 = max(cols[0] - ROI_MARGIN_PX, 0), min(cols[-1] + ROI_MARGIN_PX + 1, camera.width)
        optical.append(np.ascontiguousarray(blurred[k, v0:v1, u0:u1]))
        offsets[k] = (u0, v0)
    return optical, offsets


def placement_errors(config: TrackingConfig, runs: int) -> np.ndarray:
    """(R, 4, 4) the part's placement error δ_r per run (part frame, mm): translation N(0, placement_mm²) and
    rotation N(0, placement_deg²) per axis, from ``default_rng([run seed, 11])`` — the same for every design
    (common random numbers keep the paired test paired)."""
    out = np.tile(np.eye(4), (runs, 1, 1))
    for run in range(runs):
        rng = np.random.default_rng([config.seed * 1000 + run, 11])
        out[run, :3, 3] = rng.normal(0.0, config.placement_mm, 3)
        out[run, :3, :3] = so3_exp(np.radians(rng.normal(0.0, config.placement_deg, 3)))
    return out


def placed(config: TrackingConfig) -> bool:
    """Does every run render its own placement (``placement_mm`` or ``placement_deg`` > 0)?"""
    return bool(np.any(np.asarray(config.placement_mm) > 0) or np.any(np.asarray(config.placement_deg) > 0))


def illumination_gains(config: TrackingConfig, runs: int) -> np.ndarray:
    """(R,) the illumination gain per run, 1 + N(0, gain_sigma²) from ``default_rng([run seed, 13])``, ≥ 0.2."""
    return np.array([max(1.0 + np.random.default_rng([config.seed * 1000 + r, 13]).normal(0.0, config.gain_sigma),
                         0.2) for r in range(runs)])


def placed_observations(camera: Camera, obs: Observation, T_runs: np.ndarray) -> list[Observation]:
    """``obs`` rendered again at each run's true poses T_runs (R, F, 4, 4) (one renderer for all runs). The
    predicted ellipses and rim occlusion stay those of the nominal placement: the robot does not know δ_r."""
    from cadfeat.render import camera_renderer  # lazy: would import scipy.optimize at module load

    if obs.scene is None:
        raise ValueError("placement jitter needs an Observation made by observe() (it keeps the part to render)")
    shape, holes, sensor, screws = obs.scene
    out = []
    with camera_renderer(obs.renderer, shape, holes, camera, **obs.render_options) as renderer:
        for T in np.asarray(T_runs, dtype=float):
            clean = np.empty((len(T), camera.height, camera.width), dtype=np.float32)
            for k, pose in enumerate(T):
                clean[k] = renderer.render_grey(pose)
            blurred = apply_optics(clean, optics_kernels(camera, T, obs.centres, sensor, screws))
            optical, offsets = _regions(camera, clean, blurred)
            out.append(replace(obs, optical=optical, offsets=offsets))
    return out


def _rim_hidden(shape: ShapeLike, holes: Sequence[Hole], T: np.ndarray, centres: np.ndarray, normals: np.ndarray,
                radii: np.ndarray) -> np.ndarray:
    """(F, N) hidden fraction of each rim (ray test against the part's mesh, ``measures.rim_occlusion``)."""
    return rim_hidden(part_mesh(shape), holes, T, centres, normals, radii)


def part_mesh(shape: ShapeLike) -> trimesh.Trimesh:
    """The part's triangle mesh the closed loop's rim test uses (0.05 mm chord)."""
    return mesh_from_shape(shape, tolerance=0.05)


def rim_hidden(mesh: trimesh.Trimesh, holes: Sequence[Hole], T: np.ndarray, centres: np.ndarray, normals: np.ndarray,
               radii: np.ndarray) -> np.ndarray:
    """(F, N) hidden fraction of each rim at the poses T (F, 4, 4) on the part's ``mesh`` (``part_mesh``)."""
    return rim_occlusion(mesh, T, centres, normals, radii, samples=12, through=[h.through for h in holes],
                         depth_mm=[h.depth_mm for h in holes])


def not_associated(hidden: np.ndarray, gap: np.ndarray) -> np.ndarray:
    """(F, N) the holes the closed loop never associates: rim hidden by more than ``RIM_HIDDEN_MAX`` or closer than
    ``RIM_GAP_MIN_PX`` to another rim (at the predicted pose)."""
    return (np.asarray(hidden) > RIM_HIDDEN_MAX) | (np.asarray(gap) < RIM_GAP_MIN_PX)


def expected_visible(camera: Camera, obs: Observation, T: np.ndarray) -> np.ndarray:
    """(F, N): a hole counts as expected when its ellipse is valid, inside the image with its whole extent,
    facing the camera, its minor axis ≥ 3 px and (when predicted) its rim not hidden by the part."""
    c_cam = np.einsum("fij,nj->fni", T[:, :3, :3], obs.centres) + T[:, None, :3, 3]
    n_cam = np.einsum("fij,nj->fni", T[:, :3, :3], obs.normals)
    facing = np.einsum("fnk,fnk->fn", n_cam, -c_cam) > 0
    out = np.zeros(facing.shape, dtype=bool)
    for k, e in enumerate(obs.predicted):
        half = np.asarray(e.axes_px)[:, 0] / 2 + 2                    # whole rim inside, 2 px spare
        cu, cv = np.asarray(e.centre_px)[:, 0], np.asarray(e.centre_px)[:, 1]
        inside = (cu > half) & (cv > half) & (cu < camera.width - half) & (cv < camera.height - half)
        out[k] = np.asarray(e.valid) & inside & facing[k] & (np.asarray(e.axes_px)[:, 1] >= 3.0)
    if obs.rim_hidden is not None:
        out &= obs.rim_hidden <= RIM_HIDDEN_MAX
    if obs.rim_gap is not None:
        out &= obs.rim_gap >= RIM_GAP_MIN_PX
    return out


def report_frames(n: int, count: int = 3) -> list[int]:
    """The frames the report draws of a sequence of n (first, middle, last; at most ``count``)."""
    return sorted({0, n // 2, n - 1})[:count]


def frame_seed(run_seed: int, k: int) -> int:
    """The noise seed of frame k of a run (``sensor_images`` adds the frame index too)."""
    return int(run_seed) * 100_003 + k


def frame_image(camera: Camera, obs: Observation, k: int, noise_grey: float, run_seed: int) -> np.ndarray:
    """The full (H, W) uint8 camera image of frame k in run ``run_seed`` (the region, on black)."""
    roi = sensor_images(obs.optical[k][None], noise_grey, frame_seed(run_seed, k))[0]
    full = np.zeros((camera.height, camera.width), np.uint8)
    u0, v0 = obs.offsets[k]
    full[v0:v0 + roi.shape[0], u0:u0 + roi.shape[1]] = roi
    return full


def draw_frame(image: np.ndarray, predicted: Ellipse, detections: Detections, pixels: np.ndarray) -> np.ndarray:
    """RGB copy of a grey frame with the predicted rim ellipses (red), every detected ellipse (green) and the
    associated centres (yellow crosses) — the report's "detected vs predicted" frames."""
    import cv2

    out = cv2.cvtColor(np.asarray(image, np.uint8), cv2.COLOR_GRAY2RGB)
    s = 16

    def ell(c: np.ndarray, ax: np.ndarray, ang: float, colour: tuple[int, int, int]) -> None:
        if np.all(np.isfinite(c)) and np.all(np.abs(c) < 1e5) and 0 < ax[0] < 1e5:
            cv2.ellipse(out, (int(round(c[0] * s)), int(round(c[1] * s))), (int(round(ax[0] / 2 * s)),
                        int(round(ax[1] / 2 * s))), float(np.degrees(ang)), 0, 360, colour, 1, cv2.LINE_AA, 4)

    for j in np.flatnonzero(np.asarray(predicted.valid)):
        ell(np.asarray(predicted.centre_px)[j], np.asarray(predicted.axes_px)[j],
            float(np.asarray(predicted.angle_rad)[j]), (230, 40, 40))
    for j in range(len(detections)):
        ell(detections.centre_px[j], detections.axes_px[j], float(detections.angle_rad[j]), (40, 220, 60))
    for p in pixels:
        if np.all(np.isfinite(p)):
            cv2.drawMarker(out, (int(round(p[0])), int(round(p[1]))), (250, 220, 0), cv2.MARKER_CROSS, 9, 1)
    return out


def detect_sequence(obs: Observation, noise_grey: float, seed: int, gate_px: float,
                    gain: float = 1.0, detector: str = "cadfeat",
                    point_sampled: bool | None = None) -> tuple[np.ndarray, list[Detections]]:
    """Pixels (F, N, 2) of one Monte-Carlo run (NaN = missing) and the raw detections per frame; ``gain``
    scales the optical image (the run's illumination) before the noise; ``detector``: ``vision.detectors``'s
    kind (cadfeat's rim-edge detector takes the nominal predicted rims as its prior; the others see the image
    alone); ``point_sampled``: ``detectors.detect``'s (None: the raster renderer's images are)."""
    if point_sampled is None:
        point_sampled = obs.renderer == "raster"
    F_, N = len(obs.optical), len(obs.centres)
    pixels = np.full((F_, N, 2), np.nan)
    dets: list[Detections] = []
    for k, img in enumerate(obs.optical):
        frame = sensor_images(img[None] * np.float32(gain), noise_grey, frame_seed(seed, k))[0]
        d = detect(detector, frame, camera=obs.camera, origin_px=obs.offsets[k], predicted=obs.predicted[k],
                   point_sampled=point_sampled)
        d = Detections(d.centre_px + obs.offsets[k], d.axes_px, d.angle_rad, d.residual_px)
        dets.append(d)
        pixels[k] = associate(obs.predicted[k], d, gate_px)
        if obs.rim_hidden is not None:
            pixels[k, obs.rim_hidden[k] > RIM_HIDDEN_MAX] = np.nan
        if obs.rim_gap is not None:
            pixels[k, obs.rim_gap[k] < RIM_GAP_MIN_PX] = np.nan
    return pixels, dets


def initial_pose(T_true0: np.ndarray, error_mm: float, error_deg: float, seed: int) -> np.ndarray:
    """T_true0 with a translation error of ``error_mm`` and a rotation error of ``error_deg`` in random
    directions drawn from ``default_rng(seed)`` (left perturbation, camera frame)."""
    rng = np.random.default_rng([int(seed), 7])
    u = rng.standard_normal(3)
    w = rng.standard_normal(3)
    T0 = np.array(T_true0, dtype=float)
    T0[:3, 3] += error_mm * u / np.linalg.norm(u)
    T0[:3, :3] = so3_exp(np.radians(error_deg) * w / np.linalg.norm(w)) @ T0[:3, :3]
    return T0


def track_design(camera: Camera, obs: Observation, T_true: np.ndarray, times_s: np.ndarray,
                 config: TrackingConfig, estimator_camera: Camera | None = None) -> DesignTracking:
    """Monte-Carlo tracking of one observed design (module docstring). ``estimator_camera``: the camera model
    the estimators assume, when it differs from the one that made the images (calibration error, thesis
    Figs. 6.10–6.11)."""
    T_true = np.asarray(T_true, dtype=float)
    T_runs, runs_obs = run_observations(camera, obs, T_true, config)
    pixels, first = detect_runs(runs_obs, config)
    errors, summaries = estimate_runs(camera, obs, pixels, T_runs, times_s, config, estimator_camera)
    return DesignTracking(errors, summaries, pixels, expected_visible(camera, obs, T_true), obs.names,
                          np.asarray(times_s, dtype=float), first)


def run_observations(camera: Camera, obs: Observation, T_true: np.ndarray, config: TrackingConfig
                     ) -> tuple[np.ndarray, list[Observation]]:
    """(each run's true poses (R, F, 4, 4), each run's observation): the part placed by ``placement_errors`` and
    rendered again per run when the config has a placement error and ``obs`` keeps its scene, else ``obs``."""
    R_ = config.runs
    if placed(config) and obs.scene is not None:
        T_runs = T_true[None] @ placement_errors(config, R_)[:, None]
        return T_runs, placed_observations(camera, obs, T_runs)
    return np.broadcast_to(T_true, (R_,) + T_true.shape), [obs] * R_


def detect_runs(runs_obs: Sequence[Observation], config: TrackingConfig) -> tuple[np.ndarray, list[Detections]]:
    """(pixels (R, F, N, 2), NaN = missing; run 0's raw detections per frame): each run's images with its noise
    seed and illumination gain, searched by ``config.detector`` and associated (``detect_sequence``)."""
    gains = illumination_gains(config, len(runs_obs))
    found = [detect_sequence(o, config.sensor.noise_grey, config.seed * 1000 + run, config.gate_px,
                             float(gains[run]), config.detector) for run, o in enumerate(runs_obs)]
    return np.stack([f[0] for f in found]), found[0][1]


def estimate_runs(camera: Camera, obs: Observation, pixels: np.ndarray, T_runs: np.ndarray, times_s: np.ndarray,
                  config: TrackingConfig, estimator_camera: Camera | None = None
                  ) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], dict[str, list[dict[str, float]]]]:
    """Per estimator of ``config``: the errors (translation mm (R, F), rotation deg (R, F)) against each run's truth
    ``T_runs`` — a lost frame at the last estimate's error (``metrics.hold_last``) — and the per-run summaries; every
    run from its perturbed initial pose (``initial_pose``), all runs at once (the filters are batched)."""
    R_ = len(T_runs)
    normals = obs.normals if config.rim_model else None
    radii = obs.radii if config.rim_model else None
    T0 = np.stack([initial_pose(T_runs[run, 0], config.initial_error_mm, config.initial_error_deg,
                                config.seed * 1000 + run) for run in range(R_)])
    errors: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    summaries: dict[str, list[dict[str, float]]] = {}
    for m in config.estimators:
        track = estimate_poses(estimator_camera or camera, obs.centres, pixels, times_s, m, T0,
                               normals_part=normals, radii_mm=radii, tuning=config.tuning)
        held, lost = hold_last(track.T_cam_part, T0)  # a lost frame counts at the last estimate's error
        et, er = pose_errors(held, T_runs)
        errors[m] = (et, er)
        summaries[m] = [run_summary(et[run], er[run], times_s, config.settle_frames, config.converged_mm,
                                    config.converged_deg, lost[run]) for run in range(R_)]
    return errors, summaries


def design_json(result: DesignTracking) -> DesignTrackingData:
    """results.json form of one design's tracking: per estimator the Monte-Carlo means and intervals."""
    rate = result.detection_rate
    found = np.all(np.isfinite(result.pixels), axis=-1)
    return {
        "estimators": {m: aggregate_runs(s) for m, s in result.summaries.items()},
        "detection_rate": {name: (None if not np.isfinite(r) else round(float(r), 4))
                           for name, r in zip(result.names, rate, strict=True)},
        "frames_under_3_holes": float(np.mean(np.sum(found.sum(axis=-1) < 3, axis=1))),
        "frames": int(result.pixels.shape[1]),
        "runs": int(result.pixels.shape[0]),
    }


def compare(before: DesignTracking, after: DesignTracking, alpha: float = 0.05,
            min_change: float = 0.0) -> dict[str, EstimatorVerdictData]:
    """Paired verdicts per estimator on the per-run translation and rotation RMS errors, and an overall line.

    Per estimator: ``better`` when the translation or the rotation RMS is significantly lower after and the
    other not significantly higher (symmetrically ``worse``), ``mixed`` when one is significantly lower and
    the other significantly higher, else ``no significant difference``.
    """
    out: dict[str, EstimatorVerdictData] = {}
    for m in before.summaries:
        if m not in after.summaries:
            continue
        vt = paired_verdict(np.array([s["trans_mm_rms"] for s in before.summaries[m]]),
                            np.array([s["trans_mm_rms"] for s in after.summaries[m]]), alpha, min_change)
        vr = paired_verdict(np.array([s["rot_deg_rms"] for s in before.summaries[m]]),
                            np.array([s["rot_deg_rms"] for s in after.summaries[m]]), alpha, min_change)
        pair = {vt["verdict"], vr["verdict"]}
        if pair == {"better", "worse"}:
            verdict = "mixed"
        elif "better" in pair:
            verdict = "better"
        elif "worse" in pair:
            verdict = "worse"
        else:
            verdict = "no significant difference"
        out[m] = {"verdict": verdict, "translation": vt, "rotation": vr}
    return out


@dataclass
class BeforeAfter:
    """``track_designs`` result: per design name its ``DesignTracking`` and ``Observation``, the paired
    ``verdicts`` per estimator (before vs after), the config, frame times and wall-clock ``timings_s``."""

    designs: dict[str, DesignTracking]
    observations: dict[str, Observation]
    verdicts: dict[str, EstimatorVerdictData]
    config: TrackingConfig
    frame_indices: np.ndarray
    timings_s: dict[str, float]
    comparisons: dict[str, ComparisonData] = field(default_factory=dict[str, "ComparisonData"])
    """More paired comparisons: label → {"before": name, "after": name, "verdicts": per estimator}."""

    def to_json(self) -> TrackingData:
        """The results.json ``tracking`` section (plain data; infinities as None)."""
        c = self.config
        out: TrackingData = {
            "settings": {"estimators": list(c.estimators), "runs": c.runs, "noise_grey": c.sensor.noise_grey,
                         "defocus": c.sensor.defocus, "exposure_s": c.sensor.exposure_s,
                         "initial_error_mm": c.initial_error_mm, "initial_error_deg": c.initial_error_deg,
                         "r_px2": c.tuning.r_px2, "q_rate_mm2_s2": c.tuning.q_rate_mm2_s2,
                         "q_omega_rad2_s2": c.tuning.q_omega_rad2_s2, "iterations": c.tuning.iterations,
                         "tau": c.tuning.tau, "settle_frames": c.settle_frames, "frames": len(self.frame_indices),
                         "frame_step": c.frame_step, "rim_model": c.rim_model, "seed": c.seed,
                         "alpha": c.alpha, "min_change": c.min_change, "placement_mm": c.placement_mm,
                         "placement_deg": c.placement_deg, "gain_sigma": c.gain_sigma, "gate_px": c.gate_px,
                         "detector": c.detector, "renderer": c.renderer,
                         **({"spp": c.spp, "light": getattr(c.light, "kind", None),
                             "material": getattr(c.material, "name", None), "hole_ends": c.hole_ends}
                            if c.renderer == "pbr" else {})},
            "designs": {name: design_json(d) for name, d in self.designs.items()},
            "verdicts": self.verdicts,
            **({"comparisons": self.comparisons} if self.comparisons else {}),
            "timings_s": {k: round(v, 3) for k, v in self.timings_s.items()},
        }
        return cast("TrackingData", _finite_json(out))  # (the same keys; a non-finite number is None)


def _finite_json(value: object) -> object:
    """Replace NaN/inf by None and numpy scalars by Python numbers (strict JSON)."""
    if isinstance(value, dict):
        return {k: _finite_json(v) for k, v in cast("dict[str, object]", value).items()}
    if isinstance(value, list | tuple):
        return [_finite_json(v) for v in cast("Sequence[object]", value)]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def track_one(camera: Camera, T: np.ndarray, t: np.ndarray, sc: np.ndarray | None,
              design: tuple[ShapeLike, Sequence[Hole]],
              config: TrackingConfig, estimator_camera: Camera | None = None
              ) -> tuple[DesignTracking, Observation, dict[str, float]]:
    """One design of ``track_designs`` on its tracked frames ``T`` (F, 4, 4), times ``t`` (F,) s and screws ``sc``
    (F, 6) or None: its tracking, observation and wall-clock timings ("render", "track", s). A design's numbers do
    not depend on the other designs (the runs' seeds are the config's), so designs may be tracked apart — the
    study's check tracks the original in a worker process while the optimiser runs (``study.closed_loop_check``)."""
    shape, holes = design
    start = time.perf_counter()
    # with placement jitter every run renders its own placement: the nominal images are the report's frames
    obs = observe(shape, holes, camera, T, config.sensor, sc, frames=report_frames(len(T)) if placed(config) else None,
                  renderer=config.renderer, render_options=config.render_options())
    mid = time.perf_counter()
    tracked = track_design(camera, obs, T, t, config, estimator_camera)
    return tracked, obs, {"render": mid - start, "track": time.perf_counter() - mid}


def tracked_frames(T_cam_part: np.ndarray, times_s: np.ndarray, screws: np.ndarray | None, frame_step: int
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """(indices, poses, times, screws) of every ``frame_step``-th sample of the trajectory (the tracked frames)."""
    idx = np.arange(0, len(T_cam_part), max(1, int(frame_step)))
    sc = None if screws is None else np.asarray(screws, dtype=float)[idx]
    return idx, np.asarray(T_cam_part, dtype=float)[idx], np.asarray(times_s, dtype=float)[idx], sc


def track_designs(camera: Camera, T_cam_part: np.ndarray, times_s: np.ndarray, screws: np.ndarray | None,
                  designs: dict[str, tuple[ShapeLike, Sequence[Hole]]], config: TrackingConfig,
                  before: str = "before", after: str = "after", estimator_camera: Camera | None = None,
                  tracked: Mapping[str, tuple[DesignTracking, Observation, dict[str, float]]] | None = None,
                  pairs: Mapping[str, tuple[str, str]] | None = None) -> BeforeAfter:
    """Closed loop on several designs along one trajectory (every ``config.frame_step``-th sample), and the
    paired verdict ``after`` vs ``before`` per estimator. ``designs`` maps a name to (shape, holes); ``tracked``:
    designs already tracked with this config by ``track_one`` (their entries of ``designs`` are not re-run);
    ``pairs``: more paired comparisons, label → (before name, after name), each as the main one (the runs' seeds
    are the config's, so every design's run r has the same noise, initial error, placement and light)."""
    idx, T, t, sc = tracked_frames(T_cam_part, times_s, screws, config.frame_step)
    results, observations, timings = {}, {}, {}
    for name, design in designs.items():
        done = (tracked or {}).get(name) or track_one(camera, T, t, sc, design, config, estimator_camera)
        results[name], observations[name] = done[0], done[1]
        timings[f"{name}_render"], timings[f"{name}_track"] = done[2]["render"], done[2]["track"]
    verdicts = compare(results[before], results[after], config.alpha, config.min_change) \
        if before in results and after in results else {}
    more = {label: {"before": a, "after": b,
                    "verdicts": compare(results[a], results[b], config.alpha, config.min_change)}
            for label, (a, b) in (pairs or {}).items() if a in results and b in results}
    return BeforeAfter(results, observations, verdicts, config, idx, timings, more)
