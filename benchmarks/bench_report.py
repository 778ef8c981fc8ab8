"""Benchmark: writing the whole report of a study, split into renders, plots and HTML.

The study is the four-hole plate of tests/report_fixture.py (CadQuery build + hole extraction, a 21-point
one-variable sweep of the batched measures over a 30-pose trajectory, CAD rebuild, STEP export). Timed: the
study itself (wall time), ``build_report`` with the study's ReportContext (renders by ``cadfeat.render``
when it renders here, the matplotlib plots, the HTML), and — the baseline measured in the same run — one
evaluation of the measures of the same study (all poses, all holes).
"""

from __future__ import annotations

import importlib.util
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from benchutil import load as _load
from benchutil import median_s as _median_s
from benchutil import save_section

REAL_STUDY = ROOT / "studies" / "nema17_mount.toml"


def _real_study() -> list[str]:
    """A real ``run_study`` (when cadfeat.study.run and the study file exist) with its report timed from inside."""
    if importlib.util.find_spec("cadfeat.study.run") is None or not REAL_STUDY.is_file():
        return ["", f"(No real study timed: cadfeat.study.run or {REAL_STUDY.name} missing.)"]
    import cadfeat.report as report
    from cadfeat import measures, run_study
    from cadfeat.cad.features import holes_to_arrays

    seen: dict = {}
    original = report.write_report

    def timed_write_report(out_dir, results, context=None):
        built = report.build_report(out_dir, results, context)
        seen.update(built=built, context=context, page_mb=built.path.stat().st_size / 1e6)
        return built.path

    report.write_report = timed_write_report
    try:
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            run_study(REAL_STUDY, Path(tmp) / "out", quiet=True)
            wall = time.perf_counter() - start
    finally:
        report.write_report = original
    built, ctx = seen["built"], seen["context"]
    T = ctx.T_cam_part(range(len(ctx.trajectory)))
    screws = ctx.trajectory.velocity_screws()
    arrays = holes_to_arrays(ctx.holes_after)
    evaluation = _median_s(lambda: measures.evaluate(ctx.camera, T, screws, *arrays), 50)
    t = built.timings_s
    n_img = len(built.images)
    return ["", f"Real study `{REAL_STUDY.relative_to(ROOT)}` ({len(ctx.trajectory)} poses, {len(ctx.holes_after)} "
            f"holes): wall time {wall:.1f} s, of which the report {t['total']:.1f} s ({100 * t['total'] / wall:.0f} %: "
            f"renders {t['renders']:.1f} s [part {t.get('renders: part', 0):.1f} s, views "
            f"{t.get('renders: views', 0):.1f} s], plots {t['plots']:.1f} s, 3-D view {1e3 * t.get('view3d', 0):.0f} "
            f"ms, HTML {1e3 * t['html']:.0f} ms; {n_img} images; report.html {seen['page_mb']:.1f} MB, "
            f"self-contained). One measures evaluation of the same study: {1e3 * evaluation:.2f} ms (the report "
            f"costs {t['total'] / evaluation:.0f} evaluations)."]


def main(quick: bool = False) -> str:
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.poses import invert_T
    from cadfeat.report import build_report

    machine = _load("run_all", HERE / "run_all.py").machine_description()
    load = os.getloadavg()[0]
    fixture = _load("report_fixture", ROOT / "tests" / "report_fixture.py")
    repeats = 1 if quick else 3
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        results, ctx = fixture.build_case(Path(tmp) / "study")
        study_s = time.perf_counter() - start

        T_cam_part = invert_T(ctx.trajectory.T_task_cam)
        screws = ctx.trajectory.velocity_screws()
        arrays = holes_to_arrays(ctx.holes_after)
        fixture.evaluate(ctx.camera, T_cam_part, screws, *arrays)  # warm-up (imports)
        baseline_s = _median_s(lambda: fixture.evaluate(ctx.camera, T_cam_part, screws, *arrays), 50)

        build_report(Path(tmp) / "warm-up", results, ctx)  # imports PyVista/VTK once (a study pays it once too)
        runs = [build_report(Path(tmp) / f"report{i}", results, ctx, parallel=False) for i in range(repeats)]
        parallel = [build_report(Path(tmp) / f"par{i}", results, ctx, parallel=True) for i in range(repeats)]
        page_mb = runs[-1].path.stat().st_size / 1e6
    keys = ("renders", "renders: part", "renders: views", "plots", "view3d", "html")
    phases = {k: statistics.median(r.timings_s.get(k, 0.0) for r in runs) for k in keys}
    total = phases["renders"] + phases["plots"] + phases["view3d"] + phases["html"]
    out = runs[-1]
    n_renders = len(out.images) - sum(1 for p in out.images if p.stem in {
        "tracks", "pose_measures", "motion", "convergence", "sweep", "pareto"})
    n_plots = len(out.images) - n_renders
    n_views = sum(1 for p in out.images if p.stem.startswith("view_"))
    rows = [
        ("baseline: one measures evaluation (30 poses x 4 holes)", baseline_s),
        (f"report: renders ({n_renders} images)", phases["renders"]),
        ("  of which the part before/after (2 images)", phases["renders: part"]),
        (f"  of which the camera views ({n_views} images, one plotter per design)", phases["renders: views"]),
        (f"report: plots ({n_plots} PNGs)", phases["plots"]),
        ("report: interactive 3-D view (tessellation, scene JSON, three.js inlined)", phases["view3d"]),
        ("report: HTML (images embedded as data URIs)", phases["html"]),
        ("report: total", total),
        ("report: total with the plots drawn in a child process meanwhile (parallel=True)",
         statistics.median(r.timings_s["total"] for r in parallel)),
        ("study without the report (build, sweep, rebuild, STEP export)", study_s),
    ]
    lines = [
        "## Writing the report (bench_report)",
        "",
        f"Machine: {machine}; load average {load:.1f} at the start. Median of {repeats} report runs after "
        "one warm-up run (PyVista/VTK import); "
        "baseline median of 50 evaluations with "
        f"cadfeat.measures.evaluate. Ratio: time / baseline.",
        "",
        "| phase | time (ms) | ratio to baseline |",
        "|---|---:|---:|",
    ]
    lines += [f"| {name} | {1e3 * s:.1f} | {s / baseline_s:.0f} |" for name, s in rows]
    per_render = f"{phases['renders'] / n_renders:.2f} s per render" if n_renders else "no renders (see notes)"
    lines += [
        "",
        f"Share of the study's wall time taken by the report: {100 * total / (study_s + total):.0f} % "
        f"({total:.2f} s of {study_s + total:.2f} s); {per_render}; "
        f"{phases['plots'] / max(n_plots, 1):.2f} s per plot. The self-contained report.html is "
        f"{page_mb:.2f} MB (images and three.js inside).",
    ]
    if out.notes:
        lines += ["", "Notes: " + "; ".join(out.notes)]
    if not quick:
        lines += _real_study()
    return save_section("bench_report", "\n".join(lines))


if __name__ == "__main__":
    print(main(quick="--quick" in sys.argv))
