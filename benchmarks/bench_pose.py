"""Benchmark: cost of ``measures.pose_information`` against the current four measures (``measures.evaluate``)
on the flagship study (studies/nema17_mount.toml: 40 poses × 9 holes), the same batch.

Rows: ``evaluate`` (FOV, focus, resolution, Λ; no occlusion), ``pose_information`` with the calibrated models
(no occlusion input), with a fixed σ and no detection model (the bare Fisher information), the rim occlusion
by depth maps (the optimiser's test; maps built once, not timed) and by the exact ray test, and the posterior
CRLB recursion. Single thread (BLAS threads 1). Median of repeats.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from benchutil import load as _load  # noqa: E402
from benchutil import median_ms, save_section  # noqa: E402


def main() -> str:
    from cadfeat import measures
    from cadfeat.cad.export import mesh_from_shape
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.cad.parts import load_part
    from cadfeat.measures.depth import DepthMaps
    from cadfeat.measures.pose_information import pose_information
    from cadfeat.measures.rim_occlusion import rim_occlusion
    from cadfeat.poses import invert_T
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import _extract, load_scene
    from cadfeat.vision.crlb import posterior_crlb

    load0 = os.getloadavg()[0]
    cfg = load_study(ROOT / "studies" / "nema17_mount.toml")
    camera, traj, T_task_part = load_scene(cfg)
    T = invert_T(traj.T_task_cam) @ T_task_part
    screws = traj.velocity_screws()
    part = load_part(cfg.study.part_path)
    shape = part.build(**part.defaults())
    holes = _extract(shape, part.view_direction)
    c, n, r = holes_to_arrays(holes)
    L, N = len(T), len(c)
    mesh = mesh_from_shape(shape, tolerance=0.05)
    maps = DepthMaps(mesh, camera, T, grid=128)
    occ = rim_occlusion(maps, T, c, n, r)
    rows = [
        ("measures.evaluate (4 measures, no occlusion)",
         median_ms(lambda: measures.evaluate(camera, T, screws, c, n, r, min_axis_px=8.0), 20)),
        ("pose_information (calibrated models)", median_ms(lambda: pose_information(camera, T, c, n, r), 20)),
        ("pose_information, occlusion given", median_ms(lambda: pose_information(camera, T, c, n, r,
                                                                                  occlusion=occ), 20)),
        ("pose_information, σ = 0.3 px, detection=False",
         median_ms(lambda: pose_information(camera, T, c, n, r, sigma_px=0.3, detection=False), 20)),
        ("rim_occlusion, depth maps (16 samples per rim)", median_ms(lambda: rim_occlusion(maps, T, c, n, r), 10)),
        ("rim_occlusion, exact ray test (16 samples per rim)", median_ms(lambda: rim_occlusion(mesh, T, c, n, r), 2)),
    ]
    info = pose_information(camera, T, c, n, r, occlusion=occ).information
    rows.append(("posterior_crlb (40 steps, 12 states)",
                 median_ms(lambda: posterior_crlb(info, np.asarray(traj.times_s)), 20)))
    machine = _load("run_all", HERE / "run_all.py").machine_description()
    lines = [f"## Pose information (bench_pose)\n\nMachine: {machine}; load average {load0:.1f} at the start, "
             f"{os.getloadavg()[0]:.1f} at the end (a machine shared with other jobs: the ratios to the baseline, "
             "measured in the same run, are the numbers to compare).\n\n"
             f"Flagship nema17_mount ({', '.join(cfg.objective.measures)} objective, "
             f"{len(cfg.design.parameters)} design variables): L = {L} poses × N = {N} holes, one batch; "
             "single thread; median wall time.\n", "| step | ms |", "|---|---|"]
    base = rows[0][1]  # the baseline: the four thesis measures on the same batch, measured in this run
    lines[-2:] = ["| step | ms | × the four measures |", "|---|---|---|"]
    lines += [f"| {name} | {ms:.2f} | {ms / base:.1f} |" for name, ms in rows]
    return save_section("bench_pose", "\n".join(lines))


if __name__ == "__main__":
    print(main())
