"""Calibrate the detection and measurement models (``cadfeat.measures.pose_models``) on cadfeat's own detector.

Renders a 60×60×5 mm plate with one hole (cadfeat's renderer, ``vision.images``) over a grid of causes, adds
the thin-lens blur (a pillbox of the given diameter) and the sensor noise (2 grey levels) over several noise
seeds, runs ``vision.detection.detect_holes`` + ``associate`` against the exact rim ellipse, and writes one
row per condition: detection rate, mean offset (px, and its component along the image direction of the hole
axis), centre noise σ (px, per axis), and the causes (view angle, minor axis, rim length, blur, depth/diameter,
through, hidden fraction of the rim). The models are then fitted to the table (least squares on the rate, on
log σ and on the offset) and both are written as package data:

    cadfeat/measures/data/detection_calibration.csv   the measured table
    cadfeat/measures/data/detection_model.json        the fitted ``PoseModels``

Grid (coarse, a few minutes on one core): 3 radii × 3 hole kinds (blind shallow, blind deep, through) × 5 view
angles × 2 distances = 90 conditions, each rendered at ``PLACEMENTS`` = 6 placements of the plate (shifted and
turned within a cell's placement tolerance, so each rim falls on different sub-pixel phases) with 3 blurs × 3
noise seeds per placement: the mean offset over placements is the systematic part, the spread of the
per-placement offsets the pixel-grid ("aliasing") part ``alias_px`` — the closed loop's run-to-run placement
jitter (``vision.closed_loop``) draws the same; plus 5 partial-occlusion renders (a wall whose edge covers part
of the rim; one placement, 12 seeds) and a large-rim band (``LARGE_RADII`` through holes, 48 conditions: rims of
90–450 px, where the systematic offset of an oblique rim stands out of the pixel-grid scatter). The offset fit
weights each row by the uncertainty of its mean offset (pixel-grid scatter over the placements, noise over the
draws). Run: ``python tools/calibrate_detection.py`` (``--quick`` for a
smaller grid, no files written).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cadfeat.camera import Camera  # noqa: E402
from cadfeat.measures.pose_models import PoseModels, hole_geometry  # noqa: E402

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
          "sigma_px", "draws", "alias_px", "placements")


def plate(radius: float, kind: str, depth_ratio: float, wall: float | None = None):
    """The test plate (hole at the origin, axis +z, top face z = 0), optionally with a 4 mm wall of height
    ``wall`` (mm) standing at x in [−10, −6], between the hole and the camera, to hide part of the rim."""
    import cadquery as cq

    wp = cq.Workplane("XY").box(60, 60, 5).translate((0, 0, -2.5))
    if kind == "through":
        wp = wp.faces(">Z").workplane().hole(2 * radius)
    else:
        wp = wp.faces(">Z").workplane().hole(2 * radius, depth_ratio * 2 * radius)
    if wall is not None:
        wp = wp.union(cq.Workplane("XY").box(4, 60, wall).translate((-8.0, 0, 0.5 * wall)))
    return wp


def pose(angle_deg: float, distance_mm: float, azimuth_deg: float = 180.0) -> np.ndarray:
    from cadfeat.poses import invert_T, look_at

    a, b = np.radians(angle_deg), np.radians(azimuth_deg)
    eye = distance_mm * np.array([np.sin(a) * np.cos(b), np.sin(a) * np.sin(b), np.cos(a)])
    up = (0.0, 1.0, 0.0)
    return invert_T(look_at(eye, np.zeros(3), up=up))


def measure_condition(images: np.ndarray, hole, T: np.ndarray, blur: float, seeds: int) -> dict[str, float]:
    """Detection statistics of one clean render under blur and ``seeds`` noise draws."""
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.measures import hole_ellipse
    from cadfeat.vision.detection import associate, detect_holes
    from cadfeat.vision.images import _disk_kernel, apply_optics, sensor_images

    c, n, r = holes_to_arrays([hole])
    e = hole_ellipse(CAMERA, c @ T[:3, :3].T + T[:3, 3], n @ T[:3, :3].T, r)
    optical = apply_optics(images, [_disk_kernel(blur)])
    found = []
    for s in range(seeds):
        frame = sensor_images(optical, NOISE_GREY, 1000 + s)[0]
        z = associate(e, detect_holes(frame), gate_px=10.0)[0]
        if np.all(np.isfinite(z)):
            found.append(z - e.centre_px[0])
    geo = hole_geometry(CAMERA, T[None], c, n, r)
    d = np.asarray(found)
    row = {"rate": len(found) / seeds, "draws": seeds, "minor_px": float(geo.minor_px[0, 0]),
           "rim_px": float(geo.rim_px[0, 0]), "facing": float(geo.facing[0, 0]),
           "margin_px": float(geo.margin_px[0, 0])}
    if len(d) >= 3:
        mean = d.mean(axis=0)
        row.update(offset_u_px=float(mean[0]), offset_v_px=float(mean[1]),
                   offset_axis_px=float(mean @ geo.axis_dir_px[0, 0]),
                   sigma_px=float(np.sqrt(0.5 * np.sum(d.var(axis=0, ddof=1)))))
    else:
        row.update(offset_u_px=np.nan, offset_v_px=np.nan, offset_axis_px=np.nan, sigma_px=np.nan)
    return row


def placements(T: np.ndarray, count: int = PLACEMENTS, seed: int = 0) -> np.ndarray:
    """(count, 4, 4) T · δ_k: the plate shifted in its plane and turned about its normal (``PLACEMENTS``)."""
    from cadfeat.vision.motion import so3_exp

    rng = np.random.default_rng([seed, 17])
    out = np.tile(np.eye(4), (count, 1, 1))
    out[:, :2, 3] = rng.uniform(-0.6, 0.6, (count, 2))
    out[:, :3, :3] = [so3_exp(np.array([0.0, 0.0, np.radians(a)])) for a in rng.uniform(-3.0, 3.0, count)]
    return T[None] @ out


def measure_placements(images: np.ndarray, hole, Ts: np.ndarray, blur: float,
                       seeds: int = SEEDS_PER_PLACEMENT) -> dict[str, float]:
    """Detection statistics of one condition over placements (``placements``): rate over all draws, the mean
    offset over placements (systematic), the noise σ (pooled within placements, per axis) and the pixel-grid
    RMS per axis (the spread of the per-placement mean offsets, less their noise share σ²/seeds)."""
    rows = [measure_condition(images[k:k + 1], hole, Ts[k], blur, seeds) for k in range(len(Ts))]
    means = np.array([[r["offset_u_px"], r["offset_v_px"]] for r in rows])
    ok = np.all(np.isfinite(means), axis=1)
    geo = rows[0]
    out = {"rate": float(np.mean([r["rate"] for r in rows])), "draws": seeds * len(Ts),
           "minor_px": geo["minor_px"], "rim_px": geo["rim_px"], "facing": geo["facing"],
           "margin_px": geo["margin_px"], "placements": int(ok.sum())}
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
    from cadfeat.vision.images import render_sequence

    return render_sequence(shape, holes, CAMERA, T[None])


def render_many(shape, holes, Ts: np.ndarray) -> np.ndarray:
    from cadfeat.vision.images import render_sequence

    return render_sequence(shape, holes, CAMERA, Ts)


def run_grid(radii=RADII, kinds=KINDS, angles=ANGLES_DEG, distances=DISTANCES, blurs=BLURS_PX,
             seeds=SEEDS_PER_PLACEMENT, occlusion=True, large=True, contrast=True, seed0=0) -> list[dict]:
    from cadfeat.cad.features import extract_holes
    from cadfeat.measures.rim_occlusion import rim_occlusion

    rows = []
    for radius in radii:
        for kind, ratio in kinds:
            wp = plate(radius, kind, ratio)
            holes = [h for h in extract_holes(wp) if np.linalg.norm(h.centre[:2]) < 1e-6]
            for angle in angles:
                for dist in distances:
                    Ts = placements(pose(angle, dist), seed=seed0 + len(rows))
                    images = render_many(wp.val(), holes, Ts)
                    for blur in blurs:
                        # what was rendered: a "blind" hole deeper than the 5 mm plate is a through hole
                        thr = bool(holes[0].through)
                        row = {"radius_mm": radius, "kind": "through" if thr else kind, "through": thr,
                               "depth_ratio": float(holes[0].depth_mm) / (2 * radius),
                               "angle_deg": angle, "distance_mm": dist, "blur_px": blur, "hidden": 0.0}
                        row.update(measure_placements(images, holes[0], Ts, blur, seeds))
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
                   "distance_mm": 300.0, "blur_px": 0.0, "hidden": hidden}
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


def fit(rows: list[dict]) -> PoseModels:
    """Least-squares fits of the detection rate, log σ and the axis offset (module docstring)."""
    from scipy.optimize import least_squares, nnls

    a = _arrays(rows)
    base = PoseModels()
    clean = a["hidden"] == 0

    def p_model(x, sel):
        m = replace(base, m0_px=x[0], w_m_px=x[1], kappa_blur=x[2], c0=x[3], w_c=x[4])
        return _geo_p(m, a, sel)

    sel = clean
    r = least_squares(lambda x: p_model(x, sel) - a["rate"][sel], [4.0, 0.7, 0.3, 0.2, 0.05],
                      bounds=([0.5, 0.1, 0.0, -0.5, 0.01], [20.0, 5.0, 2.0, 0.9, 0.5]))
    m0, w_m, kappa, c0, w_c = r.x
    ok = clean & np.isfinite(a["sigma_px"]) & (a["rate"] >= 0.5)
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
    return replace(base, m0_px=float(m0), w_m_px=float(w_m), kappa_blur=float(kappa), c0=float(c0),
                   w_c=float(w_c), sigma0_px=float(s0), k_sigma=float(k_s), w0_px=float(w0), k_b=float(k_b),
                   k_d=float(k_d), k_w_px=float(k_w), k_i=float(k_i), k_alias_px=k_alias, alias_floor_px=alias_floor,
                   o0=o0,
                   source=f"tools/calibrate_detection.py: {len(rows)} rendered conditions, noise {NOISE_GREY} grey")


def _geo_p(m: PoseModels, a: dict[str, np.ndarray], sel: np.ndarray) -> np.ndarray:
    """The detection model on the table's recorded causes (same formula as ``PoseModels.detection_probability``)."""
    from cadfeat.measures.pose_models import HoleGeometry

    k = int(sel.sum())
    g = HoleGeometry(a["minor_px"][sel][None], a["minor_px"][sel][None], a["margin_px"][sel][None],
                     a["facing"][sel][None], a["blur_px"][sel][None], a["rim_px"][sel][None], np.zeros((1, k, 2)),
                     np.ones((1, k), bool), np.ones((1, k), bool))
    return m.detection_probability(g, a["hidden"][sel][None])[0]


def write(rows: list[dict], model: PoseModels) -> None:
    DATA.mkdir(parents=True, exist_ok=True)
    tmp = DATA / "detection_calibration.csv.tmp"
    with tmp.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{r[k]:.6g}" if isinstance(r[k], float) else r[k]) for k in FIELDS})
    tmp.replace(DATA / "detection_calibration.csv")
    (DATA / "detection_model.json.tmp").write_text(json.dumps(asdict(model), indent=2) + "\n")
    (DATA / "detection_model.json.tmp").replace(DATA / "detection_model.json")


def _write_to(out: Path, rows: list[dict], source: str, start: float) -> int:
    """Fit ``rows`` and write the table and model into ``out`` (not the committed data folder)."""
    global DATA
    model = replace(fit(rows), source=f"tools/calibrate_detection.py {source}")
    DATA = out
    write(rows, model)
    print(f"{len(rows)} conditions in {time.perf_counter() - start:.0f} s -> {out}")
    print(model.to_json())
    return 0


def main(argv: list[str] | None = None) -> int:
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
    args = ap.parse_args(argv)
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
    if args.add_contrast:
        rows = list(csv.DictReader((DATA / "detection_calibration.csv").open()))
        rows = [r for r in rows if float(r["angle_deg"]) not in CONTRAST_ANGLES_DEG] + contrast_grid()
    elif args.refit:
        rows = list(csv.DictReader((DATA / "detection_calibration.csv").open()))
    elif args.quick:
        rows = run_grid(radii=(1.5,), kinds=KINDS[:1], angles=(0.0, 60.0), distances=(300.0,), blurs=(0.0,),
                        seeds=4, occlusion=False, large=False)
    else:
        rows = run_grid()
    model = fit(rows)
    print(f"{len(rows)} conditions in {time.perf_counter() - start:.0f} s")
    print(model.to_json())
    if args.add_contrast:
        write([{k: r.get(k) for k in FIELDS} for r in rows], model)
    elif args.refit:
        (DATA / "detection_model.json").write_text(json.dumps(asdict(model), indent=2) + "\n")
    elif not args.quick:
        write(rows, model)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
