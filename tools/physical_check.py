"""The flagship's (or any study's) two exported designs under physical light, with three detectors (docs/results.md,
"Under physical light").

Renders the original and the optimised design of a study's output folder with Mitsuba 3 in the study's cell (its
light; the material given here), the fast check's frames and 8 paired runs (each at its own part placement, the
same seeds for both designs), detects the holes with cadfeat's rim-edge detector, EDCircles and SimpleBlobDetector on
the SAME images, tracks with PnP and the IEKF, and prints per detector the holes found per frame and the median
per-run RMS errors with the paired Wilcoxon p-values, then per hole the share of its expected frames in which it
was found and its centre RMS (px) against the rim at the run's true pose. Run:

    python tools/physical_check.py studies/nema17_mount.toml exports/nema17_mount --material grey_plastic

(docs/results.md's second-session table: ``--runs 16 --seed 7``, each material.)

(~10-20 min on 2 cores: 2 designs x 8 runs x 20 frames of 1280 x 1024 at 16 spp). ``--json OUT`` keeps the runs.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cadfeat.cell.material import Material  # noqa: E402
from cadfeat.measures.rim_centre import measure  # noqa: E402
from cadfeat.study.closed_loop_check import fast_spec  # noqa: E402
from cadfeat.study.schema import load_study  # noqa: E402
from cadfeat.study.tracking import _named, _scene, exported_designs  # noqa: E402
from cadfeat.vision import closed_loop as cl  # noqa: E402

DETECTORS = ("cadfeat", "edcircles", "blob")


def design_runs(config, design, spec) -> dict:
    """One design rendered along the fast check's frames, every run at its placement (``closed_loop.
    run_observations``), then per detector on the same images: holes found per frame and the per-run RMS errors of
    PnP and the IEKF (``closed_loop.detect_runs``, ``estimate_runs``)."""
    camera, T_all, times, screws = _scene(config)
    tc = spec.in_cell(config.cell)
    _, T, t, sc = cl.tracked_frames(T_all, times, screws, tc.frame_step)
    shape, holes = design
    obs = cl.observe(shape, _named(holes), camera, T, tc.sensor, sc, frames=cl.report_frames(len(T)),
                     renderer="pbr", render_options=tc.render_options())
    T_runs, runs_obs = cl.run_observations(camera, obs, T, tc)
    expected = cl.expected_visible(camera, obs, T)
    truth = np.stack([measure(camera, T_r, obs.centres, obs.normals, obs.radii, jacobian=False)[0] for T_r in T_runs])
    out = {}
    for detector in DETECTORS:
        config_d = tc.in_cell(tc.cell.replace(detector=detector))
        pixels, _ = cl.detect_runs(runs_obs, config_d)
        _, summaries = cl.estimate_runs(camera, obs, pixels, T_runs, t, config_d)
        found = np.all(np.isfinite(pixels), -1) & expected
        out[detector] = {"found_per_frame": float(found.sum(-1).mean()),
                         "expected_per_frame": float(expected.sum(-1).mean()),
                         "holes": per_hole(obs.names, pixels, truth, expected),
                         **{m: {"trans": [x["trans_mm_rms"] for x in s], "rot": [x["rot_deg_rms"] for x in s]}
                            for m, s in summaries.items()}}
    return out


def per_hole(names: list[str], pixels: np.ndarray, truth: np.ndarray, expected: np.ndarray) -> dict:
    """Per hole expected in some frame: the share of its expected (run, frame)s in which it was found and the
    RMS and mean (u, v) of the found centres' error (px) against the rim centre at each run's true pose
    (``measures.rim_centre.measure``, the quantity the detectors estimate)."""
    exp = np.broadcast_to(expected, pixels.shape[:3])
    out = {}
    for j, name in enumerate(names):
        if not exp[..., j].any():
            continue
        hit = np.isfinite(pixels[..., j, 0]) & exp[..., j]
        err = (pixels[..., j, :] - truth[..., j, :])[hit]
        out[name] = {"found": float(hit.sum() / exp[..., j].sum()),
                     "rms_px": float(np.sqrt(np.mean(np.sum(err ** 2, -1)))) if len(err) else None,
                     "mean_px": err.mean(0).round(3).tolist() if len(err) else None}
    return out


def hole_lines(before: dict, after: dict) -> list[str]:
    """Per detector and design, each expected hole's found share and centre RMS (px)."""
    lines = []
    for d in DETECTORS:
        for name, runs in (("before", before[d]), ("after", after[d])):
            cells = [f"{h} {v['found']:.2f}" + (f"/{v['rms_px']:.2f}px" if v["rms_px"] is not None else "")
                     for h, v in runs["holes"].items()]
            lines.append(f"  {d:9s} {name:6s} found/RMS: " + ", ".join(cells))
    return lines


def summary(before: dict, after: dict) -> list[str]:
    """One line per detector: holes found and median errors before -> after with paired Wilcoxon p-values."""
    from scipy.stats import wilcoxon

    lines = []
    for d in DETECTORS:
        b, a = before[d], after[d]
        line = f"{d:9s} found/frame {b['found_per_frame']:.2f} -> {a['found_per_frame']:.2f}"
        for m in ("pnp", "iekf"):
            for k in ("trans", "rot"):
                x, y = np.array(b[m][k]), np.array(a[m][k])
                p = wilcoxon(x, y).pvalue if np.any(x != y) else 1.0
                line += f" | {m} {k} {np.median(x):.3g} -> {np.median(y):.3g} (p {p:.2g})"
        lines.append(line)
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("study", type=Path)
    ap.add_argument("out", type=Path, help="the study's output folder (original.step, optimised.step, results.json)")
    ap.add_argument("--material", default=None, help="cadfeat.cell.material name (default: the study's [cell])")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--runs", type=int, default=None, help="paired runs (default: the fast check's 8)")
    ap.add_argument("--seed", type=int, default=None, help="the runs' base seed (default: the study's)")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    config = load_study(args.study)
    if args.material:
        config = replace(config, cell=config.cell.replace(material=Material(name=args.material)))
    spec = fast_spec(config, len(_scene(config)[1])).replace(renderer="pbr", spp=args.spp)
    if args.runs is not None:
        spec = spec.replace(runs=args.runs)
    if args.seed is not None:
        spec = spec.replace(seed=args.seed)
    runs = {name: design_runs(config, d, spec) for name, d in exported_designs(config, args.out).items()}
    print(f"{config.study.name}: {config.cell.material.name}, {config.cell.light.kind} light, {args.spp} spp, "
          f"{spec.runs} paired runs")
    print("\n".join(summary(runs["before"], runs["after"])))
    print("\n".join(hole_lines(runs["before"], runs["after"])))
    if args.json:
        args.json.write_text(json.dumps(runs, indent=1), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
