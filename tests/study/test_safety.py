"""Reliability under bad input and faults (issue 9), end to end through the ``cadfeat`` command.

Every case runs the real CLI in a subprocess, the way a user meets it: output folders cadfeat did not create,
unwritable destinations, part scripts that hang, exit, flood the terminal or are interrupted, sizes that
cannot fit, SIGTERM / SIGKILL at observed moments (a staging folder appearing, a file appearing in it), a
camera that never sees the part, a CAD rebuild that fails at the optimum. Memory cases run under an
address-space limit (``resource.setrlimit`` in the child), so a failure cannot take the machine down.
"""

from __future__ import annotations

import hashlib
import json
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from study_helpers import PLATE, STEP, study, write_toml

ROOT = Path(__file__).resolve().parents[2]
ENV = {"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/tmp"),
       "CADFEAT_CACHE": "off"}  # (the suite never writes into the user's set-up cache: tests/conftest.py)
TINY = {"trajectory": {"n": 4}, "optimizer": {"starts": 1, "maxiter": 5},
        "design": {"parameters": {"x0": {"lower": -15, "upper": -5}}}}  # (no integer parameter: one setup)
MEMORY_LIMIT_BYTES = 3 * 2**30


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT_BYTES, MEMORY_LIMIT_BYTES))


def cadfeat(*args: str, cwd: Path = ROOT, timeout: float = 180, memory_limit: bool = False
            ) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cadfeat", *args], capture_output=True, text=True, cwd=cwd,
                          env=ENV, timeout=timeout, preexec_fn=_limit_memory if memory_limit else None)


def _as_from_a_terminal() -> None:
    """In the child: SIGINT and SIGTERM at their default dispositions, as a command typed in a terminal has them.
    A harness started in the background of a non-interactive shell (``cmd &``) ignores SIGINT, and an ignored
    signal stays ignored across exec: Python then keeps it ignored and Ctrl-C could not be tested."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def popen(*args: str, cwd: Path = ROOT) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "cadfeat", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=cwd, env={**ENV, "PYTHONFAULTHANDLER": "1"},
                            preexec_fn=_as_from_a_terminal)


def _signal_state(pid: int) -> str:
    """Each thread's blocked, ignored and caught signal sets (/proc, Linux): why a signal was not acted on."""
    out = []
    for task in sorted(Path(f"/proc/{pid}/task").glob("*")):
        try:
            status = (task / "status").read_text().splitlines()
        except OSError:
            continue
        out.append(f"{pid}/{task.name}: " + " ".join(line.replace("\t", "") for line in status
                                                     if line.startswith(("Name", "SigBlk", "SigIgn", "SigCgt"))))
    return "\n".join(out)


def finish(proc: subprocess.Popen, timeout_s: float = 60.0) -> str:
    """Wait for cadfeat to exit after a signal; its stderr. If it does not: the process tree and every thread's
    stack (SIGABRT, dumped by faulthandler) in the failure message, to show what it was waiting on."""
    try:
        return proc.communicate(timeout=timeout_s)[1]
    except subprocess.TimeoutExpired:
        tree = subprocess.run(["ps", "-o", "pid,ppid,stat,etime,args", "--ppid", str(proc.pid), "-p", str(proc.pid)],
                              capture_output=True, text=True).stdout
        tree += "\nsignal masks (SigBlk/SigIgn/SigCgt) of cadfeat's threads and of this test process:\n" + \
            _signal_state(proc.pid) + "\n" + _signal_state(os.getpid())
        proc.send_signal(signal.SIGABRT)
        try:
            err = proc.communicate(timeout=30)[1]
        except subprocess.TimeoutExpired:
            proc.kill()
            err = proc.communicate()[1]
        pytest.fail(f"cadfeat did not exit within {timeout_s:g} s; processes:\n{tree}\nstderr:\n{err[-6000:]}")


def one_error_line(res: subprocess.CompletedProcess, *needles: str) -> str:
    """The run failed with status 2 and exactly one ``cadfeat: error:`` line (no traceback) holding needles."""
    assert res.returncode == 2, (res.returncode, res.stdout[-2000:], res.stderr[-2000:])
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("cadfeat: error:")]
    assert len(errors) == 1 and "Traceback" not in res.stderr, res.stderr[-3000:]
    for needle in needles:
        assert needle in errors[0], (needle, errors[0])
    return errors[0]


def tiny_study(folder: Path, **changes: dict) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    merged = {k: dict(v) for k, v in TINY.items()}
    for section, table in changes.items():
        merged[section] = {**merged.get(section, {}), **table} if table is not None else None
    return study(folder, **merged)


def snapshot(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def wait_for(predicate, proc: subprocess.Popen, what: str, timeout_s: float = 240.0):
    """Poll until ``predicate()`` returns something truthy (the observable event), or fail."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        found = predicate()
        if found:
            return found
        if proc.poll() is not None:
            out, err = proc.communicate()
            pytest.fail(f"cadfeat ended (status {proc.returncode}) before {what}: {err[-2000:]}")
        time.sleep(0.01)
    proc.kill()
    pytest.fail(f"timed out waiting for {what}")


def staging_folders(parent: Path) -> list[Path]:
    return [p for p in parent.iterdir() if p.name.startswith(".") and ".staging-" in p.name]


def user_folder(tmp_path: Path) -> tuple[Path, Path, dict[str, str]]:
    """The issue's case: a folder with the study, its part and the user's own notes."""
    d = tmp_path / "d"
    s = tiny_study(d)
    (d / "notes.txt").write_text("my notes\n")
    return d, s, snapshot(d)


# ------------------------------------------------------------------------------------ output folders
@pytest.mark.parametrize("command", ["run", "evaluate"])
def test_folder_with_the_users_files_is_refused_before_any_work(tmp_path, command):
    d, s, before = user_folder(tmp_path)
    t0 = time.monotonic()
    res = cadfeat(command, str(s), "--out", str(d))
    one_error_line(res, "did not write", "notes.txt", "--force", "--out NEW_FOLDER")
    assert time.monotonic() - t0 < 60  # refused at once: no CAD import, no build (a run takes longer)
    assert snapshot(d) == before and sorted(p.name for p in tmp_path.iterdir()) == ["d"]


def test_force_refuses_the_users_holes_csv_before_any_work(tmp_path):
    """Issue 16: holes.csv is one of cadfeat's output names, so a user's own is found at once, not at publishing."""
    d, s, before = user_folder(tmp_path)
    (d / "holes.csv").write_text("my holes\n")
    one_error_line(cadfeat("run", str(s), "--out", str(d), "--force", "--quiet"), "holes.csv", "not written by cadfeat")
    assert snapshot(d) == {**before, "holes.csv": snapshot(d)["holes.csv"]}
    assert not staging_folders(tmp_path)


def test_force_adds_cadfeats_files_and_leaves_the_users_alone(tmp_path):
    d, s, before = user_folder(tmp_path)
    (d / "results.json").write_text("{\"mine\": true}\n")  # a file of a name cadfeat writes, not cadfeat's
    res = cadfeat("run", str(s), "--out", str(d), "--force", "--quiet")
    one_error_line(res, "results.json", "not written by cadfeat", "new folder")
    (d / "results.json").unlink()
    res = cadfeat("run", str(s), "--out", str(d), "--force", "--quiet")
    assert res.returncode == 0, res.stderr[-3000:]
    after = snapshot(d)
    assert {k: after[k] for k in before} == before  # the study, the part and the notes: byte for byte
    manifest = json.loads((d / ".cadfeat-output.json").read_text())
    assert {"original.step", "optimised.step", "optimised.stl", "results.json"} <= set(manifest["files"])
    assert not set(manifest["files"]) & {"s.toml", "study_plate.py", "notes.txt"}
    assert not staging_folders(tmp_path)
    # the folder now mixes the user's files and cadfeat's: without --force it is refused again
    one_error_line(cadfeat("run", str(s), "--out", str(d), "--quiet"), "notes.txt", "--force")
    # `cadfeat report` beside the results adds report.html / img, nothing else changes
    res = cadfeat("report", str(d / "results.json"))
    assert res.returncode == 0, res.stderr[-3000:]
    assert {k: snapshot(d)[k] for k in before} == before and (d / "report.html").is_file()
    # report --out into a folder of the user's
    other = tmp_path / "other"
    other.mkdir()
    (other / "keep.txt").write_text("x")
    one_error_line(cadfeat("report", str(d / "results.json"), "--out", str(other)), "keep.txt", "--force")
    assert sorted(p.name for p in other.iterdir()) == ["keep.txt"]


@pytest.mark.parametrize("out", ["", ".", "FILE/sub", "/proc/cadfeat-x", "/proc/sys/cadfeat-x"])
def test_unwritable_output_is_refused_before_any_work(tmp_path, out):
    s = tiny_study(tmp_path)
    (tmp_path / "FILE").write_text("a regular file")
    before = snapshot(tmp_path)
    res = cadfeat("run", str(s), "--out", out, cwd=tmp_path, timeout=60)
    one_error_line(res, "folder")
    assert snapshot(tmp_path) == before and not staging_folders(tmp_path)


# ------------------------------------------------------------------------------------ signals
def test_killed_run_leftovers_removed_by_next_run_and_sigterm_cleans_up(tmp_path):
    s = tiny_study(tmp_path / "in")
    parent = tmp_path / "exports"
    parent.mkdir()
    out = parent / "plate"
    # a run killed outright (SIGKILL: no clean-up possible) leaves its staging folder behind
    proc = popen("run", str(s), "--out", str(out), "--quiet")
    stale = wait_for(lambda: staging_folders(parent), proc, "the staging folder")[0]
    proc.kill()
    proc.communicate()
    assert stale.is_dir() and not out.exists()
    (parent / ".plate.staging-1-0123abcd").mkdir()  # (looks like one, but is not cadfeat's: no manifest)
    # the next run into the same parent removes it; SIGTERM while it writes its outputs: exit 143, no trace
    proc = popen("run", str(s), "--out", str(out), "--quiet")
    wait_for(lambda: [p for p in staging_folders(parent) if (p / "original.step").exists()], proc,
             "the export writing original.step")
    assert not stale.exists()
    proc.send_signal(signal.SIGTERM)
    err = finish(proc)
    assert proc.returncode == 143, err[-2000:]
    assert "terminated" in err and "Traceback" not in err
    assert sorted(p.name for p in parent.iterdir()) == [".plate.staging-1-0123abcd"]


INTERRUPTED_IMPORT = '''
import multiprocessing
import pathlib
import time

if multiprocessing.parent_process() is None:  # in cadfeat itself (not in the worker that tries the import first)
    pathlib.Path(__file__).with_name("importing").write_text("now")
    try:
        for _ in range(1200):  # a slow import (e.g. CadQuery's first import: busy in Python, not one long sleep)
            time.sleep(0.1)
    except KeyboardInterrupt:
        raise ImportError("initialisation of an extension module failed") from None  # what such modules do
'''


def test_ctrl_c_while_the_part_script_imports_is_an_interrupt(tmp_path):
    s = tiny_study(tmp_path)
    (tmp_path / "study_plate.py").write_text(INTERRUPTED_IMPORT + PLATE.read_text())
    proc = popen("validate", str(s))
    wait_for(lambda: (tmp_path / "importing").exists(), proc, "the part script importing")
    proc.send_signal(signal.SIGINT)
    err = finish(proc)
    assert proc.returncode == 130, err[-2000:]
    assert "interrupted" in err and "ImportError" not in err and "Traceback" not in err


# ------------------------------------------------------------------------------------ part scripts
HANG_IN_BUILD = "def build(x0=-10.0, y0=5.0, pitch=10.0, diameter=4.0, count=3):\n    while True:\n        pass\n"
HANG_AT_IMPORT = "while True:\n    pass\n"


@pytest.mark.parametrize("command, hang", [("run", "build"), ("evaluate", "build"), ("validate", "import"),
                                           ("parts", "build"), ("render", "import")])
def test_a_hanging_part_script_is_stopped_at_the_time_limit(tmp_path, command, hang):
    s = tiny_study(tmp_path, study={"build_timeout_s": 1.5})
    part = tmp_path / "study_plate.py"
    text = PLATE.read_text()
    text = HANG_AT_IMPORT + text if hang == "import" else text.replace(
        "def build(x0=-10.0, y0=5.0, pitch=10.0, diameter=4.0, count=3):\n", HANG_IN_BUILD + "\n\ndef _unused():\n")
    part.write_text(text)
    args = {"run": ["run", str(s), "--out", str(tmp_path / "o")], "evaluate": ["evaluate", str(s)],
            "validate": ["validate", str(s)], "parts": ["parts", str(part), "--holes", "--build-timeout", "1.5"],
            "render": ["render", str(part), "--out", str(tmp_path / "p.png"), "--build-timeout", "1.5"]}[command]
    t0 = time.monotonic()
    res = cadfeat(*args, timeout=120)
    elapsed = time.monotonic() - t0
    what = "importing the part script" if hang == "import" else "build("
    one_error_line(res, str(part), what, "time limit of 1.5 s")
    assert elapsed < 45, elapsed  # the limit plus start-up (CadQuery imports), never the hang
    assert not (tmp_path / "o").exists() and not staging_folders(tmp_path)


@pytest.mark.parametrize("where", ["import", "build"])
def test_sys_exit_in_a_part_script_is_an_error(tmp_path, where):
    s = tiny_study(tmp_path)
    text = PLATE.read_text()
    if where == "import":
        text = "import sys\nsys.exit(0)\n" + text
    else:
        text = text.replace("    import cadquery as cq\n", "    import sys\n    sys.exit(3)\n", 1)
    (tmp_path / "study_plate.py").write_text(text)
    res = cadfeat("validate", str(s))
    one_error_line(res, "study_plate.py", "sys.exit(" + ("0" if where == "import" else "3") + ")",
                   "must not exit")


def test_output_flood_of_a_part_script_is_contained(tmp_path):
    tiny_study(tmp_path)
    flood = "for _i in range(300_000):\n    print('flood', _i)\n"
    (tmp_path / "study_plate.py").write_text(flood + PLATE.read_text())
    res = cadfeat("parts", str(tmp_path / "study_plate.py"))
    assert res.returncode == 0, res.stderr[-2000:]
    assert len(res.stdout) + len(res.stderr) < 5_000  # 3.9 MB printed; 20 lines shown, the rest counted
    assert "flood 19" in res.stderr and "flood 20\n" not in res.stderr and "more characters not shown" in res.stderr


# ------------------------------------------------------------------------------------ sizes, names, files
@pytest.mark.parametrize("changes, needles", [
    ({"trajectory": {"n": 1_000_000_000}}, ["trajectory.n", "limit of 100,000"]),
    ({"camera": {"preset": None, "fx": 500.0, "fy": 500.0, "cx": 320.0, "cy": 240.0, "width": 10**9,
                 "height": 480}}, ["camera.width", "limit of 20,000"]),
    ({"optimizer": {"starts": 10**7}}, ["optimizer.starts", "10000"]),
    ({"optimizer": {"maxiter": 10**9}}, ["optimizer.maxiter", "1000000"]),
])
def test_sizes_beyond_the_limits_are_refused_at_validation(tmp_path, changes, needles):
    s = tiny_study(tmp_path, **changes)
    t0 = time.monotonic()
    res = cadfeat("validate", str(s), memory_limit=True, timeout=60)
    one_error_line(res, *needles)
    assert time.monotonic() - t0 < 30


def test_too_many_design_variables_refused(tmp_path):
    data = {"study": {"name": "step", "part": str(STEP)}, "camera": {"preset": "dalsa-cad1-128a"},
            "trajectory": TINY["trajectory"] | {"kind": "straight_approach", "start": [0, 0, 300], "end": [0, 0, 150],
                                                "target": [0, 0, 0]},
            "design": {"holes": [{"select": 1}] * 65}}
    res = cadfeat("validate", str(write_toml(tmp_path / "s.toml", data)), memory_limit=True, timeout=60)
    one_error_line(res, "design.holes", "limit of 64")


def test_study_name_with_a_newline_is_refused(tmp_path):
    res = cadfeat("validate", str(tiny_study(tmp_path, study={"name": "abc\n"})))
    one_error_line(res, "study.name", "not allowed")


def test_validate_reads_the_step_file(tmp_path):
    s = tiny_study(tmp_path, study={"part": "part.step"}, design={"parameters": None, "holes": [{"select": 1}]})
    (tmp_path / "part.step").write_bytes(b"\x00" * 64)
    one_error_line(cadfeat("validate", str(s)), "part.step", "STEP header")
    (tmp_path / "part.step").unlink()
    (tmp_path / "part.step").symlink_to("/dev/zero")
    one_error_line(cadfeat("validate", str(s), memory_limit=True), "part.step", "not a regular file")
    (tmp_path / "part.step").unlink()
    (tmp_path / "part.step").write_bytes(STEP.read_bytes())
    assert cadfeat("validate", str(s)).returncode == 0


# ------------------------------------------------------------------------------------ the optimisation
@pytest.mark.parametrize("trajectory, cause", [
    ({"kind": "orbit_arc", "centre": [5000, 5000, 0], "radius_mm": 200.0, "elevation_deg": 60.0,
      "azimuth_start_deg": 0.0, "azimuth_end_deg": 90.0, "start": None, "end": None, "target": None},
     "field of view"),
    ({"start": [0, 0, -300], "end": [0, 0, -150]}, "behind the holes' faces"),
])
def test_a_camera_that_never_sees_the_part_is_refused_before_optimising(tmp_path, trajectory, cause):
    s = tiny_study(tmp_path, trajectory=trajectory)
    res = cadfeat("run", str(s), "--out", str(tmp_path / "o"), "--quiet")
    one_error_line(res, "never sees the part", cause, "Nothing was optimised")
    assert not (tmp_path / "o").exists()


FAILS_NEAR_OPTIMUM = '''
_real_build = build


def build(x0=-10.0, y0=5.0, pitch=10.0, diameter=4.0, count=3):
    if y0 < 2.0:
        raise ValueError("the CAD kernel fails below y0 = 2 mm")
    return _real_build(x0, y0, pitch, diameter, count)
'''


def test_a_rebuild_failing_at_the_optimum_is_an_infeasible_point(tmp_path):
    """The feature map is linear, its optimum (y0 ≈ -0.2 mm) does not build: the run continues with CAD in the
    loop, shrinking the region around the start until a design builds (y0 = 2.5 mm here), and exports it."""
    s = tiny_study(tmp_path, camera={"preset": "realsense-d435-rgb", "focus_distance_mm": 200.0},
                   trajectory={"start": [-60.0, -80.0, 260.0], "end": [40.0, -40.0, 180.0], "target": [0.0, 0.0, 6.0],
                               "n": 6, "duration_s": 2.0},
                   design={"parameters": {"x0": {"lower": -18.0, "upper": -4.0}, "y0": {"lower": -8.0, "upper": 12.0}}},
                   objective={"measures": ["fov"], "combine": "weighted", "aggregate": "sum"},
                   optimizer={"starts": 2, "maxiter": 25})
    (tmp_path / "study_plate.py").write_text(PLATE.read_text() + FAILS_NEAR_OPTIMUM)
    res = cadfeat("run", str(s), "--out", str(tmp_path / "o"), "--quiet")
    assert res.returncode == 0, res.stderr[-3000:]
    results = json.loads((tmp_path / "o" / "results.json").read_text())
    assert "fails below y0 = 2 mm" in results["optimizer"]["rebuild_failed_at_model_optimum"]
    after = {v["name"]: v["after"] for v in results["variables"]}
    assert 2.0 <= after["y0"] < 5.0  # buildable, and still better than the start (y0 = 5)
    assert results["objectives"]["combined_after"] > results["objectives"]["combined_before"]


# ------------------------------------------------------------------------------------ staging (library level)
def _fake_staging(parent: Path, name: str, pid: int, host: str | None = None, manifest: bool = True) -> Path:
    import socket

    path = parent / name
    path.mkdir()
    (path / "optimised.step").write_text("partial")
    if manifest:
        (path / ".cadfeat-output.json").write_text(json.dumps(
            {"cadfeat_output": 1, "state": "staging", "files": [], "pid": pid, "host": host or socket.gethostname()}))
    return path


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid  # (reaped: no such process now, unless the number was reused at once)


def test_only_cadfeats_own_staging_of_dead_runs_is_removed(tmp_path):
    from cadfeat.output_folder import remove_stale_staging

    dead = _dead_pid()
    gone = _fake_staging(tmp_path, f".out.staging-{dead}-0123abcd", dead)
    old = _fake_staging(tmp_path, f".out.old-{dead}-89abcdef", dead)
    alive = _fake_staging(tmp_path, f".out.staging-{os.getpid()}-0123abcd", os.getpid())
    foreign = _fake_staging(tmp_path, f".out.staging-{dead}-fedcba98", dead, manifest=False)
    other_host = _fake_staging(tmp_path, f".out.staging-{dead}-00000000", dead, host="another-machine")
    other_pid = _fake_staging(tmp_path, f".out.staging-{dead}-11111111", dead + 1)  # manifest names another pid
    user = tmp_path / ".out.staging-notes"
    user.mkdir()
    empty = tmp_path / f".out.staging-{dead}-22222222"  # killed before its manifest was written
    empty.mkdir()
    empty_alive = tmp_path / f".out.staging-{os.getpid()}-33333333"
    empty_alive.mkdir()
    cut = tmp_path / f".out.staging-{dead}-44444444"  # killed while writing its manifest: cut short
    cut.mkdir()
    (cut / ".cadfeat-output.json").write_text('{"cadfeat_output": 1, "sta')
    cut_with_more = tmp_path / f".out.staging-{dead}-55555555"  # the same, but holding a file someone wrote
    cut_with_more.mkdir()
    (cut_with_more / ".cadfeat-output.json").write_text("")
    (cut_with_more / "notes.txt").write_text("mine")
    assert sorted(remove_stale_staging(tmp_path)) == sorted([gone, old, empty, cut])
    assert all(p.is_dir() for p in (alive, foreign, other_host, other_pid, user, empty_alive, cut_with_more))
    assert (cut_with_more / "notes.txt").read_text() == "mine"


def test_concurrent_runs_into_one_folder_end_in_one_complete_result(tmp_path):
    """Two writers publish into the same new folder at the same moment: the folder ends complete (one writer's
    files and a manifest listing them), the other writer gets a one-line error or replaced it, no staging left."""
    import threading

    from cadfeat.output_folder import OutputFolderError, is_cadfeat_folder, staged_output

    out = tmp_path / "out"
    barrier = threading.Barrier(2)
    outcome: dict[int, str] = {}

    def writer(k: int) -> None:
        try:
            with staged_output(out) as stage:
                for name in ("original.step", "results.json"):
                    (stage / name).write_text(f"writer {k}")
                barrier.wait(10)
            outcome[k] = "ok"
        except OutputFolderError as exc:
            outcome[k] = str(exc)

    threads = [threading.Thread(target=writer, args=(k,)) for k in (1, 2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    assert "ok" in outcome.values() and all(v == "ok" or "\n" not in v for v in outcome.values())
    assert is_cadfeat_folder(out)
    texts = {(out / n).read_text() for n in ("original.step", "results.json")}
    assert len(texts) == 1  # one writer's complete result, not a mix
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_output_folder_of_an_older_cadfeat_counts_as_cadfeats(tmp_path):
    """A folder written before manifests existed (only cadfeat's names, a results.json naming cadfeat_version) is
    cadfeat's; one more file of the user's, or a results.json of someone else, and it is not."""
    from cadfeat.output_folder import is_cadfeat_folder

    old = tmp_path / "old"
    old.mkdir()
    (old / "results.json").write_text(json.dumps({"cadfeat_version": "0.1.0"}))
    (old / "optimised.step").write_text("ISO-10303-21;")
    (old / "img").mkdir()
    assert is_cadfeat_folder(old)
    (old / "notes.txt").write_text("mine")
    assert not is_cadfeat_folder(old)
    (old / "notes.txt").unlink()
    (old / "results.json").write_text(json.dumps({"mine": True}))
    assert not is_cadfeat_folder(old)


def test_cad_work_in_a_worker_is_cut_off_at_the_limit():
    """The mechanism behind the time limit of STEP re-drilling (``call_with_time_limit``): the result comes back
    from the worker; a call that runs past the limit is stopped within the limit plus start-up."""
    from cadfeat.cad.parts import PartBuildError, call_with_time_limit

    assert call_with_time_limit(pow, (2, 10), "pow", timeout_s=60) == 1024
    t0 = time.monotonic()
    with pytest.raises(PartBuildError, match=r"^sleeping: exceeded|^sleeping exceeded the time limit of 1 s"):
        call_with_time_limit(time.sleep, (600,), "sleeping", timeout_s=1.0)
    assert time.monotonic() - t0 < 30
    with pytest.raises(PartBuildError, match="ZeroDivisionError"):
        call_with_time_limit(divmod, (1, 0), "dividing", timeout_s=60)


def test_background_work_in_a_worker_comes_back_fails_cleanly_and_is_killed():
    """``BackgroundCall`` (the closed-loop check's workers): its result later, a failure as ``PartBuildError``
    naming the work (the check then tracks the design itself), and ``cancel`` kills a worker still running."""
    from cadfeat.cad.parts import PartBuildError
    from cadfeat.cad.sandbox import BackgroundCall

    assert BackgroundCall(pow, (2, 10), "pow").result(60) == 1024
    with pytest.raises(PartBuildError, match="dividing: ZeroDivisionError"):
        BackgroundCall(divmod, (1, 0), "dividing").result(60)
    with pytest.raises(PartBuildError, match="sleeping gave no result within 0.5 s"):
        BackgroundCall(time.sleep, (600,), "sleeping").result(0.5)
    call = BackgroundCall(time.sleep, (600,), "sleeping")
    t0 = time.monotonic()
    call.cancel()
    assert not call._worker.proc.is_alive() and time.monotonic() - t0 < 30
