"""Calibrate the detection and measurement models (``cadfeat.measures.pose_models``) on the closed loop's detector.

Renders a 60×60×5 mm plate with one hole over a grid of causes — with the raster renderer (``vision.images``,
holes painted dark) or the physically based one (``render.pbr``, Mitsuba 3: the cell's ``--material``,
``--light`` and ``--hole-ends``, ``--spp`` samples per pixel, metered exposure as
``TrackingConfig.render_options``) — adds the thin-lens blur (a pillbox of the given diameter) and the sensor
noise (2 grey levels) over several noise seeds, runs ``vision.detectors.detect`` (``--detector``: cadfeat's
rim-edge detector by default, the closed loop's; its prior the exact rim ellipse at the NOMINAL pose, as the loop
predicts it, while the plate sits at a placement off it) + ``associate`` against that predicted rim, and writes
one row per condition: detection rate, mean offset (px, from the rim at the placed pose, and its component along
the image direction of the hole axis), centre noise σ (px, per axis), the found ellipse's size over the rim's
(``scale``: a chamfered rim's bore edge would give bore / rim) and the causes (view angle, minor axis, rim
length, blur, depth/diameter, through, chamfer, hidden fraction of the rim). The models are then fitted to the
table (least squares on the rate, on log σ and on the offset; in the physically based world also the flat-floor
term and the unexplained offset ``offset_rms_px``, ``pose_models``' docstring) and both are written as package
data, one pair per world (``pose_models.model_key``):

    cadfeat/measures/data/detection_calibration_<key>.csv   the measured table
    cadfeat/measures/data/detection_model_<key>.json        the fitted ``PoseModels``

``--detector threshold`` (``detection.detect_holes``, raster) rewrites the original pair
``detection_calibration.csv`` / ``detection_model.json`` (``default_models()``).

Grid (coarse, a few minutes on one core): 3 radii × 3 hole kinds (blind shallow, blind deep, through) × 5 view
angles × 2 distances = 90 conditions, each rendered at ``PLACEMENTS`` = 6 placements of the plate (shifted and
turned within a cell's placement tolerance, so each rim falls on different sub-pixel phases) with 3 blurs × 3
noise seeds per placement: the mean offset over placements is the systematic part, the spread of the
per-placement offsets the pixel-grid ("aliasing") part ``alias_px`` — the closed loop's run-to-run placement
jitter (``vision.closed_loop``) draws the same; plus 5 partial-occlusion renders (a wall whose edge covers part
of the rim; one placement, 12 seeds) and a large-rim band (``LARGE_RADII`` through holes, 48 conditions: rims of
90–450 px, where the systematic offset of an oblique rim stands out of the pixel-grid scatter). The offset fit
weights each row by the uncertainty of its mean offset (pixel-grid scatter over the placements, noise over the
draws). Rim-edge detectors on the raster add the two chamfered kinds of the PBR grid (551 conditions).

PBR grid (``PBR_RADII`` …, 401 conditions): 2 bore radii × 5 kinds (blind d/D 0.3 and 1.0, through, and blind
d/D 0.5 with a 45° rim chamfer of 0.3 or 1.0 mm) × the same 5 angles × 2 distances, at ``PBR_PLACEMENTS`` = 4
placements (cut from 6: each is a path-traced frame), 3 blurs × 3 noise seeds per placement; the occlusion,
large-rim and contrast bands as the raster's (their 6 / 10 / 16 mm rims at 4 placements). 16 spp is the closed
loop's: at 8 spp the glossy face's path-tracing noise alone fails the detector (a Ø 12 through hole at 15° on
machined aluminium: 0 of 6 found at 8 spp, 5 of 6 at 16, 6 of 6 at 64), and at 16 spp one frame's render
noise still flips marginal conditions (a Ø 3.6 blind hole, d/D 1.2, at 20°: found in frames of seed 0 and 5,
not 77) — a rate is worth about one bit per placement. Measured run times on the shared, loaded 2-core machine:
raster 76 s; PBR 96 s at 8 spp alone, 337–527 s at 16 spp with two calibrations at once (load 6–10).

Run: ``python tools/calibrate_detection.py [--renderer pbr --material NAME --light KIND --hole-ends ENDS]``
(``--quick`` for a smaller grid, no files written; ``--refit`` refits the world's committed table;
``--validate`` renders the held-out conditions ``HELD_OUT`` and compares them with the world's committed model).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cadfeat.camera import Camera  # noqa: E402
from cadfeat.measures.pose_models import DEEP_RATIO, SHALLOW_RATIO, PoseModels, hole_geometry, model_key  # noqa: E402

DATA = ROOT / "cadfeat" / "measures" / "data"
CAMERA = Camera(fx=800.0, fy=800.0, cx=160.0, cy=120.0, width=320, height=240, focus_distance_mm=300.0)
NOISE_GREY = 2.0
RADII = (1.5, 3.0, 5.0)
KINDS = (("blind", 0.3), ("blind", 1.0), ("through", 5.0 / 6.0))   # (kind, depth / diameter)
ANGLES_DEG = (0.0, 25.0, 45.0, 60.0, 72.0)
DISTANCES = (300.0, 520.0)
BLURS_PX = (0.0, 2.0, 4.0)
#: Large rims (through the 5 mm plate: depth/diameter 5/(2r)), rims of 90–450 px: where the pixel-grid term is
#: small, the systematic offset of an oblique rim shows (with the small rims' 6 placements it is within their
#: pixel-grid scatter). Rendered after the grid and the occlusion rows, so those keep their placement seeds.
LARGE_RADII = (6.0, 10.0, 16.0)
LARGE_ANGLES_DEG = (0.0, 30.0, 50.0, 65.0)
LARGE_DISTANCES = (300.0, 180.0)
LARGE_BLURS_PX = (0.0, 2.0)
#: Interior-contrast band: rims of 80–330 px (little pixel-grid scatter) at small view angles, blind
#: (the lit floor shows past the rim) and through (the black background shows): the grey just inside an oblique
#: rim differs between the wall's side and the other (``pose_models.interior_contrast``). Rendered last.
CONTRAST_RADII = (6.0, 10.0)
CONTRAST_KINDS = (("blind", 0.2), ("through", 0.0))   # blind: 2.4 and 4 mm deep in the 5 mm plate
CONTRAST_ANGLES_DEG = (8.0, 15.0, 22.0)   # none of the other grids' angles: a re-run replaces them
CONTRAST_DISTANCES = (300.0, 180.0)
CONTRAST_SEED = 1000
SEEDS = 12
#: Placements per condition: the plate shifted in its plane by U(±0.6 mm) and turned by U(±3°) about its normal
#: (the cell's placement tolerance moves each rim over sub-pixel phases): the mean offset over placements is the
#: systematic part, their spread the pixel-grid ("aliasing") part; ``SEEDS_PER_PLACEMENT`` noise draws each.
PLACEMENTS = 6
SEEDS_PER_PLACEMENT = 3
FIELDS = ("radius_mm", "kind", "depth_ratio", "through", "angle_deg", "distance_mm", "blur_px", "hidden",
          "minor_px", "rim_px", "facing", "margin_px", "rate", "offset_u_px", "offset_v_px", "offset_axis_px",
          "sigma_px", "draws", "alias_px", "placements", "chamfer_mm", "scale")
#: Association gate (px) of the calibration's detections to the hole's predicted rim (the default cell's).
GATE_PX = 10.0

#: The PBR grid (``--renderer pbr``): smaller than the raster one (a loaded 2-core machine, ≤ ~20 min): 2 radii
#: (bore) × 5 hole kinds (blind shallow / deep, through, and two 45° rim chamfers 0.3 and 1.0 mm on a blind
#: bore of depth/diameter 0.5) × 5 view angles × 2 distances, ``PBR_PLACEMENTS`` = 4 placements × 3 blurs × 3
#: noise seeds; the large-rim and interior-contrast bands at 4 placements; the occlusion rows as the raster's.
PBR_RADII = (1.5, 3.0)
PBR_KINDS = (("blind", 0.3, 0.0), ("blind", 1.0, 0.0), ("through", 5.0 / 6.0, 0.0), ("blind", 0.5, 0.3),
             ("blind", 0.5, 1.0))
PBR_PLACEMENTS = 4


@dataclass(frozen=True)
class World:
    """What renders and what detects: the renderer (raster | pbr), the detector (``vision.detectors``, or
    ``"threshold"``: ``detection.detect_holes``, the committed ``detection_model.json``'s), and for pbr the
    cell's material, light kind, hole ends and samples per pixel (metered exposure, as the closed loop)."""

    renderer: str = "raster"
    detector: str = "cadfeat"
    material: str = "machined_aluminium"
    light: str = "ring"
    hole_ends: str = "as_modelled"
    spp: int = 16

    def key(self) -> str:
        """The model file's key (``pose_models.model_key``)."""
        return model_key(self.detector, self.renderer, self.material, self.light, self.hole_ends)


WORLD = World()


def plate(radius: float, kind: str, depth_ratio: float, wall: float | None = None, chamfer: float = 0.0):
    """The test plate (hole of bore ``radius`` mm at the origin, axis +z, top face z = 0), optionally with a 45°
    rim chamfer ``chamfer`` mm wide (the rim then has radius ``radius + chamfer``; a cone cut as
    ``parts/nema17_mount.py`` cuts its targets') and a 4 mm wall of height ``wall`` (mm) standing at x in
    [−10, −6], between the hole and the camera, to hide part of the rim."""
    import cadquery as cq

    wp = cq.Workplane("XY").box(60, 60, 5).translate((0, 0, -2.5))
    if kind == "through":
        wp = wp.faces(">Z").workplane().hole(2 * radius)
    else:
        wp = wp.faces(">Z").workplane().hole(2 * radius, depth_ratio * 2 * radius)
    if chamfer > 0:
        out = 0.1   # the cone starts above the face, so its cut meets the face at radius + chamfer exactly
        wp = wp.cut(cq.Solid.makeCone(radius + chamfer + out, radius, chamfer + out, cq.Vector(0, 0, out),
                                      cq.Vector(0, 0, -1)))
    if wall is not None:
        wp = wp.union(cq.Workplane("XY").box(4, 60, wall).translate((-8.0, 0, 0.5 * wall)))
    return wp


def pose(angle_deg: float, distance_mm: float, azimuth_deg: float = 180.0) -> np.ndarray:
    from cadfeat.poses import invert_T, look_at

    a, b = np.radians(angle_deg), np.radians(azimuth_deg)
    eye = distance_mm * np.array([np.sin(a) * np.cos(b), np.sin(a) * np.sin(b), np.cos(a)])
    up = (0.0, 1.0, 0.0)
    return invert_T(look_at(eye, np.zeros(3), up=up))


def detect_rim(frame: np.ndarray, predicted: Any) -> tuple[np.ndarray, float]:
    """The centre (2,) px of the hole's rim found in ``frame`` (NaN: none associated) by ``WORLD.detector``
    with ``predicted`` (the rim ellipse at the nominal pose) as its prior and association target, and the
    found ellipse's mean axis (px; NaN when none)."""
    from cadfeat.vision.detection import associate, detect_holes
    from cadfeat.vision.detectors import detect

    if WORLD.detector == "threshold":
        d = detect_holes(frame)
    else:
        d = detect(WORLD.detector, frame, camera=CAMERA, predicted=predicted,
                   point_sampled=WORLD.renderer == "raster")
    z = associate(predicted, d, gate_px=GATE_PX)[0]
    if not np.all(np.isfinite(z)) or len(d.centre_px) == 0:
        return z, float("nan")
    j = int(np.argmin(np.linalg.norm(np.asarray(d.centre_px) - z, axis=1)))
    return z, float(np.mean(np.asarray(d.axes_px)[j]))


def measure_condition(images: np.ndarray, hole, T: np.ndarray, blur: float, seeds: int,
                      T_nominal: np.ndarray | None = None) -> dict[str, float]:
    """Detection statistics of one clean render (the part at ``T``) under blur and ``seeds`` noise draws: the
    detector's prior and the association use the rim at ``T_nominal`` (default ``T``; the closed loop's
    nominal pose), the offsets are from the rim at ``T``; ``scale`` the found ellipse's mean axis over the
    rim's (a chamfered rim's inner edge: bore / rim radius)."""
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.measures import hole_ellipse
    from cadfeat.vision.images import _disk_kernel, apply_optics, sensor_images

    c, n, r = holes_to_arrays([hole])
    Tn = T if T_nominal is None else T_nominal
    e = hole_ellipse(CAMERA, c @ T[:3, :3].T + T[:3, 3], n @ T[:3, :3].T, r)
    prior = hole_ellipse(CAMERA, c @ Tn[:3, :3].T + Tn[:3, 3], n @ Tn[:3, :3].T, r)
    optical = apply_optics(images, [_disk_kernel(blur)])
    found, sizes = [], []
    for s in range(seeds):
        frame = sensor_images(optical, NOISE_GREY, 1000 + s)[0]
        z, size = detect_rim(frame, prior)
        if np.all(np.isfinite(z)):
            found.append(z - e.centre_px[0])
            sizes.append(size)
    geo = hole_geometry(CAMERA, T[None], c, n, r)
    d = np.asarray(found)
    row = {"rate": len(found) / seeds, "draws": seeds, "minor_px": float(geo.minor_px[0, 0]),
           "rim_px": float(geo.rim_px[0, 0]), "facing": float(geo.facing[0, 0]),
           "margin_px": float(geo.margin_px[0, 0]),
           "scale": float(np.nanmean(sizes) / np.mean(e.axes_px[0])) if sizes else float("nan")}
    if len(d) >= 3:
        mean = d.mean(axis=0)
        row.update(offset_u_px=float(mean[0]), offset_v_px=float(mean[1]),
                   offset_axis_px=float(mean @ geo.axis_dir_px[0, 0]),
                   sigma_px=float(np.sqrt(0.5 * np.sum(d.var(axis=0, ddof=1)))))
    else:
        row.update(offset_u_px=np.nan, offset_v_px=np.nan, offset_axis_px=np.nan, sigma_px=np.nan)
    return row


def placements(T: np.ndarray, count: int | None = None, seed: int = 0) -> np.ndarray:
    """(count, 4, 4) T · δ_k: the plate shifted in its plane and turned about its normal (``PLACEMENTS``, the
    default count)."""
    from cadfeat.vision.motion import so3_exp

    count = PLACEMENTS if count is None else count
    rng = np.random.default_rng([seed, 17])
    out = np.tile(np.eye(4), (count, 1, 1))
    out[:, :2, 3] = rng.uniform(-0.6, 0.6, (count, 2))
    out[:, :3, :3] = [so3_exp(np.array([0.0, 0.0, np.radians(a)])) for a in rng.uniform(-3.0, 3.0, count)]
    return T[None] @ out


def measure_placements(images: np.ndarray, hole, Ts: np.ndarray, blur: float,
                       seeds: int = SEEDS_PER_PLACEMENT, T_nominal: np.ndarray | None = None) -> dict[str, float]:
    """Detection statistics of one condition over placements (``placements``): rate over all draws, the mean
    offset over placements (systematic), the noise σ (pooled within placements, per axis) and the pixel-grid
    RMS per axis (the spread of the per-placement mean offsets, less their noise share σ²/seeds). The detector's
    prior is the rim at ``T_nominal`` (each placement's own pose when None)."""
    rows = [measure_condition(images[k:k + 1], hole, Ts[k], blur, seeds, T_nominal) for k in range(len(Ts))]
    means = np.array([[r["offset_u_px"], r["offset_v_px"]] for r in rows])
    ok = np.all(np.isfinite(means), axis=1)
    geo = rows[0]
    out = {"rate": float(np.mean([r["rate"] for r in rows])), "draws": seeds * len(Ts),
           "minor_px": geo["minor_px"], "rim_px": geo["rim_px"], "facing": geo["facing"],
           "margin_px": geo["margin_px"], "placements": int(ok.sum()),
           "scale": float(np.nanmean([r["scale"] for r in rows])) if np.any(ok) else float("nan")}
    if ok.sum() >= 3:
        from cadfeat.cad.features import holes_to_arrays

        c, n, r = holes_to_arrays([hole])
        axis = hole_geometry(CAMERA, Ts[:1], c, n, r).axis_dir_px[0, 0]
        mean = means[ok].mean(axis=0)
        sig = float(np.sqrt(np.mean([r["sigma_px"] ** 2 for r, g in zip(rows, ok, strict=True) if g])))
        spread = 0.5 * np.sum(means[ok].var(axis=0, ddof=1))
        out.update(offset_u_px=float(mean[0]), offset_v_px=float(mean[1]), offset_axis_px=float(mean @ axis),
                   sigma_px=sig, alias_px=float(np.sqrt(max(spread - sig ** 2 / seeds, 0.0))))
    else:
        out.update(offset_u_px=np.nan, offset_v_px=np.nan, offset_axis_px=np.nan, sigma_px=np.nan, alias_px=np.nan)
    return out


def render(shape, holes, T: np.ndarray) -> np.ndarray:
    """(1, H, W) noiseless grey of ``WORLD``'s renderer at pose ``T``."""
    return render_many(shape, holes, T[None])


def render_many(shape, holes, Ts: np.ndarray, seed: int = 0) -> np.ndarray:
    """(F, H, W) noiseless grey 0 … 255 of ``WORLD``'s renderer at poses ``Ts`` (F, 4, 4): the raster's, or the
    physically based one with the world's light, material, hole ends and spp, metered exposure
    (``TrackingConfig.render_options``); ``seed`` the path tracer's first frame seed."""
    if WORLD.renderer == "raster":
        from cadfeat.vision.images import render_sequence

        return render_sequence(shape, holes, CAMERA, Ts)
    from cadfeat.cell.light import Light
    from cadfeat.cell.material import Material
    from cadfeat.render.pbr import PbrRenderer
    from cadfeat.render.sensor import Sensor

    with PbrRenderer(shape, holes, CAMERA, light=Light(kind=WORLD.light), material=Material(name=WORLD.material),
                     sensor=Sensor(exposure="meter"), spp=WORLD.spp, hole_ends=WORLD.hole_ends,
                     seed=seed) as r:
        return np.stack([r.render_grey(T) for T in Ts]).astype(np.float32)


def run_grid(radii=RADII, kinds=KINDS, angles=ANGLES_DEG, distances=DISTANCES, blurs=BLURS_PX,
             seeds=SEEDS_PER_PLACEMENT, occlusion=True, large=True, contrast=True, seed0=0) -> list[dict]:
    """The table's rows (module docstring): ``kinds`` of (kind, depth/diameter[, chamfer mm]); each condition at
    ``PLACEMENTS`` placements with the detector's prior at the nominal pose (the closed loop's)."""
    from cadfeat.cad.features import extract_holes
    from cadfeat.measures.rim_occlusion import rim_occlusion

    rows = []
    for radius in radii:
        for kind, ratio, *cham in kinds:
            chamfer = float(cham[0]) if cham else 0.0
            wp = plate(radius, kind, ratio, chamfer=chamfer)
            holes = [h for h in extract_holes(wp) if np.linalg.norm(h.centre[:2]) < 1e-6]
            rim = float(holes[0].radius_mm)   # the rim the camera sees: bore + chamfer
            for angle in angles:
                for dist in distances:
                    T0 = pose(angle, dist)
                    Ts = placements(T0, seed=seed0 + len(rows))
                    images = render_many(wp.val(), holes, Ts, seed=seed0 + len(rows))
                    for blur in blurs:
                        # what was rendered: a "blind" hole deeper than the 5 mm plate is a through hole
                        thr = bool(holes[0].through)
                        row = {"radius_mm": rim, "kind": "through" if thr else kind, "through": thr,
                               "depth_ratio": float(holes[0].depth_mm) / (2 * rim), "chamfer_mm": chamfer,
                               "angle_deg": angle, "distance_mm": dist, "blur_px": blur, "hidden": 0.0}
                        row.update(measure_placements(images, holes[0], Ts, blur, seeds, T0))
                        rows.append(row)
    if occlusion:
        from cadfeat.cad.export import mesh_from_shape

        for wall in (2.6, 3.2, 3.8, 4.6, 5.4):
            wp = plate(3.0, "blind", 0.3, wall)
            holes = [h for h in extract_holes(wp) if np.linalg.norm(h.centre[:2]) < 1e-6]
            T = pose(50.0, 300.0)  # the camera 40° above the plate, on the wall's side
            from cadfeat.cad.features import holes_to_arrays

            c, n, r = holes_to_arrays(holes)
            hidden = float(rim_occlusion(mesh_from_shape(wp.val(), tolerance=0.05), T[None], c, n, r, samples=32)[0, 0])
            images = render(wp.val(), holes, T)
            row = {"radius_mm": 3.0, "kind": "blind", "depth_ratio": 0.3, "through": False, "angle_deg": 50.0,
                   "distance_mm": 300.0, "blur_px": 0.0, "hidden": hidden, "chamfer_mm": 0.0}
            row.update(measure_condition(images, holes[0], T, 0.0, 12), alias_px=np.nan, placements=1)
            rows.append(row)
    if large:
        rows += run_grid(radii=LARGE_RADII, kinds=(("through", 0.0),), angles=LARGE_ANGLES_DEG,
                         distances=LARGE_DISTANCES, blurs=LARGE_BLURS_PX, seeds=seeds, occlusion=False, large=False,
                         contrast=False)
    if contrast:
        rows += contrast_grid(seeds)
    return rows


def contrast_grid(seeds: int = SEEDS_PER_PLACEMENT) -> list[dict]:
    """The interior-contrast band (``CONTRAST_RADII`` …): its own placement seeds (``CONTRAST_SEED``)."""
    return run_grid(radii=CONTRAST_RADII, kinds=CONTRAST_KINDS, angles=CONTRAST_ANGLES_DEG,
                    distances=CONTRAST_DISTANCES, blurs=LARGE_BLURS_PX, seeds=seeds, occlusion=False, large=False,
                    contrast=False, seed0=CONTRAST_SEED)


def study_grid(path: Path) -> list[dict]:
    """The grid with a study's camera, its trajectory's depth range and its holes' radii (up to 3)."""
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.poses import invert_T
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_study

    global CAMERA
    setup = setup_study(load_study(path))
    CAMERA = setup.camera
    T = invert_T(np.asarray(setup.trajectory.T_task_cam)) @ setup.T_task_part
    c, _, r = holes_to_arrays(setup.holes0)
    depth = float(np.median((c @ T[:, :3, :3].transpose(0, 2, 1) + T[:, None, :3, 3])[..., 2]))
    radii = tuple(float(v) for v in np.quantile(np.unique(np.round(r, 1)), [0.0, 0.5, 1.0]))
    return run_grid(radii=tuple(sorted(set(radii))), distances=(0.85 * depth, 1.15 * depth))


# ------------------------------------------------------------------------------------------------ fitting
def _arrays(rows: list[dict]) -> dict[str, np.ndarray]:
    def num(v: object) -> float:
        if v is None or v == "":
            return float("nan")
        return float(v in (True, "True")) if v in (True, False, "True", "False") else float(v)
    return {k: np.array([num(r.get(k)) for r in rows]) for k in FIELDS if k != "kind"}


def fit(rows: list[dict], floor: bool | None = None) -> PoseModels:
    """Least-squares fits of the detection rate, log σ and the axis offset (module docstring); ``floor``: fit the
    flat-floor term too (default: in the physically based world, where a blind hole's floor is not painted)."""
    from scipy.optimize import least_squares, nnls

    a = _arrays(rows)
    base = PoseModels()
    clean = a["hidden"] == 0
    floor = WORLD.renderer == "pbr" if floor is None else floor

    def p_model(x, sel):
        m = replace(base, m0_px=x[0], w_m_px=x[1], kappa_blur=x[2], c0=x[3], w_c=x[4],
                    floor_q0=x[5] if floor else 0.0, floor_w_q=x[6] if floor else 0.0)
        return _geo_p(m, a, sel)

    sel = clean
    x0, lo, hi = [4.0, 0.7, 0.3, 0.2, 0.05], [0.5, 0.1, 0.0, -0.5, 0.01], [20.0, 5.0, 2.0, 0.9, 0.5]
    if floor:   # the flat-floor term's q₀ and width (module docstring of pose_models, "Flat floors")
        x0, lo, hi = x0 + [0.2, 0.05], lo + [-0.5, 0.01], hi + [3.0, 1.0]
    r = least_squares(lambda x: p_model(x, sel) - a["rate"][sel], x0, bounds=(lo, hi))
    m0, w_m, kappa, c0, w_c = r.x[:5]
    q0, w_q = (float(r.x[5]), float(r.x[6])) if floor else (0.0, 0.0)
    ok = clean & np.isfinite(a["sigma_px"]) & (a["sigma_px"] > 0) & (a["rate"] >= 0.5)   # σ = 0: quantised centres
    rho, blur, sig = a["rim_px"][ok], a["blur_px"][ok], a["sigma_px"][ok]

    def s_model(x):
        return np.sqrt(x[0] ** 2 + (x[1] ** 2 * (x[2] ** 2 + blur ** 2)) / rho)

    rs = least_squares(lambda x: np.log(s_model(x)) - np.log(sig), [0.01, 1.0, 1.0],
                       bounds=([1e-4, 1e-3, 0.1], [1.0, 20.0, 10.0]))
    s0, k_s, w0 = np.abs(rs.x)
    sin_t = np.sqrt(np.clip(1 - a["facing"][ok] ** 2, 0, 1))
    D = np.where(a["through"][ok] > 0, 1.0, 0.5)
    from cadfeat.measures.pose_models import interior_contrast

    contrast = np.sqrt(w0 ** 2 + blur ** 2) * interior_contrast(a["facing"][ok], a["depth_ratio"][ok],
                                                                a["through"][ok] > 0, a["minor_px"][ok])
    A = np.column_stack([blur * sin_t, sin_t, D * sin_t * np.minimum(a["depth_ratio"][ok], 2.0), contrast])
    # weighted by the uncertainty of each row's mean offset: its pixel-grid scatter over the placements and its
    # noise over the draws (per axis); the large rims, with little pixel-grid scatter, carry the constant term
    n_pl = np.maximum(np.nan_to_num(a["placements"][ok], nan=1.0), 1.0)
    alias_row = np.nan_to_num(a["alias_px"][ok], nan=0.0) if "alias_px" in a else np.zeros(len(sig))
    var = alias_row ** 2 / n_pl + sig ** 2 / np.maximum(a["draws"][ok], 1.0) + 1e-4 ** 2
    wgt = 1.0 / np.sqrt(np.where(np.isfinite(a["alias_px"][ok]), var, np.inf)) if "alias_px" in a else \
        np.ones(len(sig))
    use = np.isfinite(a["offset_axis_px"][ok]) & (wgt > 0)
    (k_b, k_w, k_d, k_i), *_ = np.linalg.lstsq(A[use] * wgt[use, None], a["offset_axis_px"][ok][use] * wgt[use],
                                               rcond=None)
    # the pixel-grid error: per-axis RMS √(a² + k_a²/ρ) of the offsets over placements (``alias_px``); a table
    # without placements (older) falls back to what the systematic offset leaves of the one placement's offset
    if "alias_px" in a and (np.isfinite(a["alias_px"][ok]) & (a["alias_px"][ok] > 0)).sum() >= 10:
        # in log space, like σ (each value is an RMS over 6 placements, ±25 %: relative errors): the fit gives
        # a = 0 — the 1/√ρ law of a least-squares ellipse through ρ points with independent staircase errors
        fin = np.isfinite(a["alias_px"][ok]) & (a["alias_px"][ok] > 0)
        al, rho_a = a["alias_px"][ok][fin], rho[fin]
        ra = least_squares(lambda x: 0.5 * np.log(x[0] ** 2 + x[1] ** 2 / rho_a) - np.log(al), [0.02, 0.3],
                           bounds=([0.0, 0.01], [0.2, 3.0]))
        alias_floor, k_alias = (float(v) for v in ra.x)
    else:
        resid2 = 0.5 * np.maximum(a["offset_u_px"][ok] ** 2 + a["offset_v_px"][ok] ** 2
                                  - (A @ np.array([k_b, k_w, k_d, k_i])) ** 2, 0.0)    # per-axis squared residual
        (floor2, ka2), _ = nnls(np.column_stack([np.ones(len(rho)), 1.0 / rho]), resid2)
        k_alias, alias_floor = float(np.sqrt(ka2)), float(np.sqrt(floor2))
    # occlusion: the raw detector accepts rims cut by an edge of the same grey (a wall's top face over the
    # plate) up to ~30 % hidden, with centre offsets up to ~1 px (the table's hidden > 0 rows); the closed
    # loop therefore drops every hole whose predicted rim is more than RIM_HIDDEN_MAX hidden, and the model
    # describes that pipeline: p falls to 0 past RIM_HIDDEN_MAX
    from cadfeat.vision.closed_loop import RIM_HIDDEN_MAX

    o0 = float(RIM_HIDDEN_MAX)
    off_fit = np.zeros(len(rows))
    off_fit[np.flatnonzero(ok)] = A @ np.array([k_b, k_w, k_d, k_i])
    measured = ok & np.isfinite(a["offset_axis_px"])
    cham = np.nan_to_num(a["chamfer_mm"], nan=0.0) > 0
    blind = a["through"] == 0
    described = measured & ~cham & (~blind | (a["depth_ratio"] >= DEEP_RATIO - 1e-9))
    shallow = measured & ~cham & blind & (a["depth_ratio"] <= SHALLOW_RATIO + 1e-9)
    unexplained = offset_unexplained_px(a, described, off_fit)
    by_class = {"offset_rms_shallow_px": offset_unexplained_px(a, shallow, off_fit) if shallow.any() else None,
                "offset_rms_chamfer_px": offset_unexplained_px(a, measured & cham, off_fit)
                if (measured & cham).any() else None}
    return replace(base, offset_rms_px=unexplained, **by_class, m0_px=float(m0), w_m_px=float(w_m),
                   kappa_blur=float(kappa),
                   c0=float(c0), w_c=float(w_c), sigma0_px=float(s0), k_sigma=float(k_s), w0_px=float(w0),
                   k_b=float(k_b), k_d=float(k_d), k_w_px=float(k_w), k_i=float(k_i),
                   k_alias_px=k_alias, alias_floor_px=alias_floor,
                   o0=o0, floor_q0=q0, floor_w_q=w_q,
                   source=f"tools/calibrate_detection.py: {len(rows)} rendered conditions, noise {NOISE_GREY} grey")


def offset_unexplained_px(a: dict[str, np.ndarray], ok: np.ndarray, fitted_axis_px: np.ndarray) -> float:
    """Per-axis RMS (px) of the rows' mean offsets that the fitted offset model (``fitted_axis_px``, along the
    hole axis' image direction) leaves, less what each row's mean carries of the pixel-grid scatter and the
    noise (alias²/placements + σ²/draws): the systematic offset the model cannot describe (``offset_rms_px``).
    The residual is the measured offset less the model's along the axis, plus all of the across-axis part."""
    if not ok.any():
        return 0.0
    total2 = a["offset_u_px"][ok] ** 2 + a["offset_v_px"][ok] ** 2
    along = a["offset_axis_px"][ok]
    res2 = (along - fitted_axis_px[ok]) ** 2 + np.maximum(total2 - along ** 2, 0.0)   # both axes
    n_pl = np.maximum(np.nan_to_num(a["placements"][ok], nan=1.0), 1.0)
    noise2 = 2.0 * (np.nan_to_num(a["alias_px"][ok], nan=0.0) ** 2 / n_pl
                    + a["sigma_px"][ok] ** 2 / np.maximum(a["draws"][ok], 1.0))
    return float(np.sqrt(max(0.5 * float(np.mean(res2 - noise2)), 0.0)))


def _geo_p(m: PoseModels, a: dict[str, np.ndarray], sel: np.ndarray) -> np.ndarray:
    """The detection model on the table's recorded causes (same formula as ``PoseModels.detection_probability``)."""
    from cadfeat.measures.pose_models import HoleGeometry

    k = int(sel.sum())
    g = HoleGeometry(a["minor_px"][sel][None], a["minor_px"][sel][None], a["margin_px"][sel][None],
                     a["facing"][sel][None], a["blur_px"][sel][None], a["rim_px"][sel][None], np.zeros((1, k, 2)),
                     np.ones((1, k), bool), np.ones((1, k), bool))
    if "depth_ratio" not in a or "through" not in a:   # a table without the hole's depth: no flat-floor term
        return m.detection_probability(g, a["hidden"][sel][None])[0]
    return m.detection_probability(g, a["hidden"][sel][None], depth_ratio=a["depth_ratio"][sel][None],
                                   through=a["through"][sel][None] > 0)[0]


def residuals(rows: list[dict], model: PoseModels) -> dict[str, dict[str, float]]:
    """The fit's residuals on its own table, per group (all, plain rims, chamfered rims): the detection rate's
    mean and largest |p − rate| (unoccluded rows), the axis offset's RMS residual (px) and RMS of residual /
    the row mean's uncertainty (z), the noise σ's RMS log-ratio (model / measured, the noise term alone) and the
    pixel-grid term's, and the chamfered rims' found size over the rim's (``scale``; the bore's edge would give
    bore / rim)."""
    from cadfeat.measures.pose_models import HoleGeometry

    a = _arrays(rows)
    n = len(rows)
    g = HoleGeometry(a["minor_px"][None], a["minor_px"][None], a["margin_px"][None], a["facing"][None],
                     a["blur_px"][None], a["rim_px"][None], np.tile([1.0, 0.0], (1, n, 1)), np.ones((1, n), bool),
                     np.ones((1, n), bool))
    p = model.detection_probability(g, a["hidden"][None], depth_ratio=a["depth_ratio"][None],
                                    through=a["through"][None] > 0)[0]
    noise, off = replace(model, k_alias_px=0.0, alias_floor_px=0.0, offset_rms_px=0.0, offset_rms_shallow_px=None,
                         offset_rms_chamfer_px=None).measurement_model(
        g, depth_ratio=a["depth_ratio"][None], through=a["through"][None] > 0, noise_grey=NOISE_GREY)
    alias = np.sqrt(model.alias_floor_px ** 2 + model.k_alias_px ** 2 / np.maximum(a["rim_px"], 1.0))
    cham = np.nan_to_num(a["chamfer_mm"], nan=0.0)
    draws = np.maximum(a["draws"], 1.0)
    n_pl = np.maximum(np.nan_to_num(a["placements"], nan=1.0), 1.0)
    unc = np.sqrt(np.nan_to_num(a["alias_px"], nan=0.0) ** 2 / n_pl + a["sigma_px"] ** 2 / draws + 1e-8)
    out: dict[str, dict[str, float]] = {}
    for name, sel in (("all", np.ones(n, bool)), ("plain", cham == 0), ("chamfered", cham > 0)):
        clean = sel & (a["hidden"] == 0)
        if not clean.any():
            continue
        ok = clean & np.isfinite(a["offset_axis_px"]) & (a["rate"] >= 0.5)
        res = a["offset_axis_px"][ok] - off[0, ok, 0]
        fin = ok & np.isfinite(a["alias_px"]) & (a["alias_px"] > 0)
        pos = ok & (a["sigma_px"] > 0)   # σ = 0: a detector with quantised centres (EDCircles on the raster)
        out[name] = {"rows": int(clean.sum()), "rate_mae": float(np.mean(np.abs(p[clean] - a["rate"][clean]))),
                     "rate_max": float(np.max(np.abs(p[clean] - a["rate"][clean]))),
                     "mean_rate": float(np.mean(a["rate"][clean])),
                     "offset_rms_px": float(np.sqrt(np.mean(res ** 2))) if ok.any() else float("nan"),
                     "offset_z_rms": float(np.sqrt(np.mean((res / unc[ok]) ** 2))) if ok.any() else float("nan"),
                     "sigma_log_rms": float(np.sqrt(np.mean(np.log(noise[0, pos] / a["sigma_px"][pos]) ** 2)))
                     if pos.any() else float("nan"),
                     "alias_log_rms": float(np.sqrt(np.mean(np.log(alias[fin] / a["alias_px"][fin]) ** 2)))
                     if fin.any() else float("nan"),
                     "scale_median": float(np.nanmedian(a["scale"][ok])) if ok.any() else float("nan")}
    return out


#: Held-out conditions (none in a grid: bore radius mm, kind, depth/diameter, chamfer mm, view angle deg, distance
#: mm, blur px) for ``validate`` (``--validate``): the committed model of the world against fresh renders.
HELD_OUT = ((2.2, "blind", 0.6, 0.0, 35.0, 400.0, 1.0), (2.2, "through", 1.0, 0.0, 35.0, 400.0, 1.0),
            (1.2, "blind", 0.8, 0.5, 40.0, 350.0, 0.0), (2.0, "blind", 0.5, 0.7, 15.0, 380.0, 2.0),
            (4.0, "through", 1.0, 0.0, 55.0, 260.0, 1.0), (2.5, "blind", 0.4, 0.0, 10.0, 330.0, 0.0),
            (1.8, "blind", 1.2, 0.0, 20.0, 280.0, 1.0), (2.8, "blind", 0.25, 0.4, 55.0, 420.0, 1.0))


#: Hole positions (mm, plate frame) of ``multi_plate``: 28 mm apart, so no rim comes near another's surround.
MULTI_POSITIONS = ((-14.0, -14.0), (14.0, -14.0), (-14.0, 14.0), (14.0, 14.0))


def multi_plate(specs):
    """The test plate with up to four holes (``MULTI_POSITIONS``), ``specs`` of (bore radius mm, kind,
    depth/diameter, chamfer mm): several held-out conditions in one render. Returns (workplane, holes) in the
    specs' order."""
    import cadquery as cq

    from cadfeat.cad.features import extract_holes

    wp = cq.Workplane("XY").box(60, 60, 5).translate((0, 0, -2.5))
    for (radius, kind, ratio, chamfer), (x, y) in zip(specs, MULTI_POSITIONS, strict=False):
        top = wp.faces(">Z").workplane(centerOption="CenterOfBoundBox").center(x, y)
        wp = top.hole(2 * radius) if kind == "through" else top.hole(2 * radius, ratio * 2 * radius)
        if chamfer > 0:
            wp = wp.cut(cq.Solid.makeCone(radius + chamfer + 0.1, radius, chamfer + 0.1, cq.Vector(x, y, 0.1),
                                          cq.Vector(0, 0, -1)))
    found = [h for h in extract_holes(wp) if abs(h.centre[2]) < 1e-6]
    holes = [min(found, key=lambda h: float(np.hypot(h.centre[0] - x, h.centre[1] - y)))
             for (x, y) in MULTI_POSITIONS[:len(specs)]]
    return wp, holes


def measure_holes(image: np.ndarray, holes, T: np.ndarray, blur: float, seeds: int) -> list[dict[str, float]]:
    """Per hole of one clean render (1, H, W) at pose ``T``: the detection rate over ``seeds`` noise draws and
    the mean axis offset (px), all holes detected at once with their rims at ``T`` as the prior (the closed
    loop's call)."""
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.measures import hole_ellipse
    from cadfeat.vision.detection import associate
    from cadfeat.vision.detectors import detect
    from cadfeat.vision.images import _disk_kernel, apply_optics, sensor_images

    c, n, r = holes_to_arrays(holes)
    e = hole_ellipse(CAMERA, c @ T[:3, :3].T + T[:3, 3], n @ T[:3, :3].T, r)
    geo = hole_geometry(CAMERA, T[None], c, n, r)
    optical = apply_optics(image, [_disk_kernel(blur)])
    z = np.array([associate(e, detect(WORLD.detector, sensor_images(optical, NOISE_GREY, 1000 + s)[0],
                                      camera=CAMERA, predicted=e, point_sampled=WORLD.renderer == "raster"), GATE_PX)
                  for s in range(seeds)])
    found = np.all(np.isfinite(z), axis=-1)                                          # (seeds, N)
    d = np.where(found[..., None], z - np.asarray(e.centre_px)[None], np.nan)
    mean = np.nanmean(np.where(found.any(axis=0)[None, :, None], d, 0.0), axis=0)    # (N, 2)
    return [{"rate": float(found[:, j].mean()),
             "offset_axis_px": float(mean[j] @ geo.axis_dir_px[0, j]) if found[:, j].any() else float("nan")}
            for j in range(len(holes))]


def predict(model: PoseModels, hole, T: np.ndarray, blur: float) -> dict[str, float]:
    """The model's detection probability, axis offset (px) and σ (px, with the pixel-grid term) for ``hole`` at
    pose ``T`` under ``blur`` px (the blur applied to the render, not the focus's)."""
    from cadfeat.cad.features import holes_to_arrays

    c, n, r = holes_to_arrays([hole])
    geo = hole_geometry(CAMERA, T[None], c, n, r)
    geo = geo._replace(blur_px=np.full((1, 1), blur))
    ratio, thr = [float(hole.depth_mm) / (2 * float(hole.radius_mm))], [bool(hole.through)]
    p = float(model.detection_probability(geo, np.zeros((1, 1)), depth_ratio=ratio, through=thr)[0, 0])
    sig, off = model.measurement_model(geo, depth_ratio=ratio, kinds=[hole.kind], through=thr, noise_grey=NOISE_GREY)
    return {"p": p, "offset_axis_px": float(off[0, 0] @ geo.axis_dir_px[0, 0]), "sigma_px": float(sig[0, 0])}


def validate(model: PoseModels, conditions=HELD_OUT) -> list[dict[str, float]]:
    """The held-out ``conditions`` rendered in ``WORLD`` (``PLACEMENTS`` placements, prior at the nominal pose)
    against ``model``: per condition the measured rate and mean axis offset, the model's p and offset, and the
    offset's uncertainty (pixel-grid scatter over the placements and noise over the draws, px)."""
    from cadfeat.cad.features import extract_holes

    out = []
    for k, (radius, kind, ratio, chamfer, angle, dist, blur) in enumerate(conditions):
        wp = plate(radius, kind, ratio, chamfer=chamfer)
        holes = [h for h in extract_holes(wp) if np.linalg.norm(h.centre[:2]) < 1e-6]
        T0 = pose(angle, dist)
        Ts = placements(T0, seed=5000 + k)
        m = measure_placements(render_many(wp.val(), holes, Ts, seed=5000 + k), holes[0], Ts, blur,
                               SEEDS_PER_PLACEMENT, T0)
        pred = predict(model, holes[0], T0, blur)
        unc = np.sqrt(np.nan_to_num(m.get("alias_px", np.nan), nan=0.0) ** 2 / max(m["placements"], 1)
                      + np.nan_to_num(m["sigma_px"], nan=0.0) ** 2 / m["draws"])
        out.append({"radius_mm": float(holes[0].radius_mm), "kind": kind, "chamfer_mm": chamfer, "angle_deg": angle,
                    "distance_mm": dist, "blur_px": blur, "rate": m["rate"], "p": pred["p"],
                    "offset_axis_px": m["offset_axis_px"], "predicted_axis_px": pred["offset_axis_px"],
                    "uncertainty_px": float(unc), "sigma_px": m["sigma_px"], "scale": m["scale"]})
    return out


def model_files(key: str | None) -> tuple[str, str]:
    """(table, model) file names of the world ``key``; None: the committed threshold detector's."""
    if key is None:
        return "detection_calibration.csv", "detection_model.json"
    return f"detection_calibration_{key}.csv", f"detection_model_{key}.json"


def write(rows: list[dict], model: PoseModels, key: str | None = None) -> None:
    DATA.mkdir(parents=True, exist_ok=True)
    table, name = model_files(key)
    tmp = DATA / f"{table}.tmp"
    with tmp.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{r.get(k, ''):.6g}" if isinstance(r.get(k), float) else r.get(k, ""))
                        for k in FIELDS})
    tmp.replace(DATA / table)
    (DATA / f"{name}.tmp").write_text(json.dumps(asdict(model), indent=2) + "\n")
    (DATA / f"{name}.tmp").replace(DATA / name)


def _write_to(out: Path, rows: list[dict], source: str, start: float) -> int:
    """Fit ``rows`` and write the table and model into ``out`` (not the committed data folder)."""
    global DATA
    model = replace(fit(rows), source=f"tools/calibrate_detection.py {source}")
    DATA = out
    write(rows, model)
    print(f"{len(rows)} conditions in {time.perf_counter() - start:.0f} s -> {out}")
    print(model.to_json())
    return 0


def world_grid() -> list[dict]:
    """The grid of ``WORLD``: the raster's (``run_grid``'s defaults; plus the two chamfered kinds of
    ``PBR_KINDS`` for rim-edge detectors), or the smaller PBR grid (``PBR_RADII`` × ``PBR_KINDS``, ``PBR_PLACEMENTS``
    placements; the occlusion, large-rim and contrast bands too)."""
    global PLACEMENTS
    if WORLD.renderer == "raster":
        kinds = KINDS if WORLD.detector == "threshold" else KINDS + PBR_KINDS[3:]
        return run_grid(kinds=kinds)
    PLACEMENTS = PBR_PLACEMENTS
    return run_grid(radii=PBR_RADII, kinds=PBR_KINDS)


def _world(args: argparse.Namespace) -> World:
    return World(args.renderer, args.detector, args.material, args.light, args.hole_ends, args.spp)


def _summary(rows: list[dict], model: PoseModels, seconds: float) -> str:
    return json.dumps({"world": asdict(WORLD), "key": WORLD.key(), "conditions": len(rows),
                       "seconds": round(seconds), "residuals": residuals(rows, model)}, indent=1)


def main(argv: list[str] | None = None) -> int:
    from cadfeat.cell.defaults import DETECTORS, HOLE_ENDS, RENDERERS
    from cadfeat.cell.light import LIGHT_KINDS
    from cadfeat.cell.material import MATERIALS

    global WORLD
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a small grid, print only (no files written)")
    ap.add_argument("--refit", action="store_true", help="refit the models to the committed table (no renders)")
    ap.add_argument("--study", type=Path, default=None,
                    help="calibrate with this study's camera, depths and hole radii (written to --out)")
    ap.add_argument("--out", type=Path, default=None, help="folder for --study's table and model")
    ap.add_argument("--supersample", type=int, default=1,
                    help="render with k x k sub-pixels per pixel (render.camera_views.DEFAULT_SUPERSAMPLE); k > 1 "
                         "needs --out (the committed calibration is of the default renderer)")
    ap.add_argument("--add-contrast", action="store_true",
                    help="render only the interior-contrast band, append it to the committed table, refit, write")
    ap.add_argument("--renderer", choices=RENDERERS, default="raster", help="raster (VTK) or pbr (Mitsuba 3)")
    ap.add_argument("--detector", choices=(*DETECTORS, "threshold"), default="cadfeat",
                    help="vision.detectors' kind (prior: the rim at the nominal pose); threshold: detect_holes, "
                         "the committed detection_model.json's")
    ap.add_argument("--material", choices=tuple(MATERIALS), default="machined_aluminium", help="pbr: material")
    ap.add_argument("--light", choices=LIGHT_KINDS, default="ring", help="pbr: the light's kind")
    ap.add_argument("--hole-ends", choices=HOLE_ENDS, default="as_modelled", help="pbr: blind holes' ends")
    ap.add_argument("--validate", action="store_true",
                    help="render the held-out conditions (HELD_OUT) and compare with the world's committed model")
    ap.add_argument("--spp", type=int, default=16,
                    help="pbr: samples per pixel (16: the closed loop's; 8 loses glossy faces in path-tracing noise)")
    args = ap.parse_args(argv)
    WORLD = _world(args)
    legacy = WORLD.renderer == "raster" and WORLD.detector == "threshold"
    key = None if legacy else WORLD.key()
    start = time.perf_counter()
    if args.supersample != 1:
        if args.out is None or args.study is not None or args.quick or args.refit or args.add_contrast:
            ap.error("--supersample needs --out and the full grid (no --study, --quick, --refit, --add-contrast)")
        import cadfeat.render.camera_views as views

        views.DEFAULT_SUPERSAMPLE = args.supersample
        rows = run_grid()
        return _write_to(args.out, rows, f"--supersample {args.supersample}: {len(rows)} rendered conditions, noise "
                         f"{NOISE_GREY} grey", start)
    if args.study is not None:
        if args.out is None:
            ap.error("--study needs --out (a folder for the study's calibration)")
        rows = study_grid(args.study)
        return _write_to(args.out, rows, f"--study {args.study.name}: {len(rows)} rendered conditions with the "
                         "study's camera", start)
    table, name = model_files(key)
    if args.validate:
        global PLACEMENTS
        PLACEMENTS = PBR_PLACEMENTS
        model = PoseModels(**json.loads((DATA / name).read_text()))
        res = validate(model)
        print(json.dumps({"key": key, "seconds": round(time.perf_counter() - start), "held_out": res}, indent=1))
        return 0
    if args.add_contrast:
        rows = list(csv.DictReader((DATA / table).open()))
        rows = [r for r in rows if float(r["angle_deg"]) not in CONTRAST_ANGLES_DEG] + contrast_grid()
    elif args.refit:
        rows = list(csv.DictReader((DATA / table).open()))
    elif args.quick:
        rows = run_grid(radii=(1.5,), kinds=KINDS[:1] + PBR_KINDS[4:], angles=(0.0, 60.0), distances=(300.0,),
                        blurs=(0.0,), seeds=4, occlusion=False, large=False, contrast=False)
    else:
        rows = world_grid()
    model = fit(rows)
    what = "threshold detector, raster" if legacy else f"--renderer {WORLD.renderer} --detector {WORLD.detector}" + (
        "" if WORLD.renderer == "raster" else f" --material {WORLD.material} --light {WORLD.light} --hole-ends "
        f"{WORLD.hole_ends} --spp {WORLD.spp}")
    model = replace(model, source=f"tools/calibrate_detection.py {what}: {len(rows)} rendered conditions, noise "
                                  f"{NOISE_GREY} grey")
    seconds = time.perf_counter() - start
    print(f"{len(rows)} conditions in {seconds:.0f} s")
    print(model.to_json())
    print(_summary(rows, model, seconds))
    if args.add_contrast:
        write([{k: r.get(k) for k in FIELDS} for r in rows], model, key)
    elif args.refit:
        (DATA / name).write_text(json.dumps(asdict(model), indent=2) + "\n")
    elif not args.quick:
        write(rows, model, key)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
