"""Study progress display: phases are timed (results.json timings_s), nested phases work, the optimiser's
history entries are accepted, and the display can be switched off."""

from __future__ import annotations

import time

import numpy as np

from cadfeat.study.progress import StudyProgress


def test_phases_timed_and_nested(capsys):
    with StudyProgress("demo", enabled=True) as prog:
        with prog.phase("export"):
            time.sleep(0.02)
            with prog.phase("report"):
                time.sleep(0.01)
                prog.iteration({"iteration": 0, "f": -1.0, "phase": "local", "feasible": True})
        with prog.phase("export"):  # accumulated
            time.sleep(0.01)
    assert prog.timings["report"] >= 0.01
    assert prog.timings["export"] >= 0.04 - 1e-3
    assert prog.timings["total"] >= prog.timings["export"]
    assert "demo" in capsys.readouterr().err


def test_iteration_keeps_best_feasible_design():
    prog = StudyProgress("quiet", enabled=False)
    with prog:
        prog.iteration({"x": [1.0], "f": 2.0})
        prog.iteration({"x": [2.0], "f": 1.0, "feasible": False})  # infeasible: not kept
        prog.iteration(np.array([3.0]), 1.5)  # positional (x, f)
    assert prog.best_f == 1.5 and prog.best_x.tolist() == [3.0] and prog.iterations == 3
