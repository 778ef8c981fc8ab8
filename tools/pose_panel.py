"""Panel: predicted pose error vs the closed loop on designs of a study's part (default: the flagship).

Designs: the original and ``--designs − 1`` scrambled-Sobol points of the study's design space (seeded). For each:
the part is rebuilt, its holes extracted (with the part's view direction), the rims' hidden fractions computed
by the exact ray test, and

- predicted: ``pose_information`` (calibrated detection/measurement models, occlusion) — per pose the bias +
  noise error; the PnP prediction is its RMS over the frames, the IEKF prediction the posterior CRLB
  (``posterior_crlb`` with the closed loop's filter tuning) combined with the same bias;
- simulated: the closed loop (``vision.closed_loop``: render, blur, noise, detection, association with the
  predicted occlusion, PnP and IEKF; ``--runs`` Monte-Carlo runs), the RMS error after the settle frames, lost
  frames counted separately.

Prints a table and Spearman ρ (predicted vs simulated) per estimator and per error kind; ``--json`` writes the
numbers. Cost: about 20–30 s per design on one core (the renders). Run:
``python tools/pose_panel.py --designs 12 --runs 3``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def designs(space, count: int, seed: int = 0) -> list[np.ndarray]:
    from scipy.stats import qmc

    lo = np.array([v.lower for v in space.variables])
    hi = np.array([v.upper for v in space.variables])
    pts = qmc.Sobol(len(lo), scramble=True, seed=seed).random(max(count - 1, 1))
    return [np.asarray(space.x0, float)] + [lo + p * (hi - lo) for p in pts[: count - 1]]


def score(setup, x, T, times, tuning, model=None) -> dict:
    from cadfeat.cad.export import mesh_from_shape
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.measures.pose_information import pose_information
    from cadfeat.measures.rim_occlusion import rim_occlusion
    from cadfeat.vision.crlb import posterior_crlb

    shape = setup.rebuild_shape(x)
    holes = setup.rebuild_holes(shape)
    c, n, r = holes_to_arrays(holes)
    occ = rim_occlusion(mesh_from_shape(shape, tolerance=0.05), T, c, n, r, samples=12,
                        through=[h.through for h in holes], depth_mm=[h.depth_mm for h in holes])
    ratio = [h.depth_mm / (2 * h.radius_mm) for h in holes]
    pi = pose_information(setup.camera, T, c, n, r, occlusion=occ, depth_ratio=ratio,
                          through=[h.through for h in holes], prior_sigma=(20.0, 0.1), model=model)
    _, sig = posterior_crlb(pose_information(setup.camera, T, c, n, r, occlusion=occ, depth_ratio=ratio,
                                             through=[h.through for h in holes], model=model).information,
                            times, tuning)
    rms = lambda a: float(np.sqrt(np.mean(np.square(a))))  # noqa: E731
    return {"shape": shape, "holes": holes,
            "pnp_t": rms(pi.error_translation_mm), "pnp_r": rms(pi.error_rotation_deg),
            "iekf_t": rms(np.hypot(pi.bias_translation_mm, sig[:, 0])),
            "iekf_r": rms(np.hypot(pi.bias_rotation_deg, sig[:, 1])),
            "bias_t": rms(pi.bias_translation_mm), "noise_t": rms(pi.sigma_translation_mm),
            "holes_seen": float(pi.detected.sum(axis=1).mean())}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", type=Path, default=ROOT / "studies" / "nema17_mount.toml",
                    help="a part-script study (default: the flagship)")
    ap.add_argument("--designs", type=int, default=12)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--frame-step", type=int, default=2)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--model", type=Path, default=None,
                    help="a detection_model.json (calibrate_detection.py --study); default: the committed one")
    args = ap.parse_args(argv)
    from scipy.stats import spearmanr

    from cadfeat.poses import invert_T
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_study
    from cadfeat.vision import FilterTuning, SensorModel
    from cadfeat.vision.closed_loop import TrackingConfig, observe, track_design

    setup = setup_study(load_study(args.study))
    traj = setup.trajectory
    idx = np.arange(0, len(traj.T_task_cam), args.frame_step)
    T = (invert_T(np.asarray(traj.T_task_cam)) @ setup.T_task_part)[idx]
    times = np.asarray(traj.times_s)[idx]
    tuning = FilterTuning()
    model = None
    if args.model is not None:
        from cadfeat.measures.pose_models import PoseModels

        model = PoseModels(**json.loads(args.model.read_text()))
    config = TrackingConfig(estimators=("pnp", "iekf"), runs=args.runs, sensor=SensorModel(noise_grey=2.0),
                            tuning=tuning)
    rows = []
    for i, x in enumerate(designs(setup.space, args.designs)):
        start = time.perf_counter()
        s = score(setup, x, T, times, tuning, model)
        obs = observe(s["shape"], s["holes"], setup.camera, T, config.sensor)
        res = track_design(setup.camera, obs, T, times, config)
        sim = {m: (np.nanmean([q["trans_mm_rms"] for q in res.summaries[m]]),
                   np.nanmean([q["rot_deg_rms"] for q in res.summaries[m]]),
                   np.mean([q["frames_lost"] for q in res.summaries[m]])) for m in config.estimators}
        # diagnostic: the closed loop's measured offsets (mean detection − the exact rim-ellipse centre at the
        # true pose) propagated through the pose Jacobians (δ = (JᵀWJ)⁻¹JᵀW b, the holes it detected)
        from cadfeat.cad.features import holes_to_arrays
        from cadfeat.measures.pose_information import pose_information
        from cadfeat.measures.rim_centre import measure

        c, n, r = holes_to_arrays(s["holes"])
        z_true, _ = measure(setup.camera, T, c, n, r, jacobian=False)
        found = np.all(np.isfinite(res.pixels), axis=-1).all(axis=0)                 # (F, N) in every run
        b = np.where(found[..., None], np.nanmean(res.pixels, axis=0) - z_true, 0.0)
        prop = pose_information(setup.camera, T, c, n, r, sigma_px=0.1, detection=False, offset_px=b,
                                occlusion=~found)
        s["measured_offset_px_median"] = float(np.median(np.linalg.norm(b[found], axis=-1))) if found.any() else 0.0
        s["propagated_t"] = float(np.sqrt(np.mean(prop.bias_translation_mm ** 2)))
        s["propagated_r"] = float(np.sqrt(np.mean(prop.bias_rotation_deg ** 2)))
        row = {"design": i, "x": [round(float(v), 3) for v in x],
               **{k: v for k, v in s.items() if k not in ("shape", "holes")},
               "sim_pnp_t": sim["pnp"][0], "sim_pnp_r": sim["pnp"][1], "sim_pnp_lost": sim["pnp"][2],
               "sim_iekf_t": sim["iekf"][0], "sim_iekf_r": sim["iekf"][1], "seconds": time.perf_counter() - start}
        rows.append(row)
        print(json.dumps({k: (round(v, 5) if isinstance(v, float) else v) for k, v in row.items()}), flush=True)
    out = {"rows": rows, "spearman": {}, "ratio_median": {}}
    for est in ("pnp", "iekf"):
        for kind in ("t", "r"):
            p = np.array([r[f"{est}_{kind}"] for r in rows])
            q = np.array([r[f"sim_{est}_{kind}"] for r in rows])
            ok = np.isfinite(p) & np.isfinite(q)
            rho = float(spearmanr(p[ok], q[ok]).statistic) if ok.sum() >= 3 else float("nan")
            out["spearman"][f"{est}_{kind}"] = rho
            out["ratio_median"][f"{est}_{kind}"] = float(np.median(p[ok] / q[ok])) if ok.any() else float("nan")
    print(json.dumps({"spearman": out["spearman"], "predicted/simulated (median)": out["ratio_median"]}, indent=1))
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
