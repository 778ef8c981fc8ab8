"""Benchmark: throughput of a 16-case campaign, serial vs a 2-worker Dask ``LocalCluster`` (issue 21).

The 16 cases are the tests' tiny thesis four-points study (campaigns/four_points_small.toml: 6 trajectory
samples, one optimiser start) over 2 cameras x 8 helix end radii. Measured in the same run:

- serial baseline: ``run_study`` of the 16 study dicts one after another in one process (after one untimed
  warm-up study, so CadQuery and the CAD worker server are already loaded — the best a serial loop can do);
- the campaign on a 2-worker ``LocalCluster`` (one thread per worker), after the cluster is up and each
  worker has run one untimed study too (cluster start-up, without that study, is reported apart);
- Dask's own round trip: 16 empty tasks on the same cluster.

Derived: speed-up and parallel efficiency; per-case overhead = (workers x elapsed − Σ in-worker case time) /
cases (the time a worker spent not running a study: scheduling, result transfer, the campaign's records,
the tail of the last wave); and an extrapolation to 64 workers, T(W, N) ≈ start-up + ⌈N / W⌉ x (t_case +
overhead), with t_case the mean in-worker case time measured here.
"""

from __future__ import annotations

import math
import os
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

SMALL = ROOT / "campaigns" / "four_points_small.toml"
RADII = (7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0)


def _campaign(folder: Path, n_radii: int) -> Path:
    """The 16-case campaign: the small example's grid with 8 radii (2 x 8)."""
    text = SMALL.read_text().replace('study = "../studies/', f'study = "{ROOT}/studies/')
    text = text.replace('calibration = "../tests/', f'calibration = "{ROOT}/tests/')
    text = text.replace('"trajectory.radius_end_mm" = [8.0, 10.0, 12.0]',
                        f'"trajectory.radius_end_mm" = {list(RADII[:n_radii])}')
    path = folder / "bench16.toml"
    path.write_text(text.replace('name = "four_points_small"', 'name = "bench16"'))
    return path


def _noop(i: int) -> int:
    return i


def _warm_study(study: dict, folder: str) -> int:
    """One untimed study in a worker (as the serial loop's warm-up): imports, CAD server, JIT compilation."""
    from cadfeat.study import run_study

    run_study(study, f"{folder}/{os.getpid()}", quiet=True, progress=False)
    return os.getpid()


def main(quick: bool = False) -> str:
    from cadfeat.campaign.plan import load_campaign
    from cadfeat.campaign.runner import local_cluster, run_campaign
    from cadfeat.campaign.task import warm_worker
    from cadfeat.study import run_study

    machine = _load("run_all", HERE / "run_all.py").machine_description()
    n_radii = 4 if quick else 8
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        camp = load_campaign(_campaign(tmp, n_radii))
        cases = camp.cases
        load0 = os.getloadavg()[0]
        run_study(cases[0].study, tmp / "warm", quiet=True, progress=False)  # untimed warm-up
        t0 = time.perf_counter()
        for c in cases:
            run_study(c.study, tmp / "serial" / c.name, quiet=True, progress=False)
        t_serial = time.perf_counter() - t0

        workers = 2
        t0 = time.perf_counter()
        with local_cluster(workers, retries=1) as client:
            client.run(warm_worker)
            t_start = time.perf_counter() - t0
            client.run(_warm_study, cases[0].study, str(tmp / "warm-workers"))
            t0 = time.perf_counter()
            futures = client.map(_noop, range(len(cases)), pure=False)
            client.gather(futures)
            t_noop = (time.perf_counter() - t0) / len(cases)
            t0 = time.perf_counter()
            result = run_campaign(camp, tmp / "campaign", client=client, quiet=True)
            t_campaign = time.perf_counter() - t0
        load1 = os.getloadavg()[0]
    done = result.count("done")
    in_worker = [r["wall_s"] for r in result.records if r.get("wall_s")]
    t_case = sum(in_worker) / max(len(in_worker), 1)
    overhead = (workers * t_campaign - sum(in_worker)) / len(cases)
    speedup = t_serial / t_campaign
    n = len(cases)

    def extrapolate(w: int, n_cases: int) -> float:
        return t_start + math.ceil(n_cases / w) * (t_case + overhead)

    lines = [
        f"## Campaign throughput: {n} tiny studies, serial vs 2 Dask workers (bench_campaign)",
        "",
        f"Machine: {machine}; load average {load0:.1f} at the start, {load1:.1f} at the end (a shared machine: "
        "other processes compete for the 2 cores). Cases: campaigns/four_points_small.toml's study (thesis four "
        f"points, 6 poses, 1 optimiser start, no occlusion test, with report) over 2 cameras x {n_radii} helix radii; "
        f"{done}/{n} done.",
        "",
        "| run | wall time (s) | per case (s) |",
        "|---|---:|---:|",
        f"| serial `run_study` loop, one process (warm) | {t_serial:.1f} | {t_serial / n:.2f} |",
        f"| campaign, 2-worker LocalCluster (cluster up) | {t_campaign:.1f} | {t_campaign / n:.2f} |",
        f"| cluster start-up + worker warm-up (once) | {t_start:.1f} | |",
        f"| mean in-worker case time (record wall_s) | | {t_case:.2f} |",
        "",
        f"Speed-up {speedup:.2f}x on 2 workers, parallel efficiency {100 * speedup / workers:.0f} %. Overhead per "
        f"case (workers x elapsed − Σ in-worker time, / cases) {overhead:.2f} s; Dask's own round trip of an "
        f"empty task {1e3 * t_noop:.1f} ms — the rest is the study's own start in the worker, the campaign's "
        "records and the last wave's idle worker. The serial loop is not one core either: the report's "
        "off-screen rendering (Mesa llvmpipe) and numpy's BLAS run threads on both cores, while Dask starts its "
        "workers with OMP_NUM_THREADS=1 — so 2 workers on 2 cores cannot reach 2x here.",
        "",
        "On paper, 64 workers (one core each, the same per-case time and overhead, plus one start-up): "
        "T(W, N) ≈ start-up + ⌈N/W⌉ x (t_case + overhead).",
        "",
        "| cases N | 2 workers (s) | 64 workers (s) | speed-up 64 vs 2 |",
        "|---:|---:|---:|---:|",
    ]
    for n_cases in (16, 256, 1024):
        a, b = extrapolate(2, n_cases), extrapolate(64, n_cases)
        lines.append(f"| {n_cases} | {a:.0f} | {b:.0f} | {a / b:.1f}x |")
    lines += ["", "A 16-case campaign cannot use more than 16 workers (one wave: start-up + the slowest case); "
              "the central scheduler's cost per task (ms) stays negligible next to a study (seconds), so the "
              "cluster scales until the shared output folder's file system or the start-up dominates.", ""]
    return save_section("bench_campaign", "\n".join(lines))


if __name__ == "__main__":
    print(main(quick="--quick" in sys.argv))
