"""Benchmark: ``cadfeat explore`` on the flagship (studies/nema17_mount.toml) — start time and the latency from a
slider move to the numbers.

Start: wall time from launching ``cadfeat explore STUDY --port 0 --no-browser`` (a fresh Python process) until
it prints its URL (the study is set up — CAD builds, design map, objective normaliser — and one evaluation has
warmed up the compiled kernels), then until ``/api/scene`` has answered (what the page loads first).
Latency: the HTTP round trip of ``POST /api/evaluate`` as the page sends it (JSON in, every number of the page
out: objectives, (L, N) measures, ellipses at the pose), for a drag of each design variable across its range
in 25 steps (each step a new design: the moved holes' occlusion rays are traced, the others come from the
cache) — median and 95th percentile; and the server's own compute time per request (``elapsed_s``).
In headless Chromium (SwiftShader: software WebGL), the same drags timed in the page from the slider's ``input``
event until the new numbers are shown, and until the plots, the 3-D view and the camera view are redrawn too.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from benchutil import save_section

STUDY = ROOT / "studies" / "nema17_mount.toml"
STEPS = 25


def _post(url: str, body: dict) -> dict:
    req = urllib.request.Request(url, json.dumps(body).encode(), {"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=60) as r:
        return json.loads(r.read())


def _browser(url: str, variables: list[dict]) -> list[list[float]]:
    """Slider → page in headless Chromium, timed in the page from the slider's ``input`` event: [ms until the
    new numbers are shown, ms until plots and views are redrawn too] per move, every variable dragged in
    ``STEPS`` steps; [] without Chromium."""
    import shutil
    import tempfile

    exe = os.environ.get("CADFEAT_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    if not exe:
        return []
    sys.path.insert(0, str(ROOT / "tests"))
    from cdp_helpers import open_page

    out = []
    with tempfile.TemporaryDirectory() as home, open_page(exe, url, Path(home)) as page:
        page.wait("document.body && document.body.dataset.state === 'idle' && +document.body.dataset.evals >= 1",
                  120)
        for v in variables:
            for k in range(STEPS):
                value = v["lower"] + (v["upper"] - v["lower"]) * k / (STEPS - 1)
                out.append(page.js(
                    "new Promise(function (done) { var n = +document.body.dataset.evals, t0 = performance.now(), t1;"
                    f"var el = document.querySelector('input[data-name=\"{v['name']}\"]'); el.value = {value!r};"
                    "el.dispatchEvent(new Event('input', {bubbles: true}));"
                    "(function poll() { var b = document.body.dataset;"
                    " if (t1 === undefined && +b.evals > n) t1 = performance.now();"
                    " if (t1 !== undefined && b.state === 'idle') done([t1 - t0, performance.now() - t0]);"
                    " else setTimeout(poll, 1); })(); })"))
    return out


def main() -> str:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "cadfeat", "explore", str(STUDY), "--port", "0", "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env, cwd=ROOT)
    try:
        line = proc.stdout.readline()
        t_ready = time.perf_counter() - t0
        url = line.split()[2]
        with urllib.request.urlopen(url + "api/scene", timeout=60) as r:
            scene = json.loads(r.read())
        t_scene = time.perf_counter() - t0
        variables = scene["variables"]
        current = {v["name"]: v["value"] for v in variables}
        rtt, server = [], []
        for v in variables:
            for k in range(STEPS):
                values = dict(current, **{v["name"]: v["lower"] + (v["upper"] - v["lower"]) * k / (STEPS - 1)})
                start = time.perf_counter()
                res = _post(url + "api/evaluate", {"values": values, "pose": k % len(scene["times_s"])})
                rtt.append(time.perf_counter() - start)
                server.append(res["elapsed_s"])
        page_ms = _browser(url, variables)
    finally:
        proc.terminate()
        proc.wait(30)

    def pct(a: list[float], q: float) -> float:
        return 1e3 * statistics.quantiles(a, n=100, method="inclusive")[q - 1]

    n_moves = len(rtt)
    shown, drawn = [t[0] / 1e3 for t in page_ms], [t[1] / 1e3 for t in page_ms]
    browser_rows = (f"| Chromium, slider → numbers shown (page-timed), median / 95th percentile | "
                    f"{1e3 * statistics.median(shown):.0f} / {pct(shown, 95):.0f} ms |\n"
                    f"| Chromium, slider → plots, 3-D and camera view redrawn too, median / 95th percentile | "
                    f"{1e3 * statistics.median(drawn):.0f} / {pct(drawn, 95):.0f} ms |\n"
                    if page_ms else "| in Chromium | not measured (no Chromium found) |\n")
    text = f"""## Explorer on the flagship (bench_explore)

`cadfeat explore studies/nema17_mount.toml` ({len(variables)} design variables, {len(scene['holes'])} holes,
{len(scene['times_s'])} poses, exact occlusion test against the part mesh as `cadfeat evaluate`). {n_moves} slider
moves (each variable dragged across its range in {STEPS} steps).

| what | value |
|---|---:|
| start: process launch → URL printed (study set up, warmed up) | {t_ready:.1f} s |
| start: → `/api/scene` answered | {t_scene:.1f} s |
| slider → numbers, HTTP round trip, median | {1e3 * statistics.median(rtt):.0f} ms |
| slider → numbers, HTTP round trip, 95th percentile | {pct(rtt, 95):.0f} ms |
| server compute per move, median / 95th percentile | {1e3 * statistics.median(server):.0f} / {pct(server, 95):.0f} ms |
{browser_rows}
Target (issue 20): numbers within 0.3 s of a slider move.
"""
    return save_section("bench_explore", text)


if __name__ == "__main__":
    print(main())
