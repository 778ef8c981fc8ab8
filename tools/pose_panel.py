"""Panel: predicted pose error vs the closed loop on designs of a study's part (default: the flagship).

Designs: the original and ``--designs − 1`` scrambled-Sobol points of the study's design space (seeded). For each:
the part is rebuilt, its holes extracted (with the part's view direction), the rims' hidden fractions computed
by the exact ray test, and

- predicted: ``pose_information`` (calibrated detection/measurement models, occlusion) — per pose the bias +
  noise error; the PnP prediction is its RMS over the frames with the frames PnP loses held at the last pose
  (``measures.lost_frames``: fewer than 4 holes found; ``pnp_posed_*`` without them), the IEKF prediction the
  posterior CRLB
  (``posterior_crlb`` with the closed loop's filter tuning) combined with the same bias;
- simulated: the closed loop (``vision.closed_loop``: render, blur, noise, detection, association with the
  predicted occlusion, PnP and IEKF; ``--runs`` Monte-Carlo runs), the RMS error after the settle frames, lost
  frames at the held last estimate's error; each run with its own placement error, illumination gain and noise
  (``TrackingConfig``), so the simulated error is an expectation over the cell's variability.

Prints Spearman ρ (predicted vs simulated) per estimator and error kind and the predicted/simulated ratios;
``--json`` writes the numbers, ``--markdown`` the committed table (``benchmarks/results/pose_panel.md``);
``--optimum results.json`` adds a study's optimum to the panel with a paired test vs the original. ``--added
results.json`` (a study run with ``[add_targets]``) replaces the Sobol designs by the original with each subset of
the added-target curve's greedy sites drilled (``cad.drill_targets``; 2^k designs, k ≤ 4): designs whose
predicted errors differ by up to a third, beyond the loop's scatter, where a move-only design space spans a few
per cent. Cost: the
renders, once per run and design (placement jitter). Run, e.g.:
``python tools/pose_panel.py --study studies/nema17_mount.toml --optimum OUT/results.json --study
studies/industrial_plate.toml --designs 12 --runs 8 --json panel.json --markdown benchmarks/results/pose_panel.md``.
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


def pose_setup(study: Path):
    """The study's set-up with g_POSE as its objective (whatever the study lists), so that its ``problem`` scores
    candidate designs by the predicted pose error on the feature model (no CAD rebuild) and checks every
    requirement (the study's constraints)."""
    import dataclasses

    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_study

    cfg = load_study(study)
    return setup_study(dataclasses.replace(cfg, objective=cfg.objective.model_copy(update={"measures": ("pose",)})))


def designs(setup, count: int, seed: int = 0, extremes: int = 0,
            candidates: int = 256) -> tuple[list[np.ndarray], list[str], dict]:
    """The original, the first ``count − 1`` scrambled-Sobol points of the design space (``candidates`` drawn,
    seeded) **that keep every requirement** (the study's constraint margins ≥ 0 on the feature model), and
    ``extremes`` more from the remaining feasible candidates: half the lowest and half the highest predicted
    error (g_POSE on the feature model), so that the panel spans the range the requirements allow. Also returns
    the spread of the predicted error over all feasible candidates (how much designs can differ at all)."""
    from scipy.stats import qmc

    space, problem = setup.space, setup.problem
    lo = np.array([v.lower for v in space.variables])
    hi = np.array([v.upper for v in space.variables])
    X = lo + qmc.Sobol(len(lo), scramble=True, seed=seed).random(candidates) * (hi - lo)
    G, C = problem.evaluate_batch(X)
    err = -G[:, list(problem.names).index("g_POSE")] if "g_POSE" in problem.names else -G[:, 0]
    feasible = np.nonzero(C.min(axis=1) >= 0.0)[0]
    sobol = feasible[: count - 1]
    rest = feasible[count - 1:]
    order = rest[np.argsort(err[rest])]
    k_lo = extremes // 2
    picks = list(order[:k_lo]) + (list(order[len(order) - (extremes - k_lo):]) if extremes - k_lo else [])
    g0 = float(-problem.evaluate_batch(np.asarray(space.x0, float)[None])[0][0, 0])
    xs = [np.asarray(space.x0, float)] + [X[i] for i in sobol] + [X[i] for i in picks]
    names = (["original"] + [f"sobol {i + 1}" for i in range(len(sobol))]
             + [f"extreme {'low' if j < k_lo else 'high'} {j + 1}" for j in range(len(picks))])
    info = {"candidates": candidates, "feasible": int(len(feasible)), "predicted_original": g0,
            "predicted_feasible_min": float(err[feasible].min()), "predicted_feasible_max": float(err[feasible].max()),
            **({"predicted_sobol_min": float(err[sobol].min()), "predicted_sobol_max": float(err[sobol].max())}
               if len(sobol) else {})}
    return xs, names, info


def score(setup, x, T, times, tuning, model=None, glare=None, cell=None, added=()) -> dict:
    """Predicted errors of design ``x`` along the frames T (the rows' ``pnp_*`` / ``iekf_*``): RMS over the frames
    after the closed loop's ``settle_frames`` (``TrackingConfig``), the frames its simulated RMS counts
    (``vision.metrics.run_summary``); the per-hole columns over all frames."""
    from cadfeat.cad.export import mesh_from_shape
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.measures.lost_frames import held_errors
    from cadfeat.measures.pose_estimator import equal_weight_errors
    from cadfeat.measures.pose_information import pose_information
    from cadfeat.measures.rim_occlusion import rim_occlusion
    from cadfeat.vision.closed_loop import TrackingConfig
    from cadfeat.vision.crlb import posterior_crlb

    shape = setup.rebuild_shape(x)
    holes = setup.rebuild_holes(shape)
    if added:  # (--added) the design's target holes drilled into the rebuilt solid, verified
        from cadfeat.cad.drill_targets import drill_targets

        shape, holes = drill_targets(shape, list(added), holes_before=holes, label="the panel's design",
                                     prefer_direction=setup.view_direction)
    c, n, r = holes_to_arrays(holes)
    occ = rim_occlusion(mesh_from_shape(shape, tolerance=0.05), T, c, n, r, samples=12,
                        through=[h.through for h in holes], depth_mm=[h.depth_mm for h in holes])
    ratio = [h.depth_mm / (2 * h.radius_mm) for h in holes]
    kinds = [h.kind for h in holes]
    rate = None
    if glare is not None:  # the part's own light on its blind rims (measures.glare), as g_POSE in ``cell``
        from cadfeat.design.pose_terms import designs_glare_rate

        rate = designs_glare_rate(glare, cell, T, c[None], n[None], np.asarray(r, float)[None],
                                  np.array([h.through for h in holes]), cell.noise_sigma_grey)
    pi = pose_information(setup.camera, T, c, n, r, occlusion=occ, depth_ratio=ratio, kinds=kinds,
                          through=[h.through for h in holes], prior_sigma=(20.0, 0.1), model=model,
                          contrast_rate=rate)
    _, sig = posterior_crlb(pose_information(setup.camera, T, c, n, r, occlusion=occ, depth_ratio=ratio,
                                             kinds=kinds, through=[h.through for h in holes],
                                             model=model, contrast_rate=rate).information,
                            times, tuning)
    settle = min(TrackingConfig().settle_frames, len(T) - 1)
    # PnP holds its last pose where fewer than 4 holes are found (the closed loop's metric): measures.lost_frames
    held_t, held_r, lost = held_errors(T, pi.probability, pi.error_translation_mm, pi.error_rotation_deg)
    rms = lambda a: float(np.sqrt(np.mean(np.square(a[settle:]))))  # noqa: E731
    eq = equal_weight_errors(pi)
    eq_t, eq_r, eq_bias = eq.translation_mm, eq.rotation_deg, eq.bias
    _, eq_sig = posterior_crlb(eq.information, times, tuning)
    return {"shape": shape, "holes": holes,
            "eq_pnp_t": rms(eq_t), "eq_pnp_r": rms(eq_r),
            "eq_iekf_t": rms(np.hypot(np.linalg.norm(eq_bias[:, :3], axis=-1), eq_sig[:, 0])),
            "eq_iekf_r": rms(np.hypot(np.degrees(np.linalg.norm(eq_bias[:, 3:], axis=-1)), eq_sig[:, 1])),
            "pnp_t": rms(held_t), "pnp_r": rms(held_r), "pnp_lost": float(np.mean(lost[settle:])),
            "pnp_posed_t": rms(pi.error_translation_mm), "pnp_posed_r": rms(pi.error_rotation_deg),
            "iekf_t": rms(np.hypot(pi.bias_translation_mm, sig[:, 0])),
            "iekf_r": rms(np.hypot(pi.bias_rotation_deg, sig[:, 1])),
            "bias_t": rms(pi.bias_translation_mm), "noise_t": rms(pi.sigma_translation_mm),
            "holes_seen": float(pi.detected.sum(axis=1).mean()),
            "model_px": np.sqrt(pi.sigma_px ** 2 + np.sum(pi.offset_px ** 2, axis=-1) / 2),   # (L, N) per axis
            "model_detected": pi.detected}


def added_designs(path: Path, setup) -> tuple[list[np.ndarray], list[str], list[tuple], dict]:
    """(``--added``) The original design with each subset of the greedy sites of a ``[add_targets]`` run's curve
    drilled (results.json ``added_targets.curve.sites``, in their greedy order; the drill's diameter, depth and
    chamfer from ``added_targets.settings``; each site's axis that of the delivered added hole nearest to it — the
    outward normal of the face both lie on): (xs, names, added holes per design, info)."""
    from itertools import combinations

    from cadfeat.cad.drill_targets import AddedHole

    at = json.loads(path.read_text())["added_targets"]
    sites = np.asarray(at["curve"]["sites"], float)[:4]
    st = at["settings"]
    centres = np.array([h["centre"] for h in at["holes"]], float)
    axes = np.array([h["axis"] for h in at["holes"]], float)
    nearest = np.argmin(np.linalg.norm(sites[:, None] - centres[None], axis=-1), axis=1)
    n_old = len(setup.holes0)
    holes = [AddedHole(c, axes[k], st["diameter_mm"] / 2, st["depth_mm"], st["chamfer_mm"], f"H{n_old + 1 + i}")
             for i, (c, k) in enumerate(zip(sites, nearest, strict=True))]
    x0 = np.asarray(setup.space.x0, float)
    xs, names, added = [], [], []
    for k in range(len(holes) + 1):
        for subset in combinations(range(len(holes)), k):
            xs.append(x0)
            names.append("original" if not subset else "original + " + "+".join(f"s{i + 1}" for i in subset))
            added.append(tuple(holes[i] for i in subset))
    info = {"added_sites": sites.tolist(), "curve_error_mm": at["curve"]["error_mm"][:len(sites) + 1]}
    return xs, names, added, info


def _optimum(path: Path, space) -> np.ndarray:
    """The design vector of a ``cadfeat run`` output's results.json (``variables[*].after`` by name)."""
    after = {v["name"]: v["after"] for v in json.loads(path.read_text())["variables"]}
    return np.array([float(after[v.name]) for v in space.variables])


def pbr_cell(args: argparse.Namespace, study: Path, setup):
    """``--renderer pbr``: the closed loop of ``cadfeat run --track pbr`` in the study's ``[cell]`` (its light, its
    placement and noise; ``--material`` overrides the finish, ``--light`` the light's kind) — the fast check's
    frames, ``--runs`` runs, ``--spp`` samples — and the prediction with that cell's calibrated models
    (``design.pose_terms.cell_models``).
    Returns (TrackingConfig, T (F, 4, 4), times (F,), models, glare maps or None (``study.setup.glare_maps_for``),
    the cell)."""
    from dataclasses import replace

    from cadfeat.cell.material import Material
    from cadfeat.design.pose_terms import cell_models
    from cadfeat.poses import invert_T
    from cadfeat.study.closed_loop_check import fast_spec
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import glare_maps_for
    from cadfeat.vision.closed_loop import tracked_frames

    cfg = load_study(study)
    cell = cfg.cell if args.material is None else cfg.cell.replace(material=Material(name=args.material))
    if args.light is not None:  # a light of another kind, at the study's camera distance
        from cadfeat.cell.light import Light

        cell = cell.replace(light=Light(kind=args.light, reference_mm=cell.light.reference_mm))
    traj = setup.trajectory
    T_all = invert_T(np.asarray(traj.T_task_cam)) @ setup.T_task_part
    spec = fast_spec(cfg, len(T_all)).replace(renderer="pbr", spp=args.spp, runs=args.runs, seed=args.seed)
    config = spec.replace(estimators=("pnp", "iekf")).in_cell(cell)
    _, T, times, _ = tracked_frames(T_all, np.asarray(traj.times_s), None, config.frame_step)
    glare = glare_maps_for(replace(cfg, cell=cell), setup.shape0, setup.holes0, setup.camera, T)
    return config, T, times, cell_models(cell), glare, cell


def run_panel(args: argparse.Namespace, study: Path, optimum: Path | None) -> dict:
    """Panel rows of one study (module docstring) and, with ``optimum``, the paired closed-loop test of the
    optimum vs the original on the same runs (common random numbers)."""
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.cell import PLACEMENT_SIGMA_PER_TOLERANCE, Cell
    from cadfeat.measures.pose_information import pose_information
    from cadfeat.measures.rim_centre import measure
    from cadfeat.poses import invert_T
    from cadfeat.vision import FilterTuning
    from cadfeat.vision.closed_loop import (
        TrackingConfig,
        compare,
        observe,
        placement_errors,
        report_frames,
        track_design,
    )

    setup = pose_setup(study)
    traj = setup.trajectory
    idx = np.arange(0, len(traj.T_task_cam), args.frame_step)
    T = (invert_T(np.asarray(traj.T_task_cam)) @ setup.T_task_part)[idx]
    times = np.asarray(traj.times_s)[idx]
    model = None
    if args.model is not None:
        from cadfeat.measures.pose_models import PoseModels

        model = PoseModels(**json.loads(args.model.read_text()))
    tuning = FilterTuning()
    k = PLACEMENT_SIGMA_PER_TOLERANCE  # the cell's placement tolerance t of the σ asked for (σ = k t)
    config = TrackingConfig(estimators=("pnp", "iekf"), runs=args.runs, seed=args.seed, sigma0_mm=tuning.sigma0_mm,
                            sigma0_rad=tuning.sigma0_rad,
                            cell=Cell(noise_sigma_grey=2.0, placement_position_mm=args.placement_mm / k,
                                      placement_angle_deg=args.placement_deg / k, gain_sigma=args.gain_sigma))
    glare = cell = None
    if args.renderer == "pbr":
        config, T, times, model, glare, cell = pbr_cell(args, study, setup)
        tuning = config.tuning
    T_runs = T[None] @ placement_errors(config, config.runs)[:, None]
    if args.added is not None:
        xs, names, added, spread = added_designs(args.added, setup)
    else:
        xs, names, spread = designs(setup, args.designs, extremes=args.extremes, candidates=args.candidates)
        added = [()] * len(xs)
    print(json.dumps({"design_space": spread}), flush=True)
    if optimum is not None:
        xs.append(_optimum(optimum, setup.space))
        names.append("g_POSE optimum")
        added.append(())
    rows, tracks = [], {}
    for i, (name, x) in enumerate(zip(names, xs, strict=True)):
        start = time.perf_counter()
        s = score(setup, x, T, times, tuning, model, glare, cell, added[i])
        frames = report_frames(len(T)) if config.renderer == "pbr" else None  # the runs render their placements
        obs = observe(s["shape"], s["holes"], setup.camera, T, config.sensor, frames=frames,
                      renderer=config.renderer, render_options=config.render_options())
        res = track_design(setup.camera, obs, T, times, config)
        tracks[name] = res
        ms = lambda v: float(np.sqrt(np.nanmean(np.square(v))))  # noqa: E731  RMS over runs of per-run RMS
        sim = {m: (ms([q["trans_mm_rms"] for q in res.summaries[m]]), ms([q["rot_deg_rms"] for q in res.summaries[m]]),
                   float(np.mean([q["frames_lost"] for q in res.summaries[m]]))) for m in config.estimators}
        # diagnostic: each run's measured offsets (detection − the exact rim-ellipse centre at that run's true pose)
        # propagated through the pose Jacobians (δ = (JᵀWJ)⁻¹JᵀW b over the holes it detected), RMS over runs
        c, n, r = holes_to_arrays(s["holes"])
        pt, pr, med, sq = [], [], [], []
        for run in range(config.runs):
            z_true, _ = measure(setup.camera, T_runs[run], c, n, r, jacobian=False)
            found = np.all(np.isfinite(res.pixels[run]), axis=-1)
            b = np.where(found[..., None], res.pixels[run] - z_true, 0.0)
            prop = pose_information(setup.camera, T_runs[run], c, n, r, sigma_px=0.1, detection=False, offset_px=b,
                                    occlusion=~found)
            pt.append(np.mean(prop.bias_translation_mm ** 2))
            pr.append(np.mean(prop.bias_rotation_deg ** 2))
            med.extend(np.linalg.norm(b[found], axis=-1))
            sq.append(np.where(found, np.sum(b ** 2, axis=-1) / 2, np.nan))                  # (F, N) per axis
        sq = np.array(sq)
        seen = np.isfinite(sq).any(axis=0)                                                     # (F, N)
        mdl = s.pop("model_px")
        det = s.pop("model_detected")
        s["holes"] = {h.name or f"hole{j}": [round(float(np.sqrt(np.nanmean(sq[:, :, j]))), 4) if seen[:, j].any()
                                             else None,
                                             round(float(np.sqrt(np.mean(mdl[seen[:, j], j] ** 2))), 4)
                                             if seen[:, j].any() else None,
                                             round(float(np.isfinite(sq[:, :, j]).mean()), 3),
                                             round(float(det[:, j].mean()), 3)]
                      for j, h in enumerate(s["holes"])}
        s["measured_offset_px_median"] = float(np.median(med)) if med else 0.0
        s["propagated_t"], s["propagated_r"] = float(np.sqrt(np.mean(pt))), float(np.sqrt(np.mean(pr)))
        row = {"part": study.stem, "design": i, "name": name, "x": [round(float(v), 3) for v in x]
               + [round(float(v), 3) for a in added[i] for v in a.centre],
               **{k: v for k, v in s.items() if k not in ("shape",)},
               "sim_pnp_t": sim["pnp"][0], "sim_pnp_r": sim["pnp"][1], "sim_pnp_lost": sim["pnp"][2],
               "sim_iekf_t": sim["iekf"][0], "sim_iekf_r": sim["iekf"][1], "seconds": time.perf_counter() - start,
               "runs_t": {m: [q["trans_mm_rms"] for q in res.summaries[m]] for m in config.estimators},
               "runs_r": {m: [q["rot_deg_rms"] for q in res.summaries[m]] for m in config.estimators}}
        rows.append(row)
        print(json.dumps({k: (round(v, 5) if isinstance(v, float) else v) for k, v in row.items()}), flush=True)
    out = {"study": str(study), "rows": rows, "runs": config.runs, "frames": len(T), "seeds": [args.seed],
           "design_space": spread,
           "variability": {"placement_mm": config.placement_mm, "placement_deg": config.placement_deg,
                           "gain_sigma": config.gain_sigma, "noise_grey": config.sensor.noise_grey}}
    if optimum is not None:
        v = compare(tracks["original"], tracks["g_POSE optimum"], config.alpha, config.min_change)
        out["paired"] = {m: {"verdict": d["verdict"],
                             **{f"{k}_{q}": d[k][q] for k in ("translation", "rotation")
                                for q in ("p_value", "median_change") if q in d[k]},
                             **paired_combined(rows[0], rows[-1], m, config.alpha)}
                         for m, d in v.items()}
    return out


def run_combined(row: dict, est: str) -> np.ndarray:
    """(R,) each run's combined RMS error √(t² + (ℓ r)²) mm (``ROTATION_LENGTH_MM``, r in rad) of a panel row."""
    return np.hypot(np.asarray(row["runs_t"][est], float),
                    ROTATION_LENGTH_MM * np.radians(np.asarray(row["runs_r"][est], float)))


def paired_combined(before: dict, after: dict, est: str, alpha: float) -> dict:
    """The paired Wilcoxon test (``vision.metrics.paired_verdict``, paired by run) on the combined error that
    g_POSE optimises, ``after`` vs ``before`` panel rows of the same runs."""
    from cadfeat.vision.metrics import paired_verdict

    v = paired_verdict(run_combined(before, est), run_combined(after, est), alpha)
    return {"combined_p_value": v["p_value"], "combined_median_change": v["median_change"]}


SIM = ("sim_pnp_t", "sim_pnp_r", "sim_iekf_t", "sim_iekf_r", "propagated_t", "propagated_r")


def merge(panels: list[dict]) -> list[dict]:
    """Panels of the same study and designs from independent seeds → one panel: the simulated RMS over all runs
    (√ of the run-weighted mean square), and the split-half reliability (Spearman ρ between the seeds' simulated
    errors: how far Monte-Carlo noise alone lets a perfect prediction rank the designs)."""
    from scipy.stats import spearmanr

    by: dict[tuple, list[dict]] = {}
    for p in panels:  # the same study and the same designs
        by.setdefault((p["study"], tuple(tuple(r["x"]) for r in p["rows"])), []).append(p)
    out = []
    for group in by.values():
        first = group[0]
        if len(group) == 1:
            out.append(first)
            continue
        runs = np.array([g["runs"] for g in group], float)
        split = {k: float(spearmanr([r[k] for r in group[0]["rows"]], [r[k] for r in group[1]["rows"]]).statistic)
                 for k in SIM[:4]} if len(first["rows"]) >= 4 else None
        for i, row in enumerate(first["rows"]):
            for k in SIM:
                vals = np.array([g["rows"][i][k] for g in group])
                row[k] = float(np.sqrt(np.sum(runs * vals ** 2) / runs.sum()))
            row["seconds"] = float(sum(g["rows"][i]["seconds"] for g in group))
            if all("runs_t" in g["rows"][i] for g in group):   # per-run errors of all sets, in set order
                for key in ("runs_t", "runs_r"):
                    row[key] = {m: [v for g in group for v in g["rows"][i][key][m]] for m in row[key]}
        if split is not None:
            first["split_half"] = {**split, "seeds": [g.get("seeds", [0])[0] for g in group[:2]],
                                   "runs": [g["runs"] for g in group[:2]]}
        first["paired_by_seed"] = [(g.get("seeds", [0])[0], g.get("runs"), g["paired"]) for g in group if "paired" in g]
        first["runs"] = int(runs.sum())
        first["seeds"] = [s for g in group for s in g.get("seeds", [0])]
        out.append(first)
    return out


def repredict(panel: dict, args: argparse.Namespace) -> None:
    """Recompute a stored panel's predicted columns with the current detection/measurement models (the
    simulated columns stay: the closed loop does not depend on the models)."""
    from cadfeat.poses import invert_T
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_study
    from cadfeat.vision import FilterTuning

    setup = setup_study(load_study(Path(panel["study"])))
    traj = setup.trajectory
    idx = np.arange(0, len(traj.T_task_cam), args.frame_step)
    T = (invert_T(np.asarray(traj.T_task_cam)) @ setup.T_task_part)[idx]
    times = np.asarray(traj.times_s)[idx]
    model = None
    if args.model is not None:
        from cadfeat.measures.pose_models import PoseModels

        model = PoseModels(**json.loads(args.model.read_text()))
    x0 = np.asarray(setup.space.x0, float)
    if "design_space" in panel:   # the spread of the predicted error over the feasible space, with these models
        sobol = sum(r["name"].startswith("sobol") for r in panel["rows"])
        panel["design_space"] = designs(pose_setup(Path(panel["study"])), sobol + 1,
                                        candidates=panel["design_space"]["candidates"])[2]
    for row in panel["rows"]:
        x = np.array(row["x"], float)   # a panel from before variables were added: the new ones at the original's
        s = score(setup, np.concatenate([x, x0[len(x):]]), T, times, FilterTuning(), model)
        for k in ("pnp_t", "pnp_r", "iekf_t", "iekf_r", "bias_t", "noise_t", "holes_seen",
                  "eq_pnp_t", "eq_pnp_r", "eq_iekf_t", "eq_iekf_r"):
            row[k] = s[k]
        for j, name in enumerate(row["holes"]):
            seen = row["holes"][name][0] is not None
            row["holes"][name][1] = round(float(np.sqrt(np.mean(s["model_px"][:, j] ** 2))), 4) if seen else None
            row["holes"][name][3] = round(float(s["model_detected"][:, j].mean()), 3)
        print(json.dumps({k: row[k] for k in ("design", "pnp_t", "sim_pnp_t", "pnp_r", "sim_pnp_r")}), flush=True)


KEYS = ("pnp_t", "pnp_r", "iekf_t", "iekf_r")
LABELS = {"pnp_t": "PnP t", "pnp_r": "PnP r", "iekf_t": "IEKF t", "iekf_r": "IEKF r"}
#: ℓ (mm) of the combined error √(e_t² + (ℓ e_r)²) that g_POSE optimises (the studies' pose_rotation_length_mm)
ROTATION_LENGTH_MM = 50.0


def combined(row: dict, est: str, prefix: str = "") -> float:
    """√(e_t² + (ℓ e_r)²) mm of a panel row (e_r in rad): predicted, or simulated with ``prefix`` "sim_" — the
    RMS over runs of each run's combined RMS, exactly, since the stored values are RMS over runs."""
    return float(np.hypot(row[f"{prefix}{est}_t"], ROTATION_LENGTH_MM * np.radians(row[f"{prefix}{est}_r"])))


def statistics(rows: list[dict]) -> dict:
    """Spearman ρ (predicted vs simulated) and the median predicted/simulated ratio per estimator and kind."""
    from scipy.stats import spearmanr

    rho, ratio = {}, {}
    for key in KEYS:
        p = np.array([r[key] for r in rows])
        q = np.array([r[f"sim_{key}"] for r in rows])
        ok = np.isfinite(p) & np.isfinite(q)
        rho[key] = float(spearmanr(p[ok], q[ok]).statistic) if ok.sum() >= 3 else float("nan")
        ratio[key] = float(np.median(p[ok] / q[ok])) if ok.any() else float("nan")
    for est in ("pnp", "iekf"):
        p = np.array([combined(r, est) for r in rows])
        q = np.array([combined(r, est, "sim_") for r in rows])
        rho[f"{est}_combined"] = float(spearmanr(p, q).statistic) if len(p) >= 3 else float("nan")
        ratio[f"{est}_combined"] = float(np.median(p / q))
    for kind in ("t", "r"):
        p = np.array([r[f"propagated_{kind}"] for r in rows])
        q = np.array([r[f"sim_pnp_{kind}"] for r in rows])
        rho[f"propagated_vs_pnp_{kind}"] = float(spearmanr(p, q).statistic) if len(p) >= 3 else float("nan")
    return {"spearman": rho, "ratio_median": ratio,
            "ratio_range": {k: [float(np.min([r[k] / r[f"sim_{k}"] for r in rows])),
                                float(np.max([r[k] / r[f"sim_{k}"] for r in rows]))] for k in KEYS}}


def markdown(panels: list[dict]) -> str:
    """The committed table: per design predicted vs simulated, then ρ and ratios per part and pooled."""
    lines = ["# Pose panel: predicted pose error (g_POSE's model) vs the closed loop", "",
             "Generated by `tools/pose_panel.py` (translation mm, rotation deg; PnP compared with the single-frame "
             "prediction, the IEKF with the posterior CRLB plus the bias; simulated = RMS over the Monte-Carlo runs "
             "of each run's RMS after the settle frames, lost frames at the held last estimate).", ""]
    for pnl in panels:
        v = pnl["variability"]
        name = Path(pnl["study"])
        name = name.relative_to(ROOT) if name.is_absolute() and name.is_relative_to(ROOT) else name
        lines += [f"## {name}", "",
                  f"{len(pnl['rows'])} designs, {pnl['runs']} runs × {pnl['frames']} frames; run-to-run variability: "
                  f"placement σ {v['placement_mm']} mm / {v['placement_deg']}° per axis, illumination gain σ "
                  f"{v['gain_sigma']}, pixel noise σ {v['noise_grey']} grey levels.", "",
                  "| design | holes seen | pred PnP t | sim PnP t | pred PnP r | sim PnP r | pred IEKF t | sim IEKF t "
                  "| pred IEKF r | sim IEKF r | measured offsets propagated t / r | s |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in pnl["rows"]:
            lines.append(f"| {r['design']} {r['name']} | {r['holes_seen']:.2f} | {r['pnp_t']:.4f} "
                         f"| {r['sim_pnp_t']:.4f} "
                         f"| {r['pnp_r']:.4f} | {r['sim_pnp_r']:.4f} | {r['iekf_t']:.4f} | {r['sim_iekf_t']:.4f} "
                         f"| {r['iekf_r']:.4f} | {r['sim_iekf_r']:.4f} | {r['propagated_t']:.4f} / "
                         f"{r['propagated_r']:.4f} | {r['seconds']:.0f} |")
        if "added_sites" in pnl.get("design_space", {}):
            d = pnl["design_space"]
            lines += ["", "Designs (--added): the original with each subset of the added-target curve's greedy sites "
                      "s1…s4 " + ", ".join(f"({', '.join(f'{v:g}' for v in c)})" for c in d["added_sites"])
                      + " mm drilled; the curve's g_POSE for 0–4 holes on the move-only optimum: "
                      + " → ".join(f"{v:.4f}" for v in d["curve_error_mm"]) + " mm."]
        elif "design_space" in pnl:
            d = pnl["design_space"]
            lines += ["", f"Design space: {d['feasible']} of {d['candidates']} Sobol candidates keep every "
                      f"requirement; their predicted error (g_POSE on the feature model, rotation at 50 mm) spans "
                      f"{d['predicted_feasible_min']:.4f}–{d['predicted_feasible_max']:.4f} mm (original "
                      f"{d['predicted_original']:.4f}"
                      + (f"; the first Sobol points {d['predicted_sobol_min']:.4f}–{d['predicted_sobol_max']:.4f}"
                         if "predicted_sobol_min" in d else "") + ")."
                      " \"extreme\" rows: the feasible candidates after those with the lowest and highest of it."]
        if len(pnl["rows"]) >= 4:
            lines += [""] + _stat_lines(pnl["rows"])
            sobol = [r for r in pnl["rows"] if r["name"] == "original" or r["name"].startswith("sobol")]
            if len(sobol) >= 4 and len(sobol) < len(pnl["rows"]):
                st = statistics(sobol)["spearman"]
                lines += ["", f"Without the extremes and the optimum (original + Sobol, n = {len(sobol)}): Spearman ρ "
                          + ", ".join(f"{k} {st[k]:.2f}" for k in KEYS) + "."]
        if "split_half" in pnl:
            sh = pnl["split_half"]
            sb = {k: 2 * sh[k] / (1 + sh[k]) if sh[k] > -1 else float("nan") for k in SIM[:4]}
            lines += ["", "Monte-Carlo reliability: Spearman ρ between the simulated errors of two independent sets "
                      f"of runs (seeds {sh['seeds']}, {sh['runs']} runs): PnP t {sh['sim_pnp_t']:.2f}, "
                      f"PnP r {sh['sim_pnp_r']:.2f}, "
                      f"IEKF t {sh['sim_iekf_t']:.2f}, IEKF r {sh['sim_iekf_r']:.2f} — the ceiling that Monte-Carlo "
                      "noise puts on any prediction's ρ with one such set; for both sets together (Spearman–Brown, "
                      f"2ρ/(1 + ρ)): {sb['sim_pnp_t']:.2f}, {sb['sim_pnp_r']:.2f}, {sb['sim_iekf_t']:.2f}, "
                      f"{sb['sim_iekf_r']:.2f}."]
        for seed, runs, paired in pnl.get("paired_by_seed") or [(pnl.get("seeds", [0])[0], pnl["runs"],
                                                                  pnl.get("paired"))]:
            if not paired:
                continue
            lines += ["", f"Paired closed-loop test, g_POSE optimum vs original (seed {seed}, {runs} runs paired by "
                      "run; Wilcoxon, two-sided):", ""]
            lines += [f"- {m}: {d['verdict']} " + ", ".join(f"{k} {val:.3g}" for k, val in d.items() if k != "verdict")
                      for m, d in paired.items()]
        sets = [paired for _, _, paired in pnl.get("paired_by_seed") or [] if paired]
        if len(sets) >= 2:
            from scipy.stats import combine_pvalues

            lines += ["", f"Fisher's combination of the {len(sets)} independent sets' p-values (the optimum vs the "
                      "original):", ""]
            for m in sets[0]:
                parts = [f"{kind} p = {combine_pvalues([st[m][f'{kind}_p_value'] for st in sets]).pvalue:.2g}"
                         for kind in ("translation", "rotation", "combined")
                         if all(f"{kind}_p_value" in st[m] for st in sets)]
                lines.append(f"- {m}: " + ", ".join(parts))
        first_row, last_row = pnl["rows"][0], pnl["rows"][-1]
        if sets and last_row["name"] == "g_POSE optimum" and "runs_t" in first_row and "runs_t" in last_row:
            from cadfeat.vision.metrics import paired_verdict

            lines += ["", f"All {len(first_row['runs_t']['pnp'])} runs paired by run (Wilcoxon, two-sided), the "
                      "optimum vs the original; median change after − before:", ""]
            for m in first_row["runs_t"]:
                before, after = first_row, last_row
                vals = {"translation": paired_verdict(np.array(before["runs_t"][m]), np.array(after["runs_t"][m])),
                        "rotation": paired_verdict(np.array(before["runs_r"][m]), np.array(after["runs_r"][m])),
                        "combined": paired_verdict(run_combined(before, m), run_combined(after, m))}
                lines.append(f"- {m}: " + ", ".join(f"{k} p = {v['p_value']:.2g} ({v['median_change']:+.2g})"
                                                    for k, v in vals.items()))
        lines.append("")
    ranked = [p for p in panels if len(p["rows"]) >= 4]
    if len({p["study"] for p in ranked}) > 1:
        lines += ["## Pooled over the parts", ""] + _stat_lines([r for p in ranked for r in p["rows"]]) + [""]
    return "\n".join(lines)


def _stat_lines(rows: list[dict]) -> list[str]:
    st = statistics(rows)
    out = ["| | PnP t | PnP r | IEKF t | IEKF r |", "|---|---|---|---|---|",
           "| Spearman ρ predicted vs simulated | " + " | ".join(f"{st['spearman'][k]:.2f}" for k in KEYS) + " |",
           "| predicted/simulated, median | " + " | ".join(f"{st['ratio_median'][k]:.2f}" for k in KEYS) + " |",
           "| predicted/simulated, range | " + " | ".join("{:.2f}–{:.2f}".format(*st["ratio_range"][k]) for k in KEYS)
           + " |",
           "", f"Combined error √(e_t² + (ℓ e_r)²), ℓ = {ROTATION_LENGTH_MM:g} mm (what g_POSE optimises): Spearman ρ "
           f"PnP {st['spearman']['pnp_combined']:.2f}, IEKF {st['spearman']['iekf_combined']:.2f}; predicted/simulated "
           f"median PnP {st['ratio_median']['pnp_combined']:.2f}, IEKF {st['ratio_median']['iekf_combined']:.2f}.",
           "", f"Spearman ρ of the measured offsets propagated vs simulated PnP: "
           f"{st['spearman']['propagated_vs_pnp_t']:.2f} (t), {st['spearman']['propagated_vs_pnp_r']:.2f} (r)."]
    if all("eq_pnp_t" in r for r in rows):
        eq = statistics([{**r, **{k: r[f"eq_{k}"] for k in KEYS}} for r in rows])
        out += ["", "Predicted for the estimators the closed loop runs — every detected hole weighted alike (PnP's "
                "reprojection error, the IEKF's R = r I), error √(bias² + tr G Σ Gᵀ) of that least squares "
                "(`measures.pose_estimator`) instead of the CRLB's 1/σ² weights: Spearman ρ "
                + ", ".join(f"{LABELS[k]} {eq['spearman'][k]:.2f}" for k in KEYS)
                + f"; combined PnP {eq['spearman']['pnp_combined']:.2f}, IEKF {eq['spearman']['iekf_combined']:.2f}; "
                "predicted/simulated " + ", ".join("{:.2f}–{:.2f}".format(*eq["ratio_range"][k]) for k in KEYS) + "."]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", type=Path, action="append", default=None,
                    help="a part-script study (repeatable; default: the flagship)")
    ap.add_argument("--optimum", type=Path, action="append", default=None,
                    help="a results.json per --study whose optimum joins the panel and is paired-tested")
    ap.add_argument("--designs", type=int, default=12)
    ap.add_argument("--extremes", type=int, default=0,
                    help="feasible designs added at the low and high ends of the predicted error (designs())")
    ap.add_argument("--candidates", type=int, default=256, help="Sobol candidates drawn before the requirements")
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--frame-step", type=int, default=2)
    ap.add_argument("--placement-mm", type=float, default=0.2)
    ap.add_argument("--placement-deg", type=float, default=0.2)
    ap.add_argument("--gain-sigma", type=float, default=0.05)
    ap.add_argument("--seed", type=int, default=0, help="the closed loop's base seed (independent Monte-Carlo runs)")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--markdown", type=Path, default=None)
    ap.add_argument("--from-json", type=Path, action="append", default=None,
                    help="only write --markdown from earlier --json outputs")
    ap.add_argument("--repredict", action="store_true",
                    help="with --from-json: recompute the predictions with the current models (no closed loop)")
    ap.add_argument("--notes", type=Path, default=None,
                    help="a markdown file appended to --markdown (the committed panel's notes)")
    ap.add_argument("--supersample", type=int, default=1,
                    help="the closed loop renders with k x k sub-pixels per pixel (render.camera_views."
                         "DEFAULT_SUPERSAMPLE; pair with a --model calibrated at the same k)")
    ap.add_argument("--renderer", choices=("raster", "pbr"), default="raster",
                    help="pbr: the closed loop of `cadfeat run --track pbr` in the study's [cell] (pbr_cell)")
    ap.add_argument("--spp", type=int, default=16, help="with --renderer pbr: samples per pixel")
    ap.add_argument("--material", default=None, help="with --renderer pbr: the finish (cell.material name)")
    ap.add_argument("--light", default=None, choices=("ring", "coaxial", "dome", "spot"),
                    help="with --renderer pbr: the light's kind (default: the study's [cell] light)")
    ap.add_argument("--added", type=Path, default=None,
                    help="results.json of an [add_targets] run: the original with each subset of its greedy sites")
    ap.add_argument("--model", type=Path, default=None,
                    help="a detection_model.json (calibrate_detection.py --study); default: the committed one")
    args = ap.parse_args(argv)
    if args.supersample != 1:
        import cadfeat.render.camera_views as views

        views.DEFAULT_SUPERSAMPLE = args.supersample
    if args.from_json:
        panels = [p for f in args.from_json for p in json.loads(f.read_text())["panels"]]
        panels = merge(panels)
        if args.repredict:
            for p in panels:
                repredict(p, args)
            if args.json:
                args.json.write_text(json.dumps({"panels": panels}, indent=1))
    else:
        studies = args.study or [ROOT / "studies" / "nema17_mount.toml"]
        optima = args.optimum or [None] * len(studies)
        panels = [run_panel(args, st, op) for st, op in zip(studies, optima, strict=True)]
        if args.json:
            args.json.write_text(json.dumps({"panels": panels}, indent=1))
    for p in panels:
        print(p["study"], json.dumps(statistics(p["rows"])), json.dumps(p.get("paired", {})))
    if args.markdown:
        notes = "" if args.notes is None else "\n" + args.notes.read_text()
        args.markdown.write_text(markdown(panels) + notes)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
