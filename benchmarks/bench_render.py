"""Benchmark: off-screen rendering (PyVista on EGL, Mesa) — part views and synthetic camera images.

Times, on a 120x80x8 mm plate with 6 plain and 2 counterbored holes: tessellation to PolyData, creating a
plotter, one ``render_part`` picture (900x700, SSAA), one ``render_comparison`` pair (1000x760, trajectory
and frusta), and synthetic camera images (Basler 1280x1024 and RealSense 640x480 presets) — N images
through ONE plotter (``CameraViewRenderer``, the way studies render trajectory samples) versus a new
plotter per image (the baseline, measured in the same run; the mesh is tessellated once for both).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from benchutil import load as _load
from benchutil import median_ms as _median_ms
from benchutil import save_section


def _plate(shift: float = 0.0):
    import cadquery as cq

    plain = [(-45 + shift, -25), (-15, -25), (15, -25), (45, -25 + shift), (-45, 25), (45, 25)]
    wp = cq.Workplane("XY").box(120, 80, 8).faces(">Z").workplane().pushPoints(plain).hole(8)
    return wp.faces(">Z").workplane().pushPoints([(-15, 20), (15 + shift, 20)]).cboreHole(8, 14, 3).val()


def _poses(n: int):
    import numpy as np

    from cadfeat.poses import invert_T, look_at

    s = np.linspace(0.0, 1.0, n)
    eyes = np.stack([-120 + 240 * s, -60 + 30 * s, 260 - 60 * s], axis=-1)
    T_task_cam = look_at(eyes, np.zeros(3), up=(0.0, 1.0, 0.0))
    return T_task_cam, invert_T(T_task_cam)


def main(quick: bool = False) -> str:
    from cadfeat.cad.features import extract_holes
    from cadfeat.camera import Camera
    from cadfeat.render import CameraViewRenderer, new_plotter, render_comparison, render_part, shape_polydata

    machine = _load("run_all", HERE / "run_all.py").machine_description()
    repeats = 2 if quick else 5
    n_views = 5 if quick else 20
    before, after = _plate(), _plate(6.0)
    holes_b, holes_a = extract_holes(before), extract_holes(after)
    mesh = shape_polydata(before)
    T_task_cam, T_cam_part = _poses(n_views)
    rows: list[tuple[str, float, str]] = []

    def plotter_only() -> None:
        new_plotter((640, 480)).close()

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        plotter_only()  # first EGL context of the process (driver load) is not counted
        rows.append(("tessellate plate → PolyData (0.01 mm)", _median_ms(lambda: shape_polydata(before), repeats), ""))
        rows.append(("create + close a 640x480 plotter", _median_ms(plotter_only, repeats), ""))
        rows.append(("render_part 900x700 (SSAA)", _median_ms(lambda: render_part(before, tmp / "p.png", holes_b),
                                                               repeats), "per image"))
        cam = Camera.preset("basler-aca1300-200um-8mm")
        pair = _median_ms(lambda: render_comparison(before, after, holes_b, holes_a, [False] * len(holes_b), tmp,
                                                    trajectory=T_task_cam, camera=cam), repeats)
        rows.append(("render_comparison pair 1000x760, per image", pair / 2, "per image"))
        ratios = []
        for preset in ("realsense-d435-rgb", "basler-aca1300-200um-8mm"):
            camera = Camera.preset(preset)
            size = f"{camera.width}x{camera.height}"

            def reuse(overlay: bool = False, camera: Camera = camera) -> None:
                with CameraViewRenderer(before, holes_b, camera, mesh=mesh) as r:
                    for T in T_cam_part:
                        r.render(T, overlay=overlay)

            def fresh(camera: Camera = camera) -> None:
                for T in T_cam_part:
                    with CameraViewRenderer(before, holes_b, camera, mesh=mesh) as r:
                        r.render(T)

            t_reuse = _median_ms(reuse, repeats) / n_views
            t_overlay = _median_ms(lambda: reuse(True), repeats) / n_views
            t_fresh = _median_ms(fresh, max(1, repeats // 2)) / n_views
            ratios.append((size, t_fresh / t_reuse))
            rows.append((f"camera view {size}, {n_views} poses, new plotter per image (baseline)", t_fresh,
                         "per image"))
            rows.append((f"camera view {size}, {n_views} poses, one plotter reused", t_reuse, "per image"))
            rows.append((f"camera view {size}, one plotter, with ellipse overlay", t_overlay, "per image"))
    lines = [
        "## Off-screen rendering (bench_render)",
        "",
        f"Machine: {machine}. Renderer: VTK EGL window on Mesa (software, no GPU, no X server). "
        f"Median of {repeats} runs; 120x80x8 mm plate, 8 holes; camera views along a {n_views}-pose approach.",
        "",
        "| what | time (ms) | |",
        "|---|---:|---|",
    ]
    lines += [f"| {name} | {ms:.1f} | {unit} |" for name, ms, unit in rows]
    lines += ["", "Reusing one plotter for many camera views vs a new plotter per image (same run): "
              + ", ".join(f"{size}: {ratio:.1f}x faster" for size, ratio in ratios) + "."]
    return save_section("bench_render", "\n".join(lines))


if __name__ == "__main__":
    print(main(quick="--quick" in sys.argv))
