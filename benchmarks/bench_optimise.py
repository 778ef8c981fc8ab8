"""Benchmark: the optimiser on feature geometry vs the same optimiser rebuilding the CAD model at every evaluation.

Part: ``parts/industrial_plate.py`` (120 × 80 × 10 mm plate, 7 fixed functional holes, 4 free target holes).
Variables: the first two target holes' centres and the common target radius (5 variables; 3 in quick mode).
Camera ``basler-aca1300-200um-8mm`` on a straight approach above the plate; objectives FOV + resolution +
resolvability, mean over the trajectory, weighted sum; edge distance and ligament 3 mm.

Both runs use the SAME solver (SLSQP, finite differences, same start, same settings) — only the feature
model differs: (a) ``LinearFeatureModel`` from the part's ``design_map`` (CAD finite differences once, then
feature arithmetic), (b) a model that builds the part with CadQuery and re-extracts its holes for every
evaluated design (the baseline). The optima are compared (they must agree, the map of this part is exact).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from benchutil import load as _load
from benchutil import save_section


class RebuildFeatureModel:
    """Baseline feature model: every design is built in CAD and its holes re-extracted (matched to the
    reference holes by geometry)."""

    def __init__(self, part, names, holes0):
        self.part, self.names, self.holes = part, list(names), list(holes0)
        self.n_builds = 0

    def features_batch(self, X):
        from cadfeat.cad.features import holes_to_arrays, match_holes

        out = []
        for x in np.atleast_2d(X):  # one CAD build per design: the point of the baseline
            holes = self.part.holes(**dict(zip(self.names, map(float, x), strict=True)))
            self.n_builds += 1
            idx = match_holes(self.holes, holes, tol_mm=60.0, axis_tol_rad=1e-3)
            out.append(holes_to_arrays([holes[i] for i in idx]))
        return tuple(np.stack(a) for a in zip(*out, strict=True))

    def features(self, x):
        c, a, r = self.features_batch(np.asarray(x)[None])
        return c[0], a[0], r[0]


def _problem(model, space, fixed, mesh=None, normaliser=None):
    from cadfeat.camera import Camera
    from cadfeat.design.constraints import ConstraintConfig
    from cadfeat.design.objectives import ObjectiveConfig
    from cadfeat.design.problem import Problem
    from cadfeat.trajectory import straight_approach

    camera = Camera.preset("basler-aca1300-200um-8mm")
    traj = straight_approach((-30, -120, 380), (30, 120, 260), (0, 0, 0), n=30)
    cfg = ObjectiveConfig(measures=("fov", "resolution", "resolvability"), aggregate="mean", combine="weighted")
    return Problem(space, model, camera, traj, np.eye(4), cfg, ConstraintConfig(edge_distance_mm=3.0, ligament_mm=3.0),
                   fixed, occlusion_mesh=mesh, normaliser=normaliser)


def main(quick: bool = False) -> str:
    from cadfeat.cad.design_map import design_map
    from cadfeat.cad.parts import load_part
    from cadfeat.design.design_space import DesignSpace, LinearFeatureModel, Variable
    from cadfeat.design.optimize import OptimizerConfig, optimise

    machine = _load("run_all", HERE / "run_all.py").machine_description()
    part = load_part(ROOT / "parts" / "industrial_plate.py")
    names = (["target_1_x_mm", "target_1_y_mm", "target_radius_mm"] if quick else
             ["target_1_x_mm", "target_1_y_mm", "target_2_x_mm", "target_2_y_mm", "target_radius_mm"])
    defaults = part.defaults()
    x0 = np.array([defaults[n] for n in names], dtype=float)
    space = DesignSpace([Variable(n, part.parameters[n].lower, part.parameters[n].upper, "mm",
                                  "diameter" if "radius" in n else "position") for n in names], x0)
    config = OptimizerConfig(method="local", maxiter=40 if quick else 100, seed=0)

    t = time.perf_counter()
    dm = design_map(part, names)
    t_map = time.perf_counter() - t
    feat_model = LinearFeatureModel.from_design_map(dm, names, x0)
    fixed = ~feat_model.moved_mask()
    from cadfeat.cad.export import mesh_from_shape

    mesh = mesh_from_shape(part.build(), tolerance=0.05)  # occlusion on, as in every study
    feat_problem = _problem(feat_model, space, fixed, mesh)
    t = time.perf_counter()
    _ = feat_problem.normaliser  # the payoff table (normalisation): K single-objective solves on features
    t_payoff = time.perf_counter() - t
    t = time.perf_counter()
    feat = optimise(feat_problem, config)
    t_feat = time.perf_counter() - t

    cad_model = RebuildFeatureModel(part, names, dm.holes0)
    cad_problem = _problem(cad_model, space, fixed, mesh, feat_problem.normaliser)
    t = time.perf_counter()
    cad = optimise(cad_problem, config)
    t_cad = time.perf_counter() - t

    dx = float(np.max(np.abs(feat.x_best - cad.x_best)))
    df = abs(feat.combined_best - cad.combined_best)
    ratio = t_cad / t_feat
    ratio_with_map = t_cad / (t_feat + t_map + t_payoff)
    rows = [
        ("features (design map, then feature arithmetic)", t_feat, feat.n_evals, len(feat.history)),
        ("CAD rebuild + re-extraction at every evaluation", t_cad, cad.n_evals, len(cad.history)),
    ]
    lines = [
        "## Optimiser: feature model vs CAD rebuild per evaluation",
        "",
        f"Part `parts/industrial_plate.py`, {len(names)} variables ({', '.join(names)}), "
        f"{len(dm.holes0)} holes, 30 poses, occlusion by the part counted; SLSQP with central finite differences, "
        "same start, settings and normalisation (the feature run's payoff table, timed apart)"
        f"{' (quick mode)' if quick else ''}. Machine: {machine}.",
        "",
        "| run | time (s) | evaluations | iterations | ms / evaluation |",
        "|---|---:|---:|---:|---:|",
    ]
    lines += [f"| {name} | {t_:.3f} | {n} | {it} | {1e3 * t_ / max(n, 1):.3f} |" for name, t_, n, it in rows]
    lines += [
        "",
        f"- Design map (one-off, {dm.n_builds} CAD builds, linear: {dm.linear}): {t_map:.2f} s; payoff table "
        f"(one-off normalisation, on features): {t_payoff:.2f} s.",
        f"- **Speed-up: {ratio:.0f}×** (optimiser alone; target ≥ 100×); {ratio_with_map:.1f}× including the "
        "design map's and the payoff table's one-off costs.",
        f"- Same optimum: max |Δx| = {dx:.2e} (variable units), |Δ combined| = {df:.2e}; "
        f"optimum {dict(zip(names, np.round(feat.x_best, 4).tolist(), strict=True))}.",
        "",
    ]
    return save_section("bench_optimise", "\n".join(lines))


if __name__ == "__main__":
    print(main(quick="--quick" in sys.argv))
