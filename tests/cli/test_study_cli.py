"""``cadfeat validate`` exit codes and messages (the CLI prints CadfeatError as one line, exit code 2)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from study_helpers import study

ROOT = Path(__file__).resolve().parents[2]


def cadfeat(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cadfeat", *args], capture_output=True, text=True, cwd=ROOT,
                          env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin", "CADFEAT_CACHE": "off"}, timeout=120)


def test_validate_ok(tmp_path):
    res = cadfeat("validate", str(study(tmp_path)))
    assert res.returncode == 0, res.stderr
    assert "ok" in res.stdout and "x0, count" in res.stdout


def test_validate_bad_value_exit_2_one_line(tmp_path):
    res = cadfeat("validate", str(study(tmp_path, objective={"aggregate": "median"})))
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1
    assert "s.toml" in lines[0] and "objective.aggregate" in lines[0] and "sum, mean, min, smoothmin" in lines[0]


def test_run_missing_file_exit_2(tmp_path):
    res = cadfeat("run", str(tmp_path / "nope.toml"), "--quiet")
    assert res.returncode == 2 and "nope.toml" in res.stderr
