"""Shared helpers of the study tests: a base study table and a TOML writer."""

from __future__ import annotations

import copy
import importlib.util
import json
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pytest

DATA = Path(__file__).parent / "data"
PLATE = DATA / "study_plate.py"
STEP = DATA / "plate_holes.step"

BASE = {
    "study": {"name": "plate", "part": "study_plate.py", "seed": 3},
    "camera": {"preset": "dalsa-cad1-128a", "focus_distance_mm": 200.0},  # the depths of the approach (pre-flight)
    "part_pose": {"position_mm": [0, 0, 0]},
    "trajectory": {"kind": "straight_approach", "start": [0, 0, 300], "end": [0, 0, 150], "target": [0, 0, 0],
                   "n": 10},
    "design": {"parameters": {"x0": {"lower": -15, "upper": -5}, "count": {}}},
    "constraints": {"edge_distance_mm": 2.0},
    "objective": {"measures": ["fov", "resolvability"], "aggregate": "sum", "combine": "maxmin"},
    "optimizer": {"method": "multistart", "starts": 2},
    "robustness": {"robust": False},  # the nominal optimum: robust studies are tested in test_robust*.py
}


#: The kept requirements of ``SMALL`` (tests re-check them on the written STEP).
EDGE_MM, LIGAMENT_MM = 3.0, 2.5
#: A small script study optimised end to end (tests/study/test_study_run.py, the results model, compare_results).
SMALL = {
    "study": {"name": "small_plate", "part": str(PLATE), "seed": 7},
    "camera": {"preset": "realsense-d435-rgb", "focus_distance_mm": 200.0},
    "trajectory": {"kind": "straight_approach", "start": [-60.0, -80.0, 260.0], "end": [40.0, -40.0, 180.0],
                   "target": [0.0, 0.0, 6.0], "n": 12, "duration_s": 2.0},
    "design": {"parameters": {"x0": {"lower": -18.0, "upper": -4.0}, "y0": {"lower": -8.0, "upper": 12.0}}},
    "constraints": {"edge_distance_mm": EDGE_MM, "ligament_mm": LIGAMENT_MM},
    "objective": {"measures": ["fov", "resolution", "resolvability"], "aggregate": "sum", "combine": "maxmin",
                  "rotation_length_mm": 50.0},
    "optimizer": {"method": "multistart", "starts": 2, "maxiter": 25},
    "robustness": {"robust": False},  # the nominal optimum: robust studies are tested in test_robust*.py
}


def no_report(monkeypatch: pytest.MonkeyPatch) -> None:
    """Skip the (slow, separately tested) report rendering in runs that check other things."""
    monkeypatch.setattr("cadfeat.study.run._report", lambda *a, **k: None)


def plate_study(name: str) -> dict:
    """A small study on ``study_plate.py`` (two movable holes, 12 poses of a straight approach, the four thesis
    measures, max-min), as a fresh dict: the scene of the design-layer tests (robustness, memory budget)."""
    return {
        "study": {"name": name, "part": str(PLATE), "seed": 7},
        "camera": {"preset": "realsense-d435-rgb", "focus_distance_mm": 200.0},
        "trajectory": {"kind": "straight_approach", "start": [-60.0, -80.0, 260.0], "end": [40.0, -40.0, 180.0],
                       "target": [0.0, 0.0, 6.0], "n": 12, "duration_s": 2.0},
        "design": {"parameters": {"x0": {"lower": -18.0, "upper": -4.0}, "y0": {"lower": -8.0, "upper": 12.0}}},
        "objective": {"measures": ["fov", "focus", "resolution", "resolvability"], "aggregate": "sum",
                      "combine": "maxmin", "rotation_length_mm": 50.0},
    }


def toml_value(v: object) -> str:
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return json.dumps(v)


def write_toml(path: Path, data: dict) -> Path:
    lines = []
    for section, table in data.items():
        lines.append(f"[{section}]")
        lines += [f"{k} = {toml_value(v)}" for k, v in table.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def study(tmp_path: Path, **changes: dict) -> Path:
    """The base study written to tmp_path/s.toml with section tables updated (None deletes a key)."""
    data = copy.deepcopy(BASE)
    for section, table in changes.items():
        if table is None:
            data.pop(section)
            continue
        data.setdefault(section, {})
        for k, v in table.items():
            if v is None:
                data[section].pop(k, None)
            else:
                data[section][k] = v
    (tmp_path / "study_plate.py").write_text(PLATE.read_text())
    return write_toml(tmp_path / "s.toml", data)


def compare_results_tool():
    """``tools/compare_results.py`` as a module (the tools folder is not a package)."""
    path = Path(__file__).resolve().parents[1] / "tools" / "compare_results.py"
    spec = importlib.util.spec_from_file_location("compare_results", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
