"""Benchmark: wall time of the flagship study (studies/nema17_mount.toml) by phase.

Runs ``run_study`` on the flagship into a temporary folder (with the report unless ``quick``) and reports
each phase's wall time (results.json ``timings_s``). Baseline, measured in the same run: one CAD rebuild +
hole extraction of the part at a design; the table gives the time the optimiser would have spent if each
of its evaluations had rebuilt the CAD model (n_evals × rebuild), and the ratio to the time it actually
spent on features ("CAD in the outer loop, features in the inner loop", DESIGN.md).

The closed-loop check ``cadfeat run`` makes by default (``study.closed_loop_check``, fast mode: PnP + IEKF,
8 paired runs, at most 20 frames, on the original and the recommended design): the run is timed with it and again
with ``track="off"``; the table gives its seconds and the ratio of the two totals (issue 17: the flagship study
must stay under ~60 s with it).
"""

from __future__ import annotations

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
from benchutil import save_section

FLAGSHIP = ROOT / "studies" / "nema17_mount.toml"




def main(quick: bool = False) -> str:
    import numpy as np

    from cadfeat.study import run as study_mod
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_script

    machine = _load("run_all", HERE / "run_all.py").machine_description()
    saved = study_mod._report
    if quick:
        study_mod._report = lambda *a, **k: None
    try:
        with tempfile.TemporaryDirectory() as tmp:
            t0, c0 = time.perf_counter(), time.process_time()
            result = study_mod.run_study(FLAGSHIP, Path(tmp) / "out", quiet=True, track="fast")
            total, cpu = time.perf_counter() - t0, time.process_time() - c0
            check = (result.results.get("tracking") or {}).get("check", {})
            report_s = None
            if (Path(tmp) / "out" / "report.html").exists():
                report_s = total - sum(result.results["timings_s"].values()) - check.get("seconds", 0.0)
            t0, c0 = time.perf_counter(), time.process_time()
            study_mod.run_study(FLAGSHIP, Path(tmp) / "off", quiet=True, track="off")
            total_off, cpu_off = time.perf_counter() - t0, time.process_time() - c0
    finally:
        study_mod._report = saved
    timings = result.results["timings_s"]
    n_evals = result.results["optimizer"]["n_evals"]

    setup = setup_script(load_study(FLAGSHIP))
    x = setup.space.x0
    rebuilds = []
    for _ in range(3 if quick else 7):
        start = time.perf_counter()
        setup.rebuild_holes(setup.rebuild_shape(x))
        rebuilds.append(time.perf_counter() - start)
    t_rebuild = statistics.median(rebuilds)
    setup.problem.objective(x)  # warm: the normaliser (payoff table) and depth maps are built on first use
    start = time.perf_counter()
    for _ in range(20):
        setup.problem.objective(x + 1e-9)
    t_feature = (time.perf_counter() - start) / 20
    cad_equivalent = n_evals * t_rebuild

    lines = [
        "## Study wall time by phase: flagship NEMA 17 mount (bench_study)",
        "",
        f"Machine: {machine}. One run of `cadfeat run studies/nema17_mount.toml`"
        f"{' without the report (quick)' if quick else ''}; total {total:.1f} s.",
        "",
        "| phase | wall time (s) |",
        "|---|---:|",
    ]
    for phase in ("setup", "optimise", "rebuild", "analyse", "export"):
        if phase in timings:
            lines.append(f"| {phase} | {timings[phase]:.2f} |")
    if report_s is not None:
        lines.append(f"| report (rest of the run) | {report_s:.2f} |")
    if check.get("seconds") is not None:
        lines.append(f"| closed-loop check ({check.get('mode')}: {check.get('runs')} runs, {check.get('frames')} "
                     f"frames, {'/'.join(check.get('estimators', []))}) | {check['seconds']:.2f} |")
    lines += [
        "",
        f"The same study with the check off (`cadfeat run --no-track`): {total_off:.1f} s wall ({cpu_off:.1f} s CPU of "
        f"this process); with the default fast check {total:.1f} s ({cpu:.1f} s CPU; the check "
        f"{check.get('cpu_seconds', float('nan')):.1f} s CPU): ratio {total / total_off:.2f} wall, {cpu / cpu_off:.2f} "
        "CPU. The machine's load (other jobs on its 2 cores) inflates the wall times; the CPU times do not depend on "
        "it.",
        "",
        f"Baseline (same run): one CAD rebuild + hole extraction of the mount = {1e3 * t_rebuild:.1f} ms "
        f"(median of {len(rebuilds)}); one objective evaluation on features = {1e3 * t_feature:.2f} ms "
        f"(ratio {t_rebuild / t_feature:.0f}x).",
        f"The nominal solve made {n_evals} design evaluations (the optimise phase, "
        f"{timings.get('optimise', float('nan')):.2f} s, also holds the robust solve, each of whose evaluations "
        "scores 64 draws); rebuilding the CAD model at each "
        f"nominal evaluation alone would have cost ≈ {cad_equivalent:.1f} s "
        f"({cad_equivalent / max(timings.get('optimise', np.nan), 1e-9):.2f}x the whole optimise phase).",
        "",
    ]
    text = "\n".join(lines)
    return save_section("bench_study", text)


if __name__ == "__main__":
    print(main(quick="--quick" in sys.argv))
