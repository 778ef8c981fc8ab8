"""Benchmark: building and extracting the parts library, and the cost of design maps.

Per part of ``parts/``: median time of ``Part.build`` (CadQuery build of the default design) and of
``extract_holes`` on it; the baseline, measured in the same run, is the build itself (ratio = extraction /
build: how much the feature read-out adds to a CAD rebuild). Then the design map (docs/design.md "CAD in the
outer loop") of every non-integer parameter of a few parts: time, number of builds, time per build, and the
time of one ``predict_batch`` of 1000 designs (what the optimiser's inner loop pays instead of a rebuild).
Finally the worker-process build (``build_shape``) against the in-process build.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from benchutil import load as _load
from benchutil import median_ms as _median_ms
from benchutil import save_section

MAP_PARTS = ("thesis_hub", "industrial_plate", "nema17_mount", "pipe_flange_dn50")






def main(quick: bool = False) -> str:
    import numpy as np

    from cadfeat.cad.design_map import design_map
    from cadfeat.cad.features import extract_holes
    from cadfeat.cad.parts import build_shape, load_parts

    machine = _load("run_all", HERE / "run_all.py").machine_description()
    repeats = 3 if quick else 11
    parts = load_parts()
    lines = [
        "## Parts library: build, hole extraction, design map (bench_parts)",
        "",
        f"Machine: {machine}; load average at start {os.getloadavg()[0]:.1f}. Median of {repeats} runs, default",
        "parameters. Baseline: the part's own CadQuery build; ratio = extraction time / build time.",
        "",
        "| part | holes | build (ms) | extract (ms) | ratio extract/build |",
        "|---|---:|---:|---:|---:|",
    ]
    ratios = []
    for part in parts:
        solid = part.build()
        n = len(extract_holes(solid, part.view_direction))
        t_build = _median_ms(part.build, repeats)
        t_extract = _median_ms(lambda s=solid, p=part: extract_holes(s, p.view_direction), repeats)
        ratios.append(t_extract / t_build)
        lines.append(f"| {part.name} | {n} | {t_build:.1f} | {t_extract:.1f} | {t_extract / t_build:.2f} |")
    lines += ["", f"Median ratio extraction/build over the library: {statistics.median(ratios):.2f}.", "",
              "| design map of | parameters | builds | time (s) | ms per build+extract | linear | "
              "predict_batch 1000 designs (ms) |",
              "|---|---:|---:|---:|---:|---|---:|"]
    by_name = {p.name: p for p in parts}
    for name in MAP_PARTS[:2] if quick else MAP_PARTS:
        part = by_name[name]
        names = [n for n, p in part.parameters.items() if not p.is_int]
        start = time.perf_counter()
        dm = design_map(part, names)
        elapsed = time.perf_counter() - start
        X = np.array([dm.at[n] for n in names]) + 0.01 * np.random.default_rng(0).standard_normal((1000, len(names)))
        t_pred = _median_ms(lambda dm=dm, X=X: dm.predict_batch(X), repeats)
        nonlinear = ", ".join(n for n, ok in dm.linear_by.items() if not ok)
        lines.append(f"| {name} | {len(names)} | {dm.n_builds} | {elapsed:.2f} | {1e3 * elapsed / dm.n_builds:.1f} | "
                     f"{'yes' if dm.linear else 'no (' + nonlinear + ')'} | {t_pred:.2f} |")
    hub = by_name["thesis_hub"]
    build_shape(hub, {}, 120.0)  # start the forkserver (imports CadQuery once)
    t_worker = _median_ms(lambda: build_shape(hub, {}, 60.0), max(3, repeats // 2))
    t_local = _median_ms(hub.build, repeats)
    lines += ["", f"Time-limited build in a worker process (`build_shape`, forkserver, BRep transfer) of "
              f"thesis_hub: {t_worker:.1f} ms vs {t_local:.1f} ms in process (ratio {t_worker / t_local:.1f})."]
    return save_section("bench_parts", "\n".join(lines))


if __name__ == "__main__":
    print(main(quick="--quick" in sys.argv))
