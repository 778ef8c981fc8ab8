"""report.html in a real browser: headless Chromium loads every image and paints a non-blank page.

Chromium comes from ``$CADFEAT_CHROMIUM`` or PATH (``tools/ensure_chromium.sh`` installs Debian's package;
``make test`` runs it). Not skipped when missing: the test fails and says how to install it. The check
of the images runs on a COPY of the report with a small script added (the report itself has no script):
on ``load`` it writes, for each ``<img>``, ``complete && naturalWidth > 0`` into the DOM that
``--dump-dom`` prints.
"""

from __future__ import annotations

import copy
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from cdp_helpers import chromium
from PIL import Image
from report_fixture import shared_case
from report_html import parse_report

from cadfeat.report import write_report

CHECK_SCRIPT = """<script>
window.addEventListener('load', function () {
  var out = Array.prototype.map.call(document.images, function (im) {
    return {src: im.getAttribute('src'), ok: im.complete && im.naturalWidth > 0, w: im.naturalWidth};
  });
  var pre = document.createElement('pre');
  pre.id = 'imgcheck';
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
});
</script>"""


def _run(args: list[str], home: Path) -> subprocess.CompletedProcess:
    cmd = [chromium(), "--headless", "--disable-gpu", "--no-sandbox", "--disable-dev-shm-usage",
           "--no-first-run", "--hide-scrollbars", f"--user-data-dir={home / 'profile'}", *args]
    env = {**os.environ, "HOME": str(home)}
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=env, check=False)


@pytest.fixture(scope="module")
def browser_report(tmp_path_factory):
    """The full report of the plate study, renders included (cadfeat.render, off-screen)."""
    _, results, context = shared_case()
    out = tmp_path_factory.mktemp("browser")
    path = write_report(out / "study", copy.deepcopy(results), context)
    return path, tmp_path_factory.mktemp("chromium-home")


def test_report_has_the_renders(browser_report):
    """Part close-up and overview before/after, the camera views at each hole's worst pose, each non-blank;
    the close-up pair is the first thing in the renders section."""
    path, _ = browser_report
    srcs = parse_report(path).images
    renders = [s for s in srcs if Path(s).stem.startswith(("closeup_", "before", "after", "view_"))]
    _, results, _ = shared_case()
    n_views = len({f["worst_pose"] for f in results["measures"]["after"]["per_feature"]})
    assert len(renders) == 2 + 2 + 2 * n_views, srcs
    assert renders[:4] == ["img/closeup_before.png", "img/closeup_after.png", "img/before.png", "img/after.png"]
    for src in renders:
        grey = np.asarray(Image.open(path.parent / src).convert("L"), dtype=float)
        assert grey.std() > 10.0, f"{src} looks blank"
    assert "not rendered" not in path.read_text()


def test_every_image_loads_in_chromium(browser_report, tmp_path):
    path, home = browser_report
    n_images = len(parse_report(path).images)
    _, results, _ = shared_case()
    n_views = len({f["worst_pose"] for f in results["measures"]["after"]["per_feature"]})
    assert n_images == 6 + 4 + 2 * n_views  # plots + renders (close-up pair, overview pair, camera views)
    copy_dir = tmp_path / "copy"  # report.html ALONE: the images must come from the page itself
    copy_dir.mkdir()
    page = copy_dir / path.name
    shutil.copyfile(path, page)
    page.write_text(page.read_text().replace("</body>", CHECK_SCRIPT + "</body>"))
    proc = _run(["--virtual-time-budget=15000", "--dump-dom", page.as_uri()], home)
    match = re.search(r'<pre id="imgcheck">(.*?)</pre>', proc.stdout, re.S)
    assert match, f"Chromium printed no image check (exit {proc.returncode}): {proc.stderr[-2000:]}"
    checks = json.loads(match.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    assert len(checks) == n_images
    broken = [c["src"][:60] for c in checks if not c["ok"]]
    assert not broken, f"images that did not load in Chromium: {broken}"


def test_page_is_not_blank_in_chromium(browser_report, tmp_path):
    path, home = browser_report
    shot = tmp_path / "shot.png"
    proc = _run(["--window-size=1200,1600", f"--screenshot={shot}", path.as_uri()], home)
    assert shot.is_file(), f"no screenshot (exit {proc.returncode}): {proc.stderr[-2000:]}"
    grey = np.asarray(Image.open(shot).convert("L"), dtype=float)
    assert grey.shape == (1600, 1200)
    ink = (grey < 200).mean()  # text, table rules, plots
    assert grey.std() > 20.0 and 0.02 < ink < 0.8, (grey.std(), ink)


VIEW_SCRIPT = """<script>
window.addEventListener('load', function () {
  var out = {};
  try {
    var v = window.cadfeat3d;
    out.after = v.snapshot(); out.which_after = v.which();
    var labels = Array.prototype.filter.call(document.querySelectorAll('#view3d .lbl'),
      function (e) { return e.style.display !== 'none'; });
    out.labels = labels.map(function (e) { return e.textContent; });
    var xy = v.screen(0);
    var canvas = document.querySelector('#view3d canvas');
    canvas.dispatchEvent(new MouseEvent('click', {clientX: xy[0], clientY: xy[1], bubbles: true}));
    out.info = document.getElementById('view3d-info').innerText;
    v.show('before'); out.before = v.snapshot(); out.which_before = v.which();
    v.frame(true); out.framed = v.snapshot();
  } catch (e) { out.error = String(e); }
  var pre = document.createElement('pre'); pre.id = 'check3d'; pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
});
</script>"""


def test_3d_view_offline(browser_report, tmp_path):
    """The interactive view in report.html ALONE, with every network request failing (proxy and DNS off): it
    draws a non-blank canvas, switching to "before" changes the picture, each hole is labelled, and a click
    on a hole shows its measures, equal to results.json."""
    path, home = browser_report
    _, results, _ = shared_case()
    raw = path.read_text()
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", raw), "the page references the network"
    page = tmp_path / "alone.html"
    page.write_text(raw.replace("</body>", VIEW_SCRIPT + "</body>"))
    proc = _run(["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--proxy-server=127.0.0.1:9",
                 "--host-resolver-rules=MAP * ~NOTFOUND", "--virtual-time-budget=20000", "--dump-dom",
                 page.as_uri()], home)
    match = re.search(r'<pre id="check3d">(.*?)</pre>', proc.stdout, re.S)
    assert match, f"no 3-D view check (exit {proc.returncode}): {proc.stderr[-2000:]}"
    out = json.loads(match.group(1).replace("&quot;", '"').replace("&amp;", "&").replace("&lt;", "<")
                     .replace("&gt;", ">"))
    assert "error" not in out, out
    assert out["which_after"] == "after" and out["which_before"] == "before"
    for snap in (out["after"], out["before"]):
        assert snap["width"] > 300 and snap["std"] > 5.0, snap  # a part drawn over the background
    assert out["after"]["hash"] != out["before"]["hash"]  # hole A moved: the picture changed
    assert out["framed"]["hash"] != out["before"]["hash"]
    names = [h["name"] for h in results["holes"]["after"]]
    assert sorted(out["labels"]) == sorted(names)
    first = results["measures"]["after"]["per_feature"][0]
    assert out["info"].startswith(first["name"])
    shown = dict(line.split(": ", 1) for line in out["info"].splitlines() if ": " in line)
    for key in ("fov_min", "focus_min", "resolution_px_min"):
        assert float(shown[key]) == pytest.approx(first[key], rel=1e-3)


def test_decision_requirements_and_hole_table_in_chromium(browser_report):
    """The DOM Chromium builds from report.html holds the verdict, the active requirements and the hole table,
    and they agree with results.json (the verdict with the rules applied here by hand to the plate study)."""
    from report_html import ReportParser

    path, home = browser_report
    _, results, _ = shared_case()
    proc = _run(["--virtual-time-budget=5000", "--dump-dom", path.as_uri()], home)
    assert "<html" in proc.stdout, proc.stderr[-2000:]
    page = ReportParser()
    page.feed(proc.stdout)
    obj = results["objectives"]
    gain = (obj["combined_after"] - obj["combined_before"]) / abs(obj["combined_before"])
    active = [c for c in results["constraints"] if 0 <= c["margin"] < 0.1]
    expected = "do not adopt" if gain < 0.01 or not all(c["ok"] for c in results["constraints"]) else None
    if expected is None:
        worse = [k for k in obj["after"] if obj["after"][k] < obj["before"][k]]
        fb = {f["name"]: f for f in results["measures"]["before"]["per_feature"]}
        failing = [f for f in results["measures"]["after"]["per_feature"] for k in
                   ("fov_min", "fov_px_min", "focus_min", "resolution_px_min") if fb[f["name"]][k] >= 0 > f[k]]
        expected = "adopt with care" if active or worse or failing else "adopt"
    assert page.by_id["verdict"] == expected
    rows = page.tables.get("constraints", [])
    assert sorted(r.cells[0].text for r in rows if r.css == "active") == sorted(c["name"] for c in active)
    table = page.tables["hole-table"]
    assert [r.cells[0].text for r in table] == [h["name"] for h in results["holes"]["after"]]
    for r, h in zip(table, results["holes"]["after"], strict=True):
        assert [c.value for c in r.cells[2:5]] == pytest.approx(h["centre_mm"], abs=1e-9)
        assert r.cells[5].value == pytest.approx(2 * h["radius_mm"], abs=1e-9)
