"""The study side of the closed loop: the [tracking] schema, ``cadfeat track`` and the report section.

``cadfeat track`` reads the designs a run exported (original.step, optimised.step); here those are written
directly (a plate with four clustered target holes and the same plate with them spread out — the known answer:
the spread one tracks better), so the test does not pay for an optimisation.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

cq = pytest.importorskip("cadquery")

from cadfeat.cli import main  # noqa: E402
from cadfeat.study.schema import StudyError, TrackingSpec, load_study  # noqa: E402
from tests.study_helpers import write_toml  # noqa: E402

PART = (Path(__file__).parents[1] / "data" / "spread_plate.py").read_text()
"""The test's part script (a spread of four through holes), written beside each study."""

STUDY = {
    "study": {"name": "spread", "part": "spread_plate.py", "seed": 2},
    "camera": {"fx": 420.0, "fy": 420.0, "cx": 160.0, "cy": 120.0, "width": 320, "height": 240,
               "focus_distance_mm": 300.0},
    "trajectory": {"kind": "orbit_arc", "centre": [0, 0, 2.5], "radius_mm": 300.0, "elevation_deg": 70.0,
                   "azimuth_start_deg": -110.0, "azimuth_end_deg": -70.0, "n": 10, "duration_s": 1.0},
    "design": {"parameters": ["spread_mm"]},
    "tracking": {"runs": 6, "settle_frames": 3, "initial_error_mm": 5.0, "initial_error_deg": 1.0,
                 "r_px2": 0.05, "q_rate_mm2_s2": 10.0, "q_omega_rad2_s2": 1e-4},
    "cell": {"noise_sigma_grey": 4.0},
}


def _study(tmp_path, **tracking):
    (tmp_path / "spread_plate.py").write_text(PART)
    data = json.loads(json.dumps(STUDY))
    data["tracking"].update(tracking)
    return write_toml(tmp_path / "spread.toml", data)


def test_tracking_section_is_validated(tmp_path):
    config = load_study(_study(tmp_path, estimators=["iekf", "pnp"]))
    assert isinstance(config.tracking, TrackingSpec) and config.tracking.estimators == ("iekf", "pnp")
    assert config.tracking.seed == 2 and config.tracking.runs == 6
    assert load_study(config.to_dict(), base_dir=tmp_path).tracking == config.tracking
    assert load_study(_study(tmp_path)).tracking.iterations == 30  # defaults fill the keys not given
    for key, value, allowed in (("estimators", ["ukf"], "ekf, iekf, pnp"), ("runs", 0, "integer"),
                                ("noise_grey", 1.0, "[cell] noise_sigma_grey"), ("rim_model", "yes", "true or false"),
                                ("nosie_grey", 1.0, "keys of [tracking]")):
        with pytest.raises(StudyError, match=rf"tracking\.{key}.*allowed: .*{re.escape(allowed)}"):
            load_study(_study(tmp_path, **{key: value}))


def _export(tmp_path):
    from cadfeat.cad.export import export_step

    out = tmp_path / "out"
    out.mkdir()
    ns: dict = {}
    exec(PART, ns)  # noqa: S102 - the test's own part script
    export_step(ns["build"](8.0).val(), out / "original.step")
    export_step(ns["build"](38.0).val(), out / "optimised.step")
    return out


def test_cadfeat_track_spread_holes_track_better(tmp_path, capsys):
    study = _study(tmp_path, estimators=["iekf", "pnp"])
    out = _export(tmp_path)
    (out / "results.json").write_text(json.dumps({"study": {"name": "spread"}}))
    assert main(["track", str(study), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "iekf: better" in text and "pnp: better" in text
    section = json.loads((out / "tracking" / "tracking.json").read_text())
    assert json.loads((out / "results.json").read_text())["tracking"] == section
    assert section["verdicts"]["iekf"]["verdict"] == "better"
    assert set(section["designs"]) == {"before", "after"}
    for design in section["designs"].values():  # holes named as everywhere else (issue 16), not hole0…
        names = list(design["detection_rate"])
        assert names == [f"H{i + 1}" for i in range(len(names))]
    for f in section["frames"]:
        assert (out / f["path"]).is_file()
    # the report section from results.json alone
    from cadfeat.report.tracking import tracking_section

    html = tracking_section({"tracking": section}, out, lambda p: str(p))
    assert "tracks better after the redesign" in html and "Wilcoxon" in html and (out / "img" /
                                                                                  "tracking_errors.png").is_file()
    assert tracking_section({}, out, str) == ""


def test_cadfeat_track_sweep_and_missing_outputs(tmp_path, capsys):
    study = _study(tmp_path, estimators=["ekf"], runs=2)
    assert main(["track", str(study), "--out", str(tmp_path / "nowhere")]) == 2
    assert "original.step not found" in capsys.readouterr().err
    out = _export(tmp_path)
    assert main(["track", str(study), "--out", str(out), "--sweep", "r", "--values", "0.05,5"]) == 0
    result = json.loads((out / "tracking" / "sweep_r.json").read_text())
    assert [r["value"] for r in result["rows"]] == [0.05, 5.0]
    assert (out / "tracking" / "sweep_r.png").is_file()
    assert not (out / "results.json").exists()


def test_a_sudden_roll_of_the_trajectory_is_reported():
    import numpy as np

    from cadfeat.poses import make_T
    from cadfeat.study.tracking import _motion_warnings
    from cadfeat.vision.motion import so3_exp

    angles = np.array([0.0, 0.1, 0.2, 2.8, 2.9])  # rad about the optical axis: a 147° jump between frames 2 and 3
    T = np.stack([make_T(so3_exp(np.array([0.0, 0.0, a])), [0.0, 0.0, 300.0]) for a in angles])
    warnings = _motion_warnings(T, np.arange(5) * 0.1)
    assert len(warnings) == 1 and "turns 149° between tracked frames 2 and 3" in warnings[0]
    assert _motion_warnings(T[:3], np.arange(3) * 0.1) == []


FLIPPED = PART.replace("PARAMETERS = {", "VIEW_DIRECTION = (0, 0, -1)  # mounted upside down: the camera sees -Z\n"
                                          "PARAMETERS = {", 1)


def test_track_uses_the_holes_run_tracked(tmp_path, monkeypatch):
    """One closed loop (issue 17): `cadfeat track` tracks the very holes `cadfeat run` tracked — same names,
    entrance centres and axes. The plate is mounted upside down (part script VIEW_DIRECTION = -Z, part pose
    rotated 180° about x): re-extracting the exported STEP without the view direction would put every through
    hole's entrance on the +Z face, which the camera never sees."""
    import numpy as np

    from cadfeat.study.run import run_study
    from cadfeat.vision import closed_loop

    seen: dict[str, dict] = {}

    def fake_track_designs(camera, T, times, screws, designs, config, **kw):  # records, tracks nothing
        seen[kind] = designs
        return closed_loop.BeforeAfter({}, {}, {}, config, np.arange(len(T)), {})

    monkeypatch.setattr(closed_loop, "track_designs", fake_track_designs)
    (tmp_path / "spread_plate.py").write_text(FLIPPED)
    data = json.loads(json.dumps(STUDY))
    data["part_pose"] = {"position_mm": [0, 0, 0], "rotvec_deg": [180.0, 0.0, 0.0]}
    data["optimizer"] = {"method": "multistart", "starts": 1}
    data["tracking"]["runs"] = 1
    study = write_toml(tmp_path / "flipped.toml", data)
    out = tmp_path / "out"
    kind = "run"
    run_study(study, out, quiet=True, progress=False)
    kind = "track"
    assert main(["track", str(study), "--out", str(out)]) == 0
    assert set(seen) == {"run", "track"}
    for design in ("before", "after"):
        ran, tracked = seen["run"][design][1], seen["track"][design][1]
        assert [h.name for h in tracked] == [h.name for h in ran] == [f"H{i + 1}" for i in range(4)]
        np.testing.assert_allclose([h.centre for h in tracked], [h.centre for h in ran], atol=1e-9)
        np.testing.assert_allclose([h.axis for h in tracked], [h.axis for h in ran], atol=1e-12)
        np.testing.assert_allclose([h.radius_mm for h in tracked], [h.radius_mm for h in ran], atol=1e-12)
        assert all(h.axis[2] < -0.99 for h in tracked)          # entrances on the side the camera sees
    # without results.json holes: extracted with the study's view direction, the same entrances
    results = json.loads((out / "results.json").read_text())
    results.pop("holes")
    (out / "results.json").write_text(json.dumps(results))
    assert main(["track", str(study), "--out", str(out)]) == 0
    np.testing.assert_allclose(sorted(map(tuple, [h.centre for h in seen["track"]["before"][1]])),
                               sorted(map(tuple, [h.centre for h in seen["run"]["before"][1]])), atol=1e-6)
