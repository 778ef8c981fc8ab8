"""A realistic results dict (the keys of results.json, contracts.md) from a small real computation.

A CadQuery plate with four through holes, the RealSense camera preset and a straight approach trajectory.
One design variable ``dx_A`` moves hole A along x; a sweep over it (per-pose measures batched over the
whole sweep) picks the "after" design, which is rebuilt in CAD, re-extracted and exported to STEP. The
measures come from ``cadfeat.measures.evaluate``.
"""

from __future__ import annotations

import atexit
import functools
import hashlib
import importlib.metadata
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

PLATE = (120.0, 90.0, 8.0)  # mm
HOLES = {"A": (-30.0, 20.0, 4.0), "B": (30.0, 20.0, 4.0), "C": (-30.0, -20.0, 5.0), "D": (30.0, -20.0, 3.0)}
FIXED = ("D",)
MIN_AXIS_PX = 5.0
EDGE_MM = 5.0


def build_plate(dx_a: float = 0.0):
    """The plate (mm) with hole A shifted by ``dx_a`` along x; returns a cq.Workplane."""
    import cadquery as cq

    plate = cq.Workplane("XY").box(*PLATE).translate((0, 0, -PLATE[2] / 2))  # top face at z = 0
    for name, (x, y, r) in HOLES.items():
        x = x + (dx_a if name == "A" else 0.0)
        plate = plate.cut(cq.Workplane("XY").circle(r).extrude(PLATE[2] * 3).translate((x, y, -PLATE[2] * 1.5)))
    return plate


def _named(holes) -> list:
    """Extracted holes named A..D by their position (nearest construction centre)."""
    from dataclasses import replace

    ref = {n: np.array([x, y]) for n, (x, y, _) in HOLES.items()}
    out = []
    for h in holes:
        name = min(ref, key=lambda n: np.linalg.norm(ref[n] - h.centre[:2]))
        out.append(replace(h, name=name))
    return sorted(out, key=lambda h: h.name)


def evaluate(camera, T_cam_part, screws, centres, axes, radii) -> dict[str, np.ndarray]:
    """``cadfeat.measures.evaluate`` as a dict of arrays."""
    from cadfeat import measures

    m = measures.evaluate(camera, T_cam_part, screws, centres, axes, radii, min_axis_px=MIN_AXIS_PX)
    keys = ("fov", "fov_px", "focus", "resolution_px", "visible", "centre_px", "sigma_min", "condition",
            "resolvability")
    return {k: np.asarray(getattr(m, k)) for k in keys}


def measures_block(m: dict[str, np.ndarray], times: np.ndarray, names: list[str]) -> dict[str, Any]:
    """The results.json ``measures.before``/``after`` block from (L, N) arrays."""
    worst = np.argmin(np.minimum(m["fov"], m["focus"]), axis=0)
    per_feature = [dict(index=j, name=names[j], fov_min=float(m["fov"][:, j].min()),
                        fov_px_min=float(m["fov_px"][:, j].min()), focus_min=float(m["focus"][:, j].min()),
                        resolution_px_min=float(m["resolution_px"][:, j].min()),
                        visible_frac=float(m["visible"][:, j].mean()), worst_pose=int(worst[j]))
                   for j in range(len(names))]
    per_pose = dict(time_s=times.tolist(), resolvability=m["resolvability"].tolist(),
                    sigma_min=m["sigma_min"].tolist(), condition=m["condition"].tolist(),
                    fov_min=m["fov"].min(1).tolist(), focus_min=m["focus"].min(1).tolist(),
                    resolution_px_min=m["resolution_px"].min(1).tolist(), centre_px=m["centre_px"].tolist())
    return dict(per_feature=per_feature, per_pose=per_pose)


def objective_values(m: dict[str, np.ndarray]) -> dict[str, float]:
    """Trajectory sums of the worst margin per pose (eq. 3.24 style) and of Λ (eq. 4.33)."""
    return dict(g_FOV=float(m["fov"].min(1).sum()), g_FOC=float(m["focus"].min(1).sum()),
                g_RES=float(m["resolution_px"].min(1).sum()), g_DIR=float(m["resolvability"].sum()))


def hole_dict(h, index: int) -> dict[str, Any]:
    return dict(index=index, name=h.name, centre_mm=[float(c) for c in h.centre], axis=[float(a) for a in h.axis],
                radius_mm=float(h.radius_mm), depth_mm=float(h.depth_mm), through=bool(h.through), kind=h.kind,
                fixed=h.name in FIXED, movable=h.name == "A")


def constraint_checks(holes) -> list[dict[str, Any]]:
    """Edge distance of each hole to the plate border and the smallest ligament, measured on the holes."""
    checks = []
    for i, h in enumerate(holes):
        edge = min(PLATE[0] / 2 - abs(h.centre[0]), PLATE[1] / 2 - abs(h.centre[1])) - h.radius_mm
        checks.append(dict(name="edge_distance", holes=[i], required=EDGE_MM, value=float(edge),
                           margin=float(edge - EDGE_MM), unit="mm", ok=bool(edge >= EDGE_MM), checked_on="brep"))
    c = np.array([h.centre for h in holes])
    r = np.array([h.radius_mm for h in holes])
    gap = np.linalg.norm(c[:, None] - c[None], axis=-1) - r[:, None] - r[None]
    gap[np.diag_indices(len(holes))] = np.inf
    i, j = np.unravel_index(np.argmin(gap), gap.shape)
    checks.append(dict(name="ligament", holes=[int(i), int(j)], required=6.0, value=float(gap[i, j]),
                       margin=float(gap[i, j] - 6.0), unit="mm", ok=bool(gap[i, j] >= 6.0), checked_on="step"))
    return checks


def build_case(out_dir: str | Path, n_poses: int = 30, n_sweep: int = 21) -> tuple[dict[str, Any], Any]:
    """(results, ReportContext) for the plate study; writes the STEP files into ``out_dir``."""
    from cadfeat.cad.export import export_step, sha256_file
    from cadfeat.cad.features import extract_holes, holes_to_arrays
    from cadfeat.camera import Camera
    from cadfeat.poses import invert_T
    from cadfeat.report import ReportContext
    from cadfeat.trajectory import straight_approach

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    camera = Camera.preset("realsense-d435-rgb").replace(f_number=1.4, aperture_mm=None)  # finite far plane
    traj = straight_approach(start=(-140.0, -60.0, 330.0), end=(120.0, 50.0, 240.0), target=(0.0, 0.0, 0.0),
                             n=n_poses, duration_s=3.0)
    T_cam_part = invert_T(traj.T_task_cam)
    screws = traj.velocity_screws()
    shape_b = build_plate(0.0).val()
    holes_b = _named(extract_holes(shape_b, prefer_direction=(0, 0, 1)))
    names = [h.name for h in holes_b]
    centres, axes, radii = holes_to_arrays(holes_b)

    lo, hi = -14.0, 14.0
    values = np.linspace(lo, hi, n_sweep)
    sweep_obj: dict[str, list[float]] = {}
    for dx in values:  # 21 evaluations of the batched measures, as a one-variable study would
        moved = centres.copy()
        moved[names.index("A"), 0] += dx
        for k, v in objective_values(evaluate(camera, T_cam_part, screws, moved, axes, radii)).items():
            sweep_obj.setdefault(k, []).append(v)
    best = float(values[int(np.argmax(sweep_obj["g_DIR"]))])

    shape_a = build_plate(best).val()
    holes_a = _named(extract_holes(shape_a, prefer_direction=(0, 0, 1)))
    m_b = evaluate(camera, T_cam_part, screws, centres, axes, radii)
    m_a = evaluate(camera, T_cam_part, screws, *holes_to_arrays(holes_a))
    obj_b, obj_a = objective_values(m_b), objective_values(m_a)
    ref = {k: abs(v) or 1.0 for k, v in obj_b.items()}
    files = []
    for name, shape in (("original.step", shape_b), ("optimised.step", shape_a)):
        path = export_step(shape, out_dir / name)
        files.append(dict(name=name, bytes=path.stat().st_size, sha256=sha256_file(path)))
    history = [dict(iteration=i, f=-v, combined=v, feasible=bool(abs(x) <= 12.0), phase="sweep", time_s=0.01 * i)
               for i, (x, v) in enumerate(zip(values, sweep_obj["g_DIR"], strict=True))]
    pareto_pts = np.array([sweep_obj["g_FOV"], sweep_obj["g_DIR"]]).T
    results: dict[str, Any] = dict(
        cadfeat_version="0.1.0", created="2026-11-23T09:00:00+00:00",
        study=dict(name="plate_<demo> & co", file="studies/plate.toml", part="tests/report_fixture.py",
                   part_kind="script", seed=1, description="Four-hole plate, hole A slides along x."),
        inputs=dict(variables=["dx_A"], camera="realsense-d435-rgb"),
        camera=camera.to_dict(), trajectory=dict(kind="straight_approach", n_samples=n_poses, duration_s=3.0),
        variables=[dict(name="dx_A", unit="mm", lower=lo, upper=hi, before=0.0, after=best, standard_sizes=None)],
        holes=dict(before=[hole_dict(h, i) for i, h in enumerate(holes_b)],
                   after=[hole_dict(h, i) for i, h in enumerate(holes_a)]),
        objectives=dict(names=list(obj_b), combine="weighted", aggregate="sum", before=obj_b, after=obj_a,
                        normalisation=dict(method="reference", reference=ref,
                                           note="Each objective divided by |its value on the original design|."),
                        combined_before=float(sum(v / ref[k] for k, v in obj_b.items())),
                        combined_after=float(sum(v / ref[k] for k, v in obj_a.items()))),
        measures=dict(before=measures_block(m_b, traj.times_s, names), after=measures_block(m_a, traj.times_s, names)),
        constraints=constraint_checks(holes_a),
        design_matrix=dict(rows=[f"position {n}" for n in names], cols=["dx_A"],
                           matrix=[[1.0 if n == "A" else 0.0] for n in names], verdict="uncoupled",
                           note="Only hole A depends on dx_A."),
        history=history,
        sweep=dict(variable="dx_A", values=values.tolist(), objectives=sweep_obj),
        pareto=dict(names=["g_FOV", "g_DIR"], points=pareto_pts.tolist(), chosen=int(np.argmax(sweep_obj["g_DIR"]))),
        files=files, timings_s=dict(build=0.2, optimise=0.05, export=0.1),
        versions={lib: importlib.metadata.version(lib) for lib in ("numpy", "cadquery", "matplotlib")},
        interrupted=False,
        verification=dict(step_roundtrip_max_error_mm=0.0, brep_valid=True, stl_watertight=True))
    context = ReportContext(shape_before=shape_b, shape_after=shape_a, holes_before=holes_b, holes_after=holes_a,
                            fixed_mask=[h.name in FIXED for h in holes_b], camera=camera, trajectory=traj,
                            T_task_part=np.eye(4), sample_indices=None)
    return results, context


def file_digest(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@functools.cache
def shared_case() -> tuple[Path, dict[str, Any], Any]:
    """``build_case`` once per test process (several test modules use it): (out_dir, results, context).
    Callers must not mutate the results (deep-copy first)."""
    out = Path(tempfile.mkdtemp(prefix="cadfeat-report-case-"))
    atexit.register(shutil.rmtree, out, True)
    results, context = build_case(out)
    return out, results, context


ROBUST_SOURCES = ("cell", "camera", "placement", "path", "pixel_noise", "manufacturing")


def _stats(nominal: float, p05: float) -> dict:
    one = {"nominal": nominal, "mean": (nominal + p05) / 2, "p05": p05, "p10": (nominal + 3 * p05) / 4, "min": p05 - 1}
    return {s: {"g_FOV": dict(one), "combined": dict(one)} for s in ROBUST_SOURCES}


def robustness_block(recommended: str) -> dict:
    """A hand-written results.json ``robustness`` block (issue 18) whose recommended design is ``recommended``:
    the report's robust section (tests/report/test_robust_report.py) and its typed model
    (tests/results/test_typed_sections.py)."""
    rng = np.random.default_rng(0)
    designs = {"original": _stats(-0.66, -1.1), "robust": _stats(0.95, 0.35), "nominal": _stats(0.98, -1.3)}
    block = {"original": designs["original"], "recommended": designs[recommended]}
    block.update({k: v for k, v in designs.items() if k not in ("original", recommended)})
    dists = {k: {"combined": {s: list(rng.normal(v["cell"]["combined"]["nominal"], 0.3, 50)) for s in ROBUST_SOURCES},
                 "objectives_cell": {"g_FOV": list(rng.normal(0.0, 1.0, 50))}} for k, v in designs.items()}
    return {"objective": {"robust": True, "statistic": "percentile", "label": "p10", "draws": 64, "sampling": "sobol",
                          "seed": 1},
            "uncertainty": {"camera_position_mm": [2.0, 2.0, 2.0], "camera_angle_deg": [1.0, 1.0, 1.0]},
            "designs": block, "recommended": recommended, "delivered": "robust", "reason": "stated reason",
            "flagged": ["nominal"] + (["robust"] if recommended == "original" else []),
            "out_of_sample": {"statistic": "p10", "draws_in_sample": 64, "seed_in_sample": 1,
                              "draws_out_of_sample": 200, "seed_out_of_sample": 2,
                              "designs": {"original": {"in_sample": -0.9, "out_of_sample": -0.87},
                                          "robust": {"in_sample": 0.07, "out_of_sample": -0.06},
                                          "nominal": {"in_sample": -0.2, "out_of_sample": -0.36}}},
            "sensitivity": {"words": "most sensitive to the camera mounting error (61 %)"},
            "distributions": dists}
