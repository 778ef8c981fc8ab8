#!/usr/bin/env python3
"""cadfeat's number for each number of the thesis's chapter 5 (README "The thesis's numbers"; docs/results.md).

    PYTHONPATH=. .venv/bin/python tools/thesis_numbers.py      # about 20 s; prints one block per thesis number

- Table 5.1 and §5.4.2 (Fig. 5.9): the FOV cone margins (eq. 3.3) of eight points yawed by 0.377 rad, the camera
  of Table A.2 128 mm above them (at x = 0 and x = 20 mm). Fig. 5.9's object is only in the figure: the points
  here are ``tests/measures/test_measures_margins.py``'s reconstruction, on a 25 mm circle. Also the distance from
  the optical axis at which each of the thesis's margins lies, for this camera.
- Fig. 5.10 (a)-(c): g_DIR (eq. 4.33) over the edge d on the §5.4.3 paths (``thesis_four_points.toml``'s for the
  square and the four points, ``thesis_cube.toml``'s for the cube), the optimum on 2-3 mm and on 2-6 mm, the largest
  condition number of the image Jacobian along the path, and g_DIR with the image-path direction D from the
  projected points' finite differences (eq. 4.29-4.30) instead of J γ̇.
- Fig. 5.11 / eq. 5.2: ``thesis_combined.toml``'s optimum (the optimiser's, before the shop's 0.01 mm grid), the
  objective that limits it, the normalised objectives there, and where the visual measures stop being positive
  along its path.

The numbers are the study set-ups' own (``setup_study``: the part built and extracted once, the feature map, the
optimiser), the same as ``cadfeat run`` reports before rounding for the shop.
"""

from __future__ import annotations

import sys
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _setup(study_name: str, **sections: Any) -> Any:
    """The set-up of ``studies/<study>.toml`` with ``sections`` replaced (a section's keys updated)."""
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_study

    data = tomllib.loads((ROOT / "studies" / f"{study_name}.toml").read_text())
    for name, values in sections.items():
        data[name] = {**data.get(name, {}), **values}
    return setup_study(load_study(data, base_dir=ROOT / "studies"))


def table_5_1() -> None:
    from cadfeat import measures
    from cadfeat.camera import Camera
    from cadfeat.poses import invert_T, make_T, points_in_frames

    cam = Camera.preset("dalsa-cad1-128a").without_distortion()
    cam = cam.replace(fy=cam.fx)
    ang = 0.377 + np.arange(8) * np.pi / 4
    pts = np.column_stack([25 * np.cos(ang), 25 * np.sin(ang), np.zeros(8)])
    print("Table 5.1 / §5.4.2 (Fig. 5.9): thesis (c) 0.0093 0.0203 0.0295 0.0295 0.0203 0.0093 0.0251 0.0251, all "
          "inside; (b) at x = 20 mm: points 1, 2, 8 outside")
    for x in (0.0, 20.0):
        T_world_cam = make_T(np.diag([1.0, -1.0, -1.0]), [x, 0.0, 128.0])
        m = measures.fov_cone_margin(cam, points_in_frames(invert_T(T_world_cam)[None], pts)[0])
        print(f"  cadfeat, 8 points on a 25 mm circle, camera at x = {x:g} mm: margins {np.round(m, 4).tolist()}, "
              f"{int((m < 0).sum())} outside")
    cos_half = np.cos(cam.fov_rad / 2)
    for v in (0.0093, 0.0203, 0.0295, 0.0251):
        rho = 128.0 * np.tan(np.arccos(v + cos_half))
        print(f"  the thesis's margin {v}: a point {rho:.1f} mm off the optical axis at 128 mm (α/2 = "
              f"{np.degrees(cam.fov_rad / 2):.2f}°)")


def _g_dir_curve(setup: Any, ds: np.ndarray) -> tuple[np.ndarray, float]:
    """g_DIR at each d, and the largest condition number of the image Jacobian over the path and the designs."""
    from cadfeat import measures

    p = setup.problem
    G, _ = p.evaluate_batch(ds[:, None])
    worst = 0.0
    for d in ds:
        c, a, r = p.model.features(np.array([d]))
        m = measures.evaluate(p.camera, p.T_cam_part, p.screws, c, a, r)
        worst = max(worst, float(np.max(m.condition)))
    return G[:, p.names.index("g_DIR")], worst


def _g_dir_finite_differences(setup: Any, ds: np.ndarray) -> np.ndarray:
    """Σ_k Λ_k with Λ_k = 1/‖J_k⁺ D_k‖, D_k the projected points' forward difference (eq. 4.29-4.32)."""
    from cadfeat import measures

    p = setup.problem
    out = []
    for d in ds:
        c, _, _ = p.model.features(np.array([d]))
        P = np.einsum("lij,nj->lni", p.T_cam_part[:, :3, :3], c) + p.T_cam_part[:, None, :3, 3]
        L = len(P)
        J = measures.image_jacobian(p.camera, P).reshape(L, -1, 6)
        uv = p.camera.project(P).reshape(L, -1)
        flow = np.vstack([uv[1:] - uv[:-1], uv[-1:] - uv[-2:-1]])
        D = flow / np.linalg.norm(flow, axis=-1, keepdims=True)
        out.append(float(np.sum(1.0 / np.linalg.norm(np.einsum("lij,lj->li", np.linalg.pinv(J), D), axis=-1))))
    return np.array(out)


def fig_5_10() -> None:
    ds = np.arange(2.0, 6.0001, 0.25)
    cases = [("(a) square", "thesis F minimised at the lower bound d = 2 mm ('odd results': ill-conditioned J)",
              _setup("thesis_four_points", study={"part": "../parts/thesis_square_points.py"},
                     design={"parameters": ["side_mm"]})),
             ("(b) four points not on a square", "thesis: optimum 2 mm on 2-3 mm, 6 mm on 2-6 mm",
              _setup("thesis_four_points")),
             ("(c) cube", "thesis: quasi-linear, rising: optimum 6 mm", _setup("thesis_cube"))]
    print("Fig. 5.10: g_DIR (px/mm, summed over the path) against d on the §5.4.3 paths")
    for label, thesis, setup in cases:
        g, cond = _g_dir_curve(setup, ds)
        fd = _g_dir_finite_differences(setup, ds)
        low = ds <= 3.0 + 1e-9
        step = np.diff(g)
        print(f"  {label}: {thesis}")
        print(f"    cadfeat: g_DIR {g[0]:.1f} (d = 2) -> {g[low][-1]:.1f} (3) -> {g[-1]:.1f} (6); steps per 0.25 mm "
              f"{step.min():.2f} ... {step.max():.2f}; optimum {ds[low][np.argmax(g[low])]:g} mm on 2-3 mm, "
              f"{ds[np.argmax(g)]:g} mm on 2-6 mm; largest condition number along the path {cond:.0f}")
        print(f"    with D from the image path's finite differences: {fd[0]:.1f} -> {fd[low][-1]:.1f} -> {fd[-1]:.1f}")


def fig_5_11() -> None:
    from cadfeat.design.objectives import per_pose_values
    from cadfeat.design.optimize import optimise

    s = _setup("thesis_combined")
    p = s.problem
    res = optimise(p, s.config.optimizer)
    g = np.array([res.objectives_best[n] for n in p.names])
    gn = p.normalised(g)
    print("Fig. 5.11 / eq. 5.2: thesis d = 1.41 mm (max-min of normalised g_FOV, g_DIR, g_FOC; focus never limits, "
          "§5.5.2)")
    print(f"  cadfeat (thesis_combined.toml, d in [{p.space.lower[0]:g}, {p.space.upper[0]:g}] mm): optimum d = "
          f"{res.x_best[0]:.4f} mm, combined {res.combined_best:.4f}, limiting {p.limiting(g)}; normalised "
          + ", ".join(f"{n} {v:.3f}" for n, v in zip(p.names, gn, strict=True)))
    ds = np.round(np.arange(1.0, 6.0001, 0.01), 2)
    c, a, r = p.model.features_batch(ds[:, None])
    from cadfeat.design.problem import _Arrays  # the optimiser's own per-pose arrays

    per_pose = per_pose_values(_Arrays(p.pose_arrays(c, np.broadcast_to(a, c.shape), r)), p.objective_config,
                               p.feature_mask)
    ok = (per_pose["fov"].min(axis=-1) >= 0) & (per_pose["focus"].min(axis=-1) >= 0)
    print(f"  on its path every corner is in view and in focus at every pose for d <= {ds[ok].max():.2f} mm; beyond, "
          f"the focus margin goes negative at the end of the approach (worst pose at d = 6 mm: "
          f"{per_pose['focus'].min(axis=-1)[-1]:.3f})")
    G, _ = p.evaluate_batch(np.array([[1.0], [2.0]]))
    print("  over the range, raw: " + "; ".join(f"{n} {G[0, i]:.4f} (d = 1) -> {G[1, i]:.4f} (d = 2)"
                                                 for i, n in enumerate(p.names)))


def main(argv: list[str] | None = None) -> int:
    del argv
    table_5_1()
    fig_5_10()
    fig_5_11()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
