"""Ctrl-C during ``cadfeat run`` (issue 32 item 8; ``cadfeat.study.interrupts``): the best design so far is written,
marked interrupted, and the command still exits 130; a second Ctrl-C writes nothing.

The run is the command a user types, started as a terminal starts it (SIGINT at its default disposition, its own
process group) and interrupted as a terminal does (SIGINT to the whole group: cadfeat and its CAD workers). The
part's holes sit on a circle at a phase angle (a non-linear design map: the optimiser searches with CAD rebuilds
in the loop), and its build sleeps, so the optimisation lasts seconds; the part logs each build, and the signal
is sent once the optimiser's own builds have started — after as many builds as the set-up makes (counted here by
setting the same study up in this process) and one more.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SLEEP_S = "0.6"

PART = '''"""Two 4 mm holes on a 20 mm circle at phase_deg and phase_deg + 120 deg in a 60 x 60 x 6 mm plate."""
import math
import os
import time

PARAMETERS = {"phase_deg": {"default": 10.0, "bounds": (0.0, 100.0), "unit": "deg", "description": "phase"}}
VIEW_DIRECTION = (0.0, 0.0, 1.0)


def build(phase_deg=10.0):
    import cadquery as cq

    log = os.environ.get("CADFEAT_TEST_BUILD_LOG")
    if log:
        with open(log, "a") as fh:
            fh.write(f"{phase_deg!r}\\n")
    time.sleep(float(os.environ.get("CADFEAT_TEST_BUILD_SLEEP_S", "0")))
    pts = [(20 * math.cos(math.radians(phase_deg + k)), 20 * math.sin(math.radians(phase_deg + k))) for k in (0, 120)]
    plate = cq.Workplane("XY").box(60.0, 60.0, 6.0, centered=(True, True, False))
    plate = plate.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0)).pushPoints(pts).hole(4.0)
    return plate.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0)) \\
        .pushPoints([(-22.0, -22.0)]).hole(4.0)
'''

STUDY = '''[study]
name = "arc"
part = "arc_plate.py"
seed = 3

[camera]
preset = "dalsa-cad1-128a"
focus_distance_mm = 200.0

[part_pose]
position_mm = [0, 0, 0]

[trajectory]
kind = "straight_approach"
start = [0, 0, 300]
end = [0, 0, 150]
target = [0, 0, 0]
n = 10

[design.parameters]
phase_deg = {}

[constraints]
edge_distance_mm = 2.0

[objective]
measures = ["fov", "resolvability"]
aggregate = "sum"
combine = "maxmin"

[optimizer]
method = "multistart"
starts = 2

[tracking]
check = "off"
'''


@pytest.fixture(scope="module")
def arc_study(tmp_path_factory) -> tuple[Path, int]:
    """(the study file, the number of builds its set-up makes)."""
    from cadfeat.study.pipeline import _set_up
    from cadfeat.study.schema import load_study

    folder = tmp_path_factory.mktemp("arc")
    (folder / "arc_plate.py").write_text(PART)
    path = folder / "s.toml"
    path.write_text(STUDY)
    log = folder / "setup.log"
    previous = os.environ.get("CADFEAT_TEST_BUILD_LOG")
    os.environ["CADFEAT_TEST_BUILD_LOG"] = str(log)
    try:
        _set_up(load_study(path), None)  # (builds in this process: the log sees them all)
    finally:
        if previous is None:
            os.environ.pop("CADFEAT_TEST_BUILD_LOG", None)
        else:
            os.environ["CADFEAT_TEST_BUILD_LOG"] = previous
    return path, len(log.read_text().split())


def _run_and_interrupt(study: Path, out: Path, after_builds: int, signals: int = 1) -> tuple[int, str, list[str]]:
    """``cadfeat run`` interrupted by ``signals`` SIGINTs to its process group (0.5 s apart) once the part has
    been built ``after_builds`` times; (exit status, stderr, the builds' phases)."""
    log = out.parent / f"{out.name}.log"
    env = {**os.environ, "CADFEAT_TEST_BUILD_LOG": str(log), "CADFEAT_TEST_BUILD_SLEEP_S": SLEEP_S,
           "CADFEAT_CACHE": "off",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    proc = subprocess.Popen([sys.executable, "-m", "cadfeat", "run", str(study), "--out", str(out), "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=study.parent,
                            start_new_session=True,  # its own process group, as a terminal's job
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # as typed
    try:
        deadline = time.monotonic() + 240
        while not (log.is_file() and len(log.read_text().split()) >= after_builds):
            assert proc.poll() is None, f"the run ended before it was interrupted: {proc.communicate()}"
            assert time.monotonic() < deadline, "the optimiser's builds did not start"
            time.sleep(0.05)
        for k in range(signals):
            if k:
                time.sleep(0.5)
            os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C in a terminal: the whole group
        _, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    return proc.returncode, err, log.read_text().split()


def test_ctrl_c_during_the_optimisation_writes_the_best_design_so_far(arc_study, tmp_path):
    study, setup_builds = arc_study
    out = tmp_path / "out"
    status, err, builds = _run_and_interrupt(study, out, setup_builds + 2)
    assert status == 130, err[-3000:]
    assert "cadfeat: interrupted" in err and f"the best design so far is in {out}" in err, err[-3000:]
    data = json.loads((out / "results.json").read_text())  # (whole: written to a temporary file, renamed)
    assert data["interrupted"] is True
    assert data["verdict"]["decision"] != "adopt" and "interrupted" in [f["rule"] for f in data["verdict"]["findings"]]
    (phase,) = data["variables"]
    assert phase["name"] == "phase_deg" and 0.0 <= phase["after"] <= 100.0
    assert phase["after"] != phase["before"]  # the optimiser's best design so far, not the start
    assert data["history"] and data["objectives"]["after"] and all(c["ok"] for c in data["constraints"])
    for name in ("optimised.step", "optimised.stl", "report.html"):
        assert (out / name).is_file(), name
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "out.log"]  # no staging folder left
    # it stopped: after the signal, the delivery rebuilt once (no shop refinement, no further CAD rounds)
    assert len(builds) <= setup_builds + 4, builds


def test_a_second_ctrl_c_stops_at_once_and_writes_nothing(arc_study, tmp_path):
    study, setup_builds = arc_study
    out = tmp_path / "out"
    status, err, _ = _run_and_interrupt(study, out, setup_builds + 2, signals=2)
    assert status == 130 and "cadfeat: interrupted" in err, err[-3000:]
    assert not out.exists()  # nothing published, and no staging folder either
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.log"]
