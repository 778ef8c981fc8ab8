"""``cadfeat explore`` driven by headless Chromium over the DevTools protocol (a websocket from aiohttp).

The explorer runs as the command a user types (``cadfeat explore STUDY --port 0 --no-browser``) on a copy of
the CQGI pillow-block study (tests/data/cqgi). Chromium comes from ``$CADFEAT_CHROMIUM`` or PATH
(``tools/ensure_chromium.sh``), as in test_report_browser.py; every host but 127.0.0.1 is unreachable for it.
References: ``cadfeat.study.evaluate_study`` of the study TOML the page's own "write as study start" button
wrote (CAD rebuilt at the slider's values, holes re-extracted); the pixels of the canvases.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from cdp_helpers import Page, chromium, open_page

DATA = Path(__file__).parents[1] / "data" / "cqgi"
ROOT = Path(__file__).resolve().parents[2]


def _explorer(study: Path) -> tuple[subprocess.Popen, str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    proc = subprocess.Popen([sys.executable, "-m", "cadfeat", "explore", str(study), "--port", "0", "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=study.parent)
    line = proc.stdout.readline()  # printed once the study is loaded
    if "http://127.0.0.1:" not in line:
        proc.kill()
        pytest.fail(f"the explorer did not start: {line!r} {proc.stderr.read()[-2000:]}")
    return proc, line.split()[2]


@pytest.fixture(scope="module")
def explorer(tmp_path_factory):
    work = tmp_path_factory.mktemp("explore")
    for name in ("ex003_study.toml", "Ex003_Pillow_Block_With_Counterbored_Holes.py"):
        shutil.copyfile(DATA / name, work / name)
    optimum = work / "exports" / "cqgi_ex003" / "results.json"  # a run's result: 'current vs optimum'
    optimum.parent.mkdir(parents=True)
    optimum.write_text(json.dumps({"variables": [{"name": "cbore_inset", "after": 25.0},
                                                 {"name": "center_hole_dia", "after": 18.0}]}))
    proc, url = _explorer(work / "ex003_study.toml")
    try:
        with open_page(chromium(), url, work) as page:
            page.wait("document.body && document.body.dataset.state === 'idle' && +document.body.dataset.evals >= 1",
                      90)
            yield page, proc, url, work
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def _post(page: Page, route: str, body: dict) -> dict:
    """A JSON request from the page itself (same origin), as its own script makes them."""
    return json.loads(page.js(f"fetch('{route}', {{method: 'POST', body: JSON.stringify({json.dumps(body)})}})"
                              ".then(function (r) { return r.text(); })"))


def _objectives(page: Page) -> dict[str, float]:
    rows = page.js("JSON.stringify(Array.from(document.querySelectorAll('#objectives tbody tr'))"
                   ".map(function (tr) { return [tr.dataset.name, tr.dataset.value]; }))")
    return {name: float(value) for name, value in json.loads(rows)}


def _move(page: Page, selector: str, value: float) -> None:
    """Move a slider as a user does (its value, then an ``input`` event) and wait for the page's numbers."""
    n = int(page.js("document.body.dataset.evals"))
    page.js(f"(function () {{ var el = document.querySelector('{selector}'); el.value = {value!r};"
            "el.dispatchEvent(new Event('input', {bubbles: true})); return true; })()")
    page.wait(f"+document.body.dataset.evals > {n} && document.body.dataset.state === 'idle'")


def test_slider_numbers_equal_cadfeat_evaluate(explorer):
    """Moving a slider shows the objectives `cadfeat evaluate` gives for the same parameters (1e-9)."""
    from cadfeat.study import evaluate_study

    page, _, _, work = explorer
    before = _objectives(page)
    shot0 = page.js("JSON.stringify(cadfeatExplore.snapshot3d())")
    _move(page, 'input[data-name="cbore_inset"]', 21.5)
    shown = _objectives(page)
    assert shown != before
    values = json.loads(page.js("JSON.stringify(cadfeatExplore.last().values)"))
    assert values["cbore_inset"] == pytest.approx(21.5, abs=0.03)  # (the slider's step)
    shot1 = page.js("JSON.stringify(cadfeatExplore.snapshot3d())")
    page.js("document.getElementById('save-start').click(); true")
    text = page.wait("(document.getElementById('message').textContent.indexOf('wrote ') === 0) && "
                     "document.getElementById('message').textContent")
    start = Path(text[len("wrote "):])
    assert start.parent == work and start.name == "ex003_study-start-1.toml"
    results = evaluate_study(start)
    assert results["objectives"]["before"].keys() == shown.keys()
    for name, value in results["objectives"]["before"].items():
        assert shown[name] == pytest.approx(value, rel=1e-9, abs=1e-12), name
    combined = float(page.js("document.getElementById('combined').dataset.value"))
    assert combined == pytest.approx(results["objectives"]["combined_before"], rel=1e-9)
    # the sweep along the moved variable (the optimiser's evaluation) passes through the same design's scores
    sweep = json.loads(page.wait("cadfeatExplore.sweep() && cadfeatExplore.sweep().name === 'cbore_inset' && "
                                 "JSON.stringify(cadfeatExplore.sweep())"))
    assert len(sweep["x"]) == 41  # (it depends on the other variables only: moving this one reuses it)
    assert sweep["x"][0] == 8.0 and sweep["x"][-1] == 30.0
    ends = _post(page, "/api/sweep", {"values": values, "name": "cbore_inset", "n": 2})
    for k, inset in enumerate((8.0, 30.0)):  # the optimiser's batch (depth maps) = the exact single evaluation
        exact = _post(page, "/api/evaluate", {"values": {**values, "cbore_inset": inset}})
        for name, value in exact["normalised"].items():
            assert ends["normalised"][name][k] == pytest.approx(value, abs=1e-9), (inset, name)  # (scale: 1)
        assert ends["combined"][k] == pytest.approx(exact["combined"], abs=1e-9)
    # the 3-D canvas is drawn and changed with the design (the hole rings moved)
    s0, s1 = json.loads(shot0), json.loads(shot1)
    assert s0["width"] > 300 and s0["std"] > 5.0 and s1["std"] > 5.0, (s0, s1)
    assert s0["hash"] != s1["hash"]


def test_camera_view_follows_the_pose_slider(explorer):
    page, _, _, _ = explorer
    assert page.js("document.body.dataset.setup") == "ready"  # (the page waited for the set-up: /api/status)
    cam0 = json.loads(page.js("JSON.stringify(cadfeatExplore.snapshotCamera())"))
    ov0 = page.js("cadfeatExplore.overlayHash()")
    _move(page, "#pose", 7)
    assert page.js("cadfeatExplore.last().pose.index") == 7
    cam1 = json.loads(page.js("JSON.stringify(cadfeatExplore.snapshotCamera())"))
    assert cam0["std"] > 5.0 and cam1["std"] > 5.0, (cam0, cam1)  # the part seen by the study camera
    assert cam0["hash"] != cam1["hash"] and page.js("cadfeatExplore.overlayHash()") != ov0
    ellipses = page.js("cadfeatExplore.last().pose.axes_px")
    assert len(ellipses) == 5 and all(a[0] >= a[1] > 0 for a in ellipses)


def _click(page: Page, button: str) -> None:
    n = int(page.js("document.body.dataset.evals"))
    page.js(f"document.getElementById('{button}').click(); true")
    page.wait(f"+document.body.dataset.evals > {n} && document.body.dataset.state === 'idle'")


def test_current_vs_optimum(explorer):
    page, _, _, _ = explorer
    _click(page, "reset")
    current = _objectives(page)
    _click(page, "toggle")
    assert json.loads(page.js("JSON.stringify(cadfeatExplore.last().values)")) == {"cbore_inset": 25.0,
                                                                                   "center_hole_dia": 18.0}
    assert _objectives(page) != current
    _click(page, "toggle")
    assert _objectives(page) == current


def test_export_step_and_glb(explorer):
    """The export button rebuilds the CAD model: the STEP re-imported has the holes of CQGI's own build at the
    page's values; the GLB's nodes are the page's hole names."""
    import cadquery as cq
    import numpy as np
    import trimesh
    from cqgi_helpers import cqgi_solid

    from cadfeat.cad.features import extract_holes

    page, _, _, work = explorer
    _move(page, 'input[data-name="cbore_inset"]', 16.0)
    values = json.loads(page.js("JSON.stringify(cadfeatExplore.last().values)"))
    page.js("document.getElementById('export').click(); true")
    text = page.wait("(document.getElementById('message').textContent.indexOf('exported ') === 0) && "
                     "document.getElementById('message').textContent", 90)
    step, glb = (Path(p) for p in text[len("exported "):].split(" and "))
    assert step.parent.parent == work and step.parent.name == "cqgi_ex003-explore-1"
    got = extract_holes(cq.importers.importStep(str(step)).val())
    want = extract_holes(cqgi_solid(DATA / "Ex003_Pillow_Block_With_Counterbored_Holes.py", values))
    key = lambda hs: sorted((tuple(np.round(h.centre, 6)), round(h.radius_mm, 6)) for h in hs)  # noqa: E731
    assert key(got) == key(want)
    names = json.loads(page.js("JSON.stringify(cadfeatExplore.scene().holes)"))
    assert set(trimesh.load(glb).graph.nodes_geometry) == set(names) | {"part"}
    # "rebuild CAD" shows the rebuilt part: the camera view changes (the holes moved in the mesh too)
    cam0 = page.js("cadfeatExplore.snapshotCamera().hash")
    page.js("document.getElementById('rebuild').click(); true")
    assert int(page.wait("document.body.dataset.rebuilt !== 'busy' && document.body.dataset.rebuilt", 90)) > 100
    assert page.js("cadfeatExplore.snapshotCamera().hash") != cam0


def test_no_network_beyond_localhost_and_clean_shutdown(explorer):
    page, proc, url, _ = explorer
    assert page.requests, "no request recorded"
    foreign = [u for u in page.requests if not u.startswith(url) and not u.startswith(("data:", "blob:"))]
    assert not foreign, foreign
    port = int(url.rstrip("/").rsplit(":", 1)[1])
    import urllib.error
    import urllib.request

    bad = urllib.request.Request(url + "api/evaluate", b'{"values": {"cbore_inset": 99}}',
                                 {"Content-Type": "application/json"})
    with pytest.raises(urllib.error.HTTPError) as err:
        urllib.request.urlopen(bad, timeout=30)
    assert err.value.code == 400 and "cbore_inset = 99 is outside [8, 30]" in err.value.read().decode()
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=30) == 0
    assert "stopped" in proc.stderr.read()
    with pytest.raises(OSError), socket.create_connection(("127.0.0.1", port), timeout=2):
        pass
