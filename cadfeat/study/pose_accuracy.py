"""results.json ``pose_accuracy``: how well the robot will know the part's pose, before and after (issue 17).

Always computed, whatever the objective, on the real (re-extracted) holes of the original and the delivered
design, along the study's trajectory:

- the predicted error per pose of a single-frame estimate (``measures.pose_information``, the calibrated
  detection and measurement models, each rim's hidden fraction from the exact ray test against the part's mesh
  ``measures.rim_occlusion``): translation (mm) and rotation (deg), the bias part (the detector's systematic
  offsets propagated through the pose Jacobians) and the noise part (the Cramér–Rao bound) separately, with
  their RMS and worst over the poses;
- the IEKF's posterior CRLB along the trajectory (``vision.posterior_crlb``) with the study's filter tuning
  (``[tracking]``, the vision defaults when the study has none), noise only, zero angular rate in F;
- the weakest direction in words per phase of the path (the trajectory split into 3 equal phases; the most
  frequent ``weakest_words`` of the phase's poses and the median standard deviation along it, mm at ℓ);
- each hole's mean share of the information (tr(S I S), ``PoseInformation.share``), by hole name;
- "what would help most": for each movable hole, central finite differences of the predicted RMS translation
  error (mm) on the hole's features — its centre moved in its face's plane (the steepest-descent direction of
  the two in-plane axes, mm of error per mm of move) and its radius (mm per mm) — with each rim's hidden
  fraction held at the design's exact value (the step is 0.25 mm; occlusion changes are not differentiated),
  the same for the RMS rotation error (deg); a movable hole hidden at most poses is probed by real moves
  (``PROBE_MM`` along ± its face's in-plane axes, rim occlusion recomputed), so the answer can be "move it out of
  hiding". The hole and change that lower the translation error most (per mm) are named.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, NotRequired, Protocol, TypedDict, cast

import numpy as np

from cadfeat.cad.export import mesh_from_shape
from cadfeat.cad.features import holes_to_arrays
from cadfeat.cell import Cell
from cadfeat.design.pose_terms import cell_models, designs_glare_rate, hole_kinds
from cadfeat.measures.raycache import cache_rays
from cadfeat.poses import cam_from_part

if TYPE_CHECKING:  # pragma: no cover
    import trimesh
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.camera import Camera
    from cadfeat.measures.evaluate import Measures
    from cadfeat.measures.glare import GlareMaps
    from cadfeat.measures.pose_information import PoseInformation
    from cadfeat.study.schema import StudyConfig
    from cadfeat.study.setup import StudySetup
    from cadfeat.vision import FilterTuning

__all__ = ["PHASES", "design_pose_accuracy", "help_most", "pose_accuracy", "predict", "with_pose"]

PHASES = ("start", "middle", "end")
STEP_MM = 0.25


class Poses(Protocol):
    """What ``with_pose`` reads of a trajectory: the camera poses ``T_task_cam`` (L, 4, 4), mm (a ``Trajectory``,
    or ``cadfeat evaluate``'s one-pose view of one)."""

    @property
    def T_task_cam(self) -> np.ndarray: ...


class Probe(TypedDict):
    """A probe move that brings a hidden hole out of hiding (``help_most``'s ``out_of_hiding``)."""

    distance_mm: float
    direction: list[float]
    d_error_mm: float
    d_rotation_deg: float
    d_error_per_mm: float
    detected_fraction: float


class HoleHelp(TypedDict):
    """``help_most``'s entry for one movable hole: the gradients of the predicted RMS errors (module docstring)."""

    d_error_per_mm_move: float
    move_direction: list[float]
    d_error_per_mm_radius: float
    d_rotation_deg_per_mm_move: float
    d_rotation_deg_per_mm_radius: float
    out_of_hiding: NotRequired[Probe | None]


def _tuning(config: StudyConfig) -> FilterTuning:
    return config.tracking_settings().tuning  # (the filter tuning only: no placement)


def _arrays(holes: Sequence[Hole]) -> tuple[np.ndarray, ...]:
    c, a, r = holes_to_arrays(list(holes))
    through = np.array([bool(h.through) for h in holes])
    depth = np.array([float(h.depth_mm) for h in holes])
    return c, a, r, through, depth


def predict(camera: Camera, T_cam_part: np.ndarray, holes: Sequence[Hole], mesh: trimesh.Trimesh | None,
            rotation_length_mm: float, occlusion: np.ndarray | None = None,
            arrays: tuple[np.ndarray, ...] | None = None, cell: Cell | None = None, glare: GlareMaps | None = None
            ) -> tuple[PoseInformation, np.ndarray]:
    """(``PoseInformation``, rim hidden fraction (L, N)) of ``holes`` at the poses, exact rim test on ``mesh``
    (None: nothing hidden) unless ``occlusion`` is given; ``arrays`` replaces the holes' (c, a, r, through, depth);
    ``cell``: the robot cell (its gate, placement and sensor noise; default ``Cell()``) — g_POSE's own;
    ``glare``: g_POSE's glare maps at these poses (``Problem.glare``, ``measures.glare``), None: none."""
    from cadfeat.measures import pose_information  # lazy: would import scipy.spatial at module load
    from cadfeat.measures.rim_occlusion import rim_occlusion

    c, a, r, through, depth = arrays if arrays is not None else _arrays(holes)
    cell = cell if cell is not None else Cell()
    if occlusion is None:
        occlusion = (np.zeros((len(T_cam_part), len(c))) if mesh is None else
                     rim_occlusion(mesh, T_cam_part, c, a, r, samples=16, through=through, depth_mm=depth))
    info = pose_information(camera, T_cam_part, c, a, r, occlusion=occlusion, through=through,
                            kinds=hole_kinds(holes) if len(holes) == len(c) else None,
                            depth_ratio=depth / (2.0 * np.maximum(r, 1e-9)), rotation_length_mm=rotation_length_mm,
                            model=cell_models(cell), noise_grey=cell.noise_sigma_grey,
                            contrast_rate=_contrast_rate(glare, cell, T_cam_part, c, a, r, through))
    return info, occlusion


def _contrast_rate(glare: GlareMaps | None, cell: Cell, T: np.ndarray, c: np.ndarray, a: np.ndarray, r: np.ndarray,
                   through: np.ndarray) -> np.ndarray | None:
    """(L, N) g_POSE's factor from the part's own light (``design.pose_terms.designs_glare_rate`` of this one
    design) when ``glare`` holds maps of these L poses; else None."""
    if glare is None or glare.n_poses != len(T):
        return None
    return designs_glare_rate(glare, cell, T, c[None], a[None], np.asarray(r, float)[None], through,
                              cell.noise_sigma_grey)


def _rms(v: np.ndarray) -> float:
    v = np.asarray(v, float)
    return float(np.sqrt(np.mean(v * v)))


def _in_plane(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(a, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(a, u)


def help_most(camera: Camera, T_cam_part: np.ndarray, holes: Sequence[Hole], names: Sequence[str],
              movable: Sequence[str], occlusion: np.ndarray, rotation_length_mm: float,
              mesh: trimesh.Trimesh | None = None, cell: Cell | None = None) -> dict[str, object]:
    """Per movable hole: d(RMS translation error)/d(move) along the steepest in-plane direction and
    d/d(radius) (mm per mm, central differences, ``STEP_MM``), the same for the RMS rotation error (deg per mm),
    and the best single change (module docstring). With the part ``mesh``, a hole hidden at most poses (mean
    detection probability < ½: its gradient is zero, since the hidden fraction is held) is also probed by real
    moves of ``PROBE_MM`` in its face's plane with its rim occlusion recomputed: "move it out of hiding"."""
    c0, a0, r0, through, depth = _arrays(holes)

    def errs(c: np.ndarray, r: np.ndarray, occ: np.ndarray = occlusion) -> tuple[float, float, PoseInformation]:
        info, _ = predict(camera, T_cam_part, holes, None, rotation_length_mm, occ, (c, a0, r, through, depth),
                          cell)
        return _rms(info.error_translation_mm), _rms(info.error_rotation_deg), info

    e0, rot0, info0 = errs(c0, r0)
    out: dict[str, HoleHelp] = {}
    for j, name in enumerate(names):
        if name not in movable:
            continue
        u, v = _in_plane(a0[j])
        grad: list[tuple[float, float]] = []
        for d in (u, v):
            cp, cm = c0.copy(), c0.copy()
            cp[j] += STEP_MM * d
            cm[j] -= STEP_MM * d
            ep, em = errs(cp, r0), errs(cm, r0)
            grad.append(((ep[0] - em[0]) / (2 * STEP_MM), (ep[1] - em[1]) / (2 * STEP_MM)))
        g = np.asarray(grad)                                                   # (2 directions, (t, r))
        norm = float(np.linalg.norm(g[:, 0]))
        direction = -(g[0, 0] * u + g[1, 0] * v) / norm if norm > 0 else np.zeros(3)
        rot_norm = float(np.linalg.norm(g[:, 1]))
        rp, rm = r0.copy(), r0.copy()
        rp[j] += STEP_MM
        rm[j] = max(r0[j] - STEP_MM, 1e-3)
        ep, em = errs(c0, rp), errs(c0, rm)
        out[name] = {"d_error_per_mm_move": 0.0 - norm, "move_direction": direction.tolist(),
                     "d_error_per_mm_radius": float((ep[0] - em[0]) / (rp[j] - rm[j])),
                     "d_rotation_deg_per_mm_move": 0.0 - rot_norm,
                     "d_rotation_deg_per_mm_radius": float((ep[1] - em[1]) / (rp[j] - rm[j]))}
        if mesh is not None and float(np.mean(info0.probability[:, j])) < 0.5:
            out[name]["out_of_hiding"] = _out_of_hiding(j, (c0, a0, r0, through, depth), mesh, T_cam_part, occlusion,
                                                        errs, e0, rot0)
    best = None
    for name, d in out.items():
        options = [("move", d["d_error_per_mm_move"]), ("radius", d["d_error_per_mm_radius"])]
        probe = d.get("out_of_hiding")
        if probe:
            options.append(("reveal", probe["d_error_per_mm"]))
        for what, value in options:
            gain = -abs(value) if what == "radius" else value
            if best is None or gain < best[2]:
                best = (name, what, gain, value)
    return {"rms_translation_mm": e0, "rms_rotation_deg": rot0, "step_mm": STEP_MM, "holes": out,
            "best": None if best is None else {"hole": best[0], "change": best[1], "d_error_per_mm": best[3],
                                               "sentence": _sentence(best, out)}}


#: Probe moves (mm) in a hidden hole's face plane, along ± its two in-plane axes ("move it out of hiding").
PROBE_MM = (3.0, 8.0)


def _out_of_hiding(j: int, arrays: tuple[np.ndarray, ...], mesh: trimesh.Trimesh, T: np.ndarray,
                   occlusion: np.ndarray, errs: Callable[[np.ndarray, np.ndarray, np.ndarray],
                                                         tuple[float, float, PoseInformation]],
                   e0: float, rot0: float) -> Probe | None:
    """The probe move of hole j that lowers the predicted RMS translation error most, with its rim occlusion
    recomputed on ``mesh`` (exact ray test, 8 rim samples); None when no probe helps."""
    from cadfeat.measures.rim_occlusion import rim_occlusion  # lazy: would import scipy.spatial at module load

    c0, a0, r0, through, depth = arrays
    u, v = _in_plane(a0[j])
    best: Probe | None = None
    for dist in PROBE_MM:
        for d in (u, -u, v, -v):
            c = c0.copy()
            c[j] = c0[j] + dist * d
            occ = occlusion.copy()
            occ[:, j] = rim_occlusion(mesh, T, c[j:j + 1], a0[j:j + 1], r0[j:j + 1], samples=8,
                                      through=through[j:j + 1], depth_mm=depth[j:j + 1])[:, 0]
            e, rot, info = errs(c, r0, occ)
            if e < e0 and (best is None or (e - e0) / dist < best["d_error_per_mm"]):
                best = {"distance_mm": dist, "direction": d.tolist(), "d_error_mm": e - e0,
                        "d_rotation_deg": rot - rot0, "d_error_per_mm": (e - e0) / dist,
                        "detected_fraction": float(np.mean(info.detected[:, j]))}
    return best


def _sentence(best: tuple[str, str, float, float], holes: Mapping[str, HoleHelp]) -> str:
    name, what, gain, value = best
    if gain >= 0 or not np.isfinite(gain):
        return "No small move or resize of a movable hole lowers the predicted error."
    if what == "reveal":
        r = holes[name].get("out_of_hiding")
        assert r is not None  # (what == "reveal": the probe exists)
        d = np.round(r["direction"], 2).tolist()
        return (f"Moving {name} out of hiding helps most: {r['distance_mm']:g} mm along {d} (part frame) it is "
                f"detected at {100 * r['detected_fraction']:.0f} % of the poses and the predicted RMS error falls by "
                f"{abs(r['d_error_mm']) * 1000:.2f} µm in translation and changes by "
                f"{r['d_rotation_deg'] * 1000:+.2f} mdeg in rotation.")
    if what == "move":
        d = np.round(holes[name]["move_direction"], 2).tolist()
        return (f"Moving {name} (direction {d} in the part frame) helps most: the predicted RMS translation "
                f"error falls by {abs(value) * 1000:.2f} µm per mm of move (rotation "
                f"{holes[name]['d_rotation_deg_per_mm_move'] * 1000:+.2f} mdeg per mm along its own steepest "
                f"direction).")
    verb = "Enlarging" if value < 0 else "Shrinking"
    return (f"{verb} {name} helps most: the predicted RMS translation error falls by {abs(value) * 1000:.2f} µm "
            f"per mm of radius (rotation {holes[name]['d_rotation_deg_per_mm_radius'] * 1000:+.2f} mdeg per mm of "
            f"radius).")


def _phases(info: PoseInformation) -> list[dict[str, object]]:
    words = info.weakest_words
    out: list[dict[str, object]] = []
    for phase, idx in zip(PHASES, np.array_split(np.arange(len(words)), len(PHASES)), strict=True):
        if len(idx) == 0:
            continue
        top, count = Counter(words[int(i)] for i in idx).most_common(1)[0]
        sig = np.asarray(info.weakest_sigma, float)[idx]
        out.append({"phase": phase, "poses": [int(idx[0]), int(idx[-1])], "weakest": top,
                    "fraction": count / len(idx),
                    "sigma_mm": float(np.median(sig)) if np.all(np.isfinite(sig)) else None})
    return out


def _finite(v: np.ndarray) -> list[float | None]:
    return [float(x) if np.isfinite(x) else None for x in np.asarray(v, float)]


def design_pose_accuracy(camera: Camera, T_cam_part: np.ndarray, times_s: np.ndarray, holes: Sequence[Hole],
                         names: Sequence[str], movable: Sequence[str], mesh: trimesh.Trimesh | None,
                         tuning: FilterTuning, rotation_length_mm: float, cell: Cell | None = None,
                         glare: GlareMaps | None = None) -> dict[str, object]:
    """The ``pose_accuracy`` block of one design (module docstring) in the robot cell ``cell`` (``glare``: g_POSE's
    glare maps, ``predict``)."""
    from cadfeat.vision import posterior_crlb  # lazy: would import scipy.spatial at module load

    info, occ = predict(camera, T_cam_part, holes, mesh, rotation_length_mm, cell=cell, glare=glare)
    _, crlb = posterior_crlb(info.information, times_s, tuning)
    per_pose = {"error_translation_mm": info.error_translation_mm, "error_rotation_deg": info.error_rotation_deg,
                "bias_translation_mm": info.bias_translation_mm, "bias_rotation_deg": info.bias_rotation_deg,
                "noise_translation_mm": info.sigma_translation_mm, "noise_rotation_deg": info.sigma_rotation_deg,
                "iekf_translation_mm": crlb[:, 0], "iekf_rotation_deg": crlb[:, 1]}
    share = np.asarray(info.share, float).mean(axis=0)
    return {
        "per_pose": {k: _finite(v) for k, v in per_pose.items()},
        "rms": {k: _rms(v) for k, v in per_pose.items()},
        "worst": {k: float(np.max(v)) for k, v in per_pose.items()},
        "holes_detected_mean": float(np.asarray(info.detected, float).sum(axis=1).mean()),
        "share": dict(zip(names, map(float, share), strict=True)),
        "weakest": _phases(info),
        "help_most": help_most(camera, T_cam_part, holes, names, movable, occ, rotation_length_mm, mesh, cell),
    }


def pose_accuracy(config: StudyConfig, base: StudySetup, holes0: Sequence[Hole], mesh0: trimesh.Trimesh | None,
                  setup: StudySetup | None = None, holes1: Sequence[Hole] | None = None,
                  mesh1: trimesh.Trimesh | None = None) -> dict[str, object]:
    """results.json ``pose_accuracy``: the original (``base``, ``holes0``) and the delivered design (``setup``,
    ``holes1``; None: the original only, ``cadfeat evaluate``), each with its own part mesh for the rim test
    (module docstring)."""
    from cadfeat.cad.features.identity import hole_names  # lazy: would import scipy.optimize at module load

    tuning = _tuning(config)
    ell = float(config.objective.pose_rotation_length_mm)
    movable = [n for n, fixed in zip(base.hole_names, base.problem.fixed_mask, strict=True) if not fixed]
    out: dict[str, object] = {
        "model": "measures.pose_information (calibrated detection and measurement models, exact rim occlusion); "
                 "IEKF: vision.posterior_crlb with the [tracking] filter tuning",
        "times_s": [float(t) for t in base.trajectory.times_s],
        "phases": list(PHASES), "rotation_length_mm": ell, "movable": movable,
        "tuning": {"r_px2": tuning.r_px2, "q_rate_mm2_s2": tuning.q_rate_mm2_s2,
                   "q_omega_rad2_s2": tuning.q_omega_rad2_s2},
    }
    designs = [("before", base, holes0, mesh0)] + ([("after", setup, holes1, mesh1)]
                                                   if setup is not None and holes1 is not None else [])
    for key, s, holes, mesh in designs:
        T = cam_from_part(s.trajectory.T_task_cam, s.T_task_part)
        out[key] = design_pose_accuracy(s.camera, T, np.asarray(s.trajectory.times_s, float), holes,
                                        hole_names(list(holes)), movable, mesh, tuning, ell, config.cell,
                                        getattr(getattr(s, "problem", None), "glare", None))
    return out


def part_mesh(config: StudyConfig, shape: Shape, mesh: trimesh.Trimesh | None = None) -> trimesh.Trimesh:
    """The part mesh for the rim test: ``mesh`` when the study built one, else one of ``shape`` (the pose
    prediction always tests occlusion, even when ``objective.occlusion`` is off)."""
    if mesh is not None:
        return mesh

    return cache_rays(mesh_from_shape(shape, tolerance=0.05))


class _MeasuresWithPose:
    """``measures`` with ``pose`` attached (read by ``objectives.objective_values``)."""

    def __init__(self, measures: Measures, pose: PoseInformation):
        self._m, self.pose = measures, pose

    def __getattr__(self, name: str) -> Any:  # (the measures' arrays, as ``Measures`` has them)
        return getattr(self._m, name)


def with_pose(setup: StudySetup, holes: Sequence[Hole], trajectory: Poses, measures: Measures,
              mesh: trimesh.Trimesh | None = None) -> Measures:
    """``measures`` of ``holes`` along ``trajectory`` with their ``PoseInformation`` attached as ``pose``: the
    exact rim test against ``mesh`` (default the set-up's part mesh, as
    ``Problem.features_objectives(exact_occlusion=True)``)."""
    T = cam_from_part(trajectory.T_task_cam, setup.T_task_part)
    mesh = mesh if mesh is not None else getattr(setup.problem, "occlusion_mesh", None)
    info, _ = predict(setup.camera, T, holes, mesh, float(setup.config.objective.pose_rotation_length_mm),
                      cell=setup.config.cell, glare=setup.problem.glare)
    return cast("Measures", _MeasuresWithPose(measures, info))  # (a Measures in all but its class)
