"""Campaigns on Dask (``cadfeat campaign``, issue 21): same results as serial runs, faults, resume, Ctrl-C.

References: the per-case results.json of a campaign on a 2-worker ``LocalCluster`` is compared with
``run_study`` of the same study dict run serially in this process (apart from ``created`` and ``timings_s``);
file integrity is checked with hashlib against the SHA-256 each results.json lists; "not run again" is checked
on the files' modification times; a worker is killed with SIGKILL and the campaign process gets a real SIGINT.
All studies are the thesis's four points with 6 trajectory samples, one optimiser start, no occlusion test.
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from cadfeat.campaign.plan import load_campaign
from cadfeat.campaign.runner import local_cluster, run_campaign
from cadfeat.campaign.spec import CampaignError

ROOT = Path(__file__).resolve().parents[2]
SMALL = ROOT / "campaigns" / "four_points_small.toml"
BASE = ROOT / "studies" / "thesis_four_points.toml"
PART = ROOT / "parts" / "thesis_four_points.py"


@pytest.fixture(scope="module")
def client():
    with local_cluster(2, retries=1) as c:
        yield c


def _campaign(tmp_path: Path, cases: list[str], name: str = "t") -> Path:
    """A campaign of ``cases`` (TOML inline tables) over the tiny four-points study."""
    text = (f'[campaign]\nname = "{name}"\nstudy = "{BASE}"\ntimeout_s = 600\n'
            "[overrides.trajectory]\nn = 6\n[overrides.objective]\nocclusion = false\n"
            "[overrides.optimizer]\nstarts = 1\nmaxiter = 20\n")
    text += "".join(f"[[cases]]\n{c}\n" for c in cases)
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def _comparable(path: Path) -> dict:
    data = json.loads(path.read_text())
    data.pop("created")
    data.pop("timings_s")
    return data


def _intact(folder: Path) -> None:
    """Every file results.json lists is there with its SHA-256; the study layer's manifest says complete."""
    results = json.loads((folder / "results.json").read_text())
    for entry in results["files"]:
        assert hashlib.sha256((folder / entry["name"]).read_bytes()).hexdigest() == entry["sha256"]
    assert json.loads((folder / ".cadfeat-output.json").read_text())["state"] == "complete"


def _staging(folder: Path) -> list[str]:
    return [p.name for p in folder.rglob(".*") if ".staging-" in p.name or ".old-" in p.name]


def _mtimes(folder: Path) -> dict[str, int]:
    return {p.name: (p / "results.json").stat().st_mtime_ns for p in (folder / "cases").iterdir()}


# ----------------------------------------------------------------------------------------- validation
def test_campaign_errors_are_one_line_with_file_key_and_allowed(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(f'[campaign]\nname = "x"\nstudy = "{BASE}"\nmode = "grid"\n[axes]\n"trajectory.n" = [4]\n')
    with pytest.raises(CampaignError, match=r"bad\.toml: campaign\.mode: Extra inputs are not permitted; allowed: "
                                            r"keys name, study, description, timeout_s, retries$"):
        load_campaign(bad)
    bad.write_text(f'[campaign]\nname = "x"\nstudy = "{BASE}"\n[axes]\n"design.parameters" = [1]\n')
    with pytest.raises(CampaignError, match=r"bad\.toml: axes: unknown axis 'design\.parameters'; allowed: part, "
                                            r"camera, study\.seed"):
        load_campaign(bad)
    bad.write_text(f'[campaign]\nname = "x"\nstudy = "{BASE}"\ntimeout_s = -1\n[axes]\n"trajectory.n" = [4]\n')
    with pytest.raises(CampaignError, match=r"campaign\.timeout_s: Input should be greater than 0 \(given: -1\); "
                                            r"allowed: wall-time limit"):
        load_campaign(bad)
    # a case's study is validated by the study layer before any work: its dotted key and allowed values
    bad.write_text(f'[campaign]\nname = "x"\nstudy = "{BASE}"\n[[cases]]\n"trajectory.n" = 6\n'
                   '[[cases]]\n"objective.aggregate" = "median"\n')
    with pytest.raises(CampaignError, match=r"bad\.toml: case 2 \(objective\.aggregate=median\): "
                                            r"objective\.aggregate: .*allowed: sum, mean, min, smoothmin"):
        load_campaign(bad)


def test_grid_resolves_paths_and_hash_follows_the_part_bytes(tmp_path: Path) -> None:
    camp = load_campaign(SMALL)
    assert camp.mode == "grid" and len(camp.cases) == 6 and len({c.input_hash for c in camp.cases}) == 6
    assert {c.values["trajectory.radius_end_mm"] for c in camp.cases} == {8.0, 10.0, 12.0}
    study = camp.cases[3].study
    assert Path(study["camera"]["calibration"]).is_absolute() and Path(study["study"]["part"]) == PART
    # the same study with a part file of other bytes has another input hash
    part = tmp_path / "thesis_four_points.py"
    part.write_text(PART.read_text())
    one = _campaign(tmp_path, [f'part = "{part}"'], "h")
    h1 = load_campaign(one).cases[0].input_hash
    part.write_text(PART.read_text() + "\n# changed\n")
    assert load_campaign(one).cases[0].input_hash != h1


# ----------------------------------------------------------------------------------------- on Dask
@pytest.mark.slow
def test_campaign_matches_serial_runs_and_rerun_skips(client, tmp_path: Path) -> None:
    from cadfeat.study import run_study

    out = tmp_path / "camp"
    result = run_campaign(SMALL, out, client=client, quiet=True)
    assert result.ran == 6 and result.count("done") == 6, [r.get("error") for r in result.records]
    camp = load_campaign(SMALL)
    for case in (camp.cases[0], camp.cases[-1]):  # the two ends of the grid (the other 4: the same code path)
        serial = run_study(case.study, tmp_path / "serial" / case.name, quiet=True, progress=False)
        assert serial.out_dir is not None
        assert _comparable(out / "cases" / case.name / "results.json") == \
            _comparable(tmp_path / "serial" / case.name / "results.json"), case.name
        _intact(out / "cases" / case.name)
    csv = (out / "campaign.csv").read_text().splitlines()
    assert len(csv) == 7 and csv[0].startswith("case,status,camera,trajectory.radius_end_mm,combined_before")
    page = (out / "campaign.html").read_text()
    assert page.count("data:image/png;base64,") == 2 and "sortable" in page and "<script src" not in page
    before = _mtimes(out)
    again = run_campaign(SMALL, out, client=client, quiet=True)  # nothing to do: no study runs
    assert (again.ran, again.skipped, again.count("done")) == (0, 6, 6)
    assert _mtimes(out) == before


@pytest.mark.slow
def test_failing_and_overrunning_cases_are_recorded_and_rerun(client, tmp_path: Path, monkeypatch) -> None:
    from cadfeat.campaign import runner

    broken = tmp_path / "broken_points.py"
    broken.write_text(PART.read_text().replace("    sx, sy, sz = PLATE_MM\n",
                                               "    raise RuntimeError('this part does not build')\n"))
    stuck = tmp_path / "slow_points.py"  # its import sleeps (in the CAD worker process): the study waits in C code
    stuck.write_text("__import__('time').sleep(40)\n" + PART.read_text())
    monkeypatch.setattr(runner, "GRACE_S", 2.0)
    # the 0.2 s case cannot finish in time even warm; the stuck case's 8 s leave the study time to reach the worker
    # (in C) even on a loaded machine (4 s did not always, under CI's two test processes and a busy machine), and
    # its import sleeps longer than the limit plus the grace
    path = _campaign(tmp_path, [f'part = "{broken}"', '"trajectory.radius_end_mm" = 9.0\ntimeout_s = 0.2',
                                '"trajectory.radius_end_mm" = 11.0', f'part = "{stuck}"\ntimeout_s = 8.0'])
    out = tmp_path / "out"
    result = run_campaign(path, out, client=client, quiet=True)
    status = [r["status"] for r in result.records]
    assert status == ["failed", "timeout", "done", "timeout"], [r.get("error") for r in result.records]
    assert "this part does not build" in result.records[0]["error"]
    assert "time limit of 0.2 s" in result.records[1]["error"]
    assert "its worker was restarted" in result.records[3]["error"]  # stuck in C: stopped by the campaign
    done = result.records[2]["case"]
    assert sorted(p.name for p in (out / "cases").iterdir()) == [done]  # nothing half-written
    _intact(out / "cases" / done)
    rows = (out / "campaign.csv").read_text()
    assert "this part does not build" in rows and ",timeout," in rows
    before = _mtimes(out)
    # the unfinished cases run again, only they — this time attached to the cluster by its scheduler's address
    again = run_campaign(path, out, scheduler=client.scheduler.address, quiet=True)
    assert (again.ran, again.skipped) == (3, 1)
    assert [r["status"] for r in again.records] == status, [r.get("error") for r in again.records]
    assert _mtimes(out) == before  # (a timed-out case that went on — its CaseTimeout swallowed — would publish)


@pytest.mark.slow
def test_killed_worker_case_is_retried_or_recorded(client, tmp_path: Path) -> None:
    path = _campaign(tmp_path, ['"trajectory.radius_end_mm" = 8.5', '"trajectory.radius_end_mm" = 9.5'], "k")
    out = tmp_path / "out"
    box: dict = {}
    runner = threading.Thread(target=lambda: box.update(r=run_campaign(path, out, client=client, quiet=True)))
    runner.start()
    killed = None
    deadline = time.monotonic() + 300
    while killed is None and time.monotonic() < deadline and runner.is_alive():
        for stage in (out / "cases").glob(".*.staging-*") if (out / "cases").exists() else []:
            try:
                killed = int(json.loads((stage / ".cadfeat-output.json").read_text())["pid"])
            except (OSError, ValueError, KeyError):
                continue
            os.kill(killed, signal.SIGKILL)  # the worker process running this study
            break
        time.sleep(0.05)
    runner.join(600)
    assert killed is not None and not runner.is_alive()
    result = box["r"]
    assert len(result.records) == 2 and all(r["status"] in ("done", "failed") for r in result.records)
    assert result.count("done") >= 1
    for r in result.records:
        if r["status"] == "failed":
            assert "worker process died" in r["error"]
        else:
            _intact(out / "cases" / r["case"])
    assert _staging(out) == []


@pytest.mark.slow
def test_sigint_keeps_finished_cases_and_leaves_no_staging(tmp_path: Path) -> None:
    path = _campaign(tmp_path, ['"trajectory.radius_end_mm" = 7.5', '"trajectory.radius_end_mm" = 8.5',
                                '"trajectory.radius_end_mm" = 9.5'], "s")
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "cadfeat", "campaign", str(path), "--out", str(out),
                             "--workers", "1", "--quiet"], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # as typed
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and proc.poll() is None:
            records = [json.loads(p.read_text()) for p in (out / "records").glob("*.json")] \
                if (out / "records").exists() else []
            if any(r["status"] == "done" for r in records):
                break
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    records = [json.loads(p.read_text()) for p in (out / "records").glob("*.json")]
    done = [r for r in records if r["status"] == "done"]
    assert done and len(records) == 3 and {r["status"] for r in records} <= {"done", "interrupted"}
    for r in done:
        _intact(out / "cases" / r["case"])
    assert sorted(p.name for p in (out / "cases").iterdir()) == sorted(r["case"] for r in done)
    assert _staging(out) == [] and not list(out.glob(".*.tmp-*"))
    assert ",interrupted," in (out / "campaign.csv").read_text()
