"""Benchmark: wall time of the flagship study (studies/nema17_mount.toml) by phase.

Runs ``run_study`` on the flagship into a temporary folder (with the report unless ``quick``) and reports
each phase's wall time (results.json ``timings_s``). Baseline, measured in the same run: one CAD rebuild +
hole extraction of the part at a design; the table gives the time the optimiser would have spent if each
of its evaluations had rebuilt the CAD model (n_evals × rebuild), and the ratio to the time it actually
spent on features ("CAD in the outer loop, features in the inner loop", docs/design.md).

The closed-loop check ``cadfeat run`` makes by default (``study.closed_loop_check``, fast mode: PnP + IEKF,
8 paired runs, at most 20 frames, on the original and the recommended design) tracks each design in a worker
process while the run goes on (the original beside the optimiser, the recommended design beside the analysis,
export and report renders): the run is timed with it, again with the check in this process
(``CADFEAT_TRACKING_BACKGROUND=0``, the baseline) and again with ``track="off"``; the table gives the check's
wait in this process, the workers' time and the ratios of the totals (issue 17: the flagship study must stay
under 60 s with it).
"""

from __future__ import annotations

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
from benchutil import save_section

FLAGSHIP = ROOT / "studies" / "nema17_mount.toml"
BACKGROUND_ENV = "CADFEAT_TRACKING_BACKGROUND"




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
            os.environ[BACKGROUND_ENV] = "0"
            t0 = time.perf_counter()
            serial = study_mod.run_study(FLAGSHIP, Path(tmp) / "serial", quiet=True, track="fast")
            total_serial = time.perf_counter() - t0
    finally:
        study_mod._report = saved
        os.environ.pop(BACKGROUND_ENV, None)
    workers = (result.results.get("tracking") or {}).get("timings_s", {})
    serial_check = (serial.results.get("tracking") or {}).get("check", {})
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
                     f"frames, {'/'.join(check.get('estimators', []))}; waiting for its workers) | "
                     f"{check['seconds']:.2f} |")
    worker_s = {k: workers.get(f"{k}_render", 0.0) + workers.get(f"{k}_track", 0.0) for k in ("before", "after")}
    lines += [
        "",
        f"The check's workers (designs tracked in: {', '.join(check.get('in_worker', [])) or 'none'}): the original "
        f"{worker_s['before']:.1f} s wall beside the optimiser, the recommended design {worker_s['after']:.1f} s "
        "beside the analysis, export and report renders.",
        "",
        f"The same study with the check off (`cadfeat run --no-track`): {total_off:.1f} s wall ({cpu_off:.1f} s CPU of "
        f"this process); with the default fast check {total:.1f} s ({cpu:.1f} s CPU of this process, the workers' "
        f"not counted): ratio {total / total_off:.2f} wall. Baseline, the check in this process "
        f"(`{BACKGROUND_ENV}=0`): {total_serial:.1f} s wall, its check "
        f"{serial_check.get('seconds', float('nan')):.1f} s wall and "
        f"{serial_check.get('cpu_seconds', float('nan')):.1f} s CPU; the workers save "
        f"{total_serial - total:.1f} s ({total_serial / total:.2f}x). The machine's load (other jobs on its 2 cores) "
        "inflates the wall times and takes the core the workers use.",
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
