"""cadfeat run's closed-loop check (``study.closed_loop_check``, issue 17): on by default, fast, and decisive.

The decisive case is built from the physics, not patched in: a plate whose four target holes grow *and* huddle
together as one parameter rises (``size_mm``). The study optimises the image resolution alone (g_RES: larger
holes are better), so the optimiser picks the largest, most clustered holes; four points 8 mm apart constrain the
pose far less than the original's 24 mm spread (the closed loop's own rendered images and detector say so), and
the verdict must then be "do not adopt" although every proxy objective improved.
"""

from __future__ import annotations

import json

import pytest

cq = pytest.importorskip("cadquery")

from cadfeat.errors import CadfeatError  # noqa: E402
from cadfeat.study import closed_loop_check as clc  # noqa: E402
from cadfeat.study.schema import StudyError, load_study  # noqa: E402
from tests.study_helpers import write_toml  # noqa: E402

PART = '''PARAMETERS = {"size_mm": {"default": 1.5, "bounds": (1.5, 2.5), "unit": "mm",
                           "description": "target hole radius; the holes huddle together as they grow"}}


def build(size_mm=1.5):
    import cadquery as cq

    s = 48.0 - 16.0 * size_mm          # half spread: 24 mm at r 1.5, 8 mm at r 2.5
    pts = [(-s, -0.75 * s), (s, -0.75 * s), (s, 0.75 * s), (-s, 0.75 * s)]
    return cq.Workplane("XY").box(100, 80, 5).faces(">Z").workplane().pushPoints(pts).hole(3 * size_mm + 1)
'''

STUDY = {
    "study": {"name": "huddle", "part": "huddle_plate.py", "seed": 3},
    "camera": {"fx": 420.0, "fy": 420.0, "cx": 160.0, "cy": 120.0, "width": 320, "height": 240,
               "focus_distance_mm": 300.0},
    "trajectory": {"kind": "orbit_arc", "centre": [0, 0, 2.5], "radius_mm": 300.0, "elevation_deg": 70.0,
                   "azimuth_start_deg": -110.0, "azimuth_end_deg": -70.0, "n": 10, "duration_s": 1.0},
    "design": {"parameters": ["size_mm"]},
    "objective": {"measures": ["resolution"]},
    "optimizer": {"method": "multistart", "starts": 1, "maxiter": 10},
    "shop": {"hole_sizes": [5.5, 6.0, 7.0, 8.0, 8.5]},
    "tracking": {"check": "fast", "initial_error_mm": 5.0, "initial_error_deg": 1.0,
                 "r_px2": 0.05, "q_rate_mm2_s2": 10.0, "q_omega_rad2_s2": 1e-4},
    "cell": {"noise_sigma_grey": 4.0},
}


def _study(tmp_path, **tracking):
    (tmp_path / "huddle_plate.py").write_text(PART)
    data = json.loads(json.dumps(STUDY))
    data["tracking"].update(tracking)
    return write_toml(tmp_path / "huddle.toml", data)


def _run(tmp_path, out):
    from cadfeat.cli import main

    assert main(["run", str(_study(tmp_path)), "--out", str(out), "--quiet"]) == 0
    return json.loads((out / "results.json").read_text())


def test_run_confirms_by_the_closed_loop_and_the_verdict_rejects(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv(clc.BACKGROUND_ENV, raising=False)  # the default: both designs tracked in workers
    results = _run(tmp_path, tmp_path / "out")
    text = capsys.readouterr().out
    assert results["tracking"]["check"]["in_worker"] == ["after", "before"]
    monkeypatch.setenv(clc.BACKGROUND_ENV, "0")  # the same check, every design tracked in this process
    here = _run(tmp_path, tmp_path / "here")
    assert here["tracking"]["check"]["in_worker"] == []
    for key in ("designs", "verdicts", "curves", "settings"):  # the workers' numbers are this process's, exactly
        assert results["tracking"][key] == here["tracking"][key], key
    variables = {v["name"]: v for v in results["variables"]}
    assert variables["size_mm"]["after"] > 2.2  # the proxy (resolution) drove the holes together
    assert results["objectives"]["after"]["g_RES"] > results["objectives"]["before"]["g_RES"]
    tr = results["tracking"]
    assert tr["check"]["mode"] == "fast" and tr["check"]["runs"] == clc.FAST_RUNS
    assert tr["settings"]["estimators"] == ["pnp", "iekf"] and tr["settings"]["frames"] <= clc.FAST_FRAMES
    for design in tr["designs"].values():  # the Monte-Carlo runs differ (a paired test on real variability)
        assert design["detection_rate"] and min(design["detection_rate"].values()) > 0.5  # seen, only clustered
        e = design["estimators"]["pnp"]["trans_mm_rms"]
        assert e["ci_high"] - e["ci_low"] > 1e-3 * e["mean"]
    worse = [m for m, v in tr["verdicts"].items() if v["verdict"] == "worse"]
    assert worse, tr["verdicts"]
    for m in worse:  # the clustered holes track worse: after's RMS error above before's
        b, a = (tr["designs"][k]["estimators"][m] for k in ("before", "after"))
        assert a["trans_mm_rms"]["mean"] + a["rot_deg_rms"]["mean"] > b["trans_mm_rms"]["mean"] + \
            b["rot_deg_rms"]["mean"]
    verdict = results["verdict"]
    assert verdict["decision"] == "do not adopt"
    assert any(f["rule"] == "tracking" and f["outcome"] == "do not adopt" for f in verdict["findings"])
    assert "closed loop (fast: 8 paired runs" in text and "worse (translation p = " in text
    assert "verdict: do not adopt" in text
    html = (tmp_path / "out" / "report.html").read_text()
    assert "fast closed-loop check" in html
    # one closed loop: the public API tracks the delivered design (a parameter dict) with the run's numbers
    from cadfeat.study import track_design

    values = {v["name"]: v["after"] for v in results["variables"]}
    tracked = track_design(_study(tmp_path), values)
    for key in ("designs", "verdicts", "settings"):
        assert tracked[key] == results["tracking"][key], key
    with pytest.raises(StudyError, match="unknown \\[tracking\\] key\\(s\\) run; allowed: .*runs"):
        track_design(_study(tmp_path), values, run=3)
    user = tmp_path / "user"  # a folder cadfeat did not create: its frames are not written over the user's files
    (user / "tracking").mkdir(parents=True)
    (user / "tracking" / "after_frame_000.png").write_bytes(b"the user's")
    with pytest.raises(CadfeatError, match="holds files cadfeat did not write"):
        track_design(_study(tmp_path), values, out_dir=user)
    assert (user / "tracking" / "after_frame_000.png").read_bytes() == b"the user's"
    drawn = track_design(_study(tmp_path), values, out_dir=tmp_path / "frames")
    assert drawn["frames"] and all((tmp_path / "frames" / f["path"]).is_file() for f in drawn["frames"])


def test_mode_precedence_and_fast_settings(tmp_path, monkeypatch):
    """The command line, then [tracking] check, then a [tracking] table (full), then the environment, then fast."""
    with_table = load_study(_study(tmp_path, check="off"))
    assert clc.check_mode(with_table) == "off"
    assert clc.check_mode(clc.with_mode(with_table, "full")) == "full"
    data = json.loads(json.dumps(STUDY))
    data["tracking"].pop("check")
    (tmp_path / "huddle_plate.py").write_text(PART)
    assert clc.check_mode(load_study(write_toml(tmp_path / "t.toml", data))) == "full"
    del data["tracking"]
    bare = load_study(write_toml(tmp_path / "b.toml", data))
    monkeypatch.delenv(clc.ENV, raising=False)
    assert clc.check_mode(bare) == "fast"
    monkeypatch.setenv(clc.ENV, "off")
    assert clc.check_mode(bare) == "off" and clc.check_mode(clc.with_mode(bare, "fast")) == "fast"
    monkeypatch.setenv(clc.ENV, "sometimes")
    with pytest.raises(StudyError, match="CADFEAT_TRACKING_CHECK.*allowed: fast, full, off"):
        clc.check_mode(bare)
    with pytest.raises(StudyError, match=r"tracking\.check.*allowed: one of fast, full, off"):
        load_study(_study(tmp_path, check="quick"))
    spec = clc.fast_spec(bare, 40)  # every 2nd of 40 samples: 20 frames
    assert spec.frame_step == 2 and len(range(0, 40, spec.frame_step)) <= clc.FAST_FRAMES
    assert spec.runs == clc.FAST_RUNS and spec.estimators == ("pnp", "iekf") and spec.seed == 3
    assert clc.fast_spec(bare, 5).settle_frames == 2  # a short trajectory keeps 3 frames to score


def test_no_track_turns_the_check_off(tmp_path, monkeypatch):
    from cadfeat.cli import build_parser

    args = build_parser().parse_args(["run", "s.toml", "--no-track"])
    assert args.track == "off"
    assert build_parser().parse_args(["run", "s.toml", "--track", "full"]).track == "full"
    assert clc.summary_lines({"warnings": []})[0].startswith("  closed loop: off")


def test_two_untracked_designs_give_no_verdict():
    """Holes never seen in either design (a small sensor): the paired test would compare two failures — no
    tracking verdict, a warning; one design tracked and the other not stays decisive."""
    def section(under_before, under_after):
        return {"settings": {"frames": 20}, "verdicts": {"iekf": {"verdict": "worse"}}, "check": {}, "warnings": [],
                "designs": {"before": {"frames_under_3_holes": under_before},
                            "after": {"frames_under_3_holes": under_after}}}

    s = section(20.0, 18.0)
    clc._inconclusive(s)
    assert s["verdicts"] == {} and s["check"]["verdicts_not_used"]["iekf"]["verdict"] == "worse"
    assert "no tracking verdict" in s["warnings"][0] and "after 10 %" in s["warnings"][0]
    s = section(0.0, 20.0)  # the redesign hides the holes: a real "worse"
    clc._inconclusive(s)
    assert s["verdicts"]["iekf"]["verdict"] == "worse" and not s["warnings"]
