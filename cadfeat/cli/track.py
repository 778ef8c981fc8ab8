"""Sub-command ``cadfeat track STUDY``: does the new design track better? (closed loop, ``cadfeat.vision``).

Reads the designs a previous ``cadfeat run`` exported (``original.step``, ``optimised.step`` in the output
folder) with the holes that run tracked (results.json ``holes``: same names, entrances and view direction, so
``cadfeat track`` and ``cadfeat run`` give the same numbers; ``study.tracking.exported_designs``), renders
the camera images along the study trajectory, detects the holes and tracks the part pose with
the EKF, IEKF and solvePnP, before and after. Writes ``tracking/`` (tracking.json, frames with detected vs
predicted ellipses) and the ``tracking`` section of results.json; ``--sweep`` runs the thesis §6.3.3
sensitivity study instead (``tracking/sweep_<kind>.json`` and ``.png``).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from cadfeat.cell.defaults import DETECTORS, RENDERERS
from cadfeat.cli.command import Command
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import TrackingData
    from cadfeat.study.schema import StudyConfig, TrackingSpec

SWEEP_KINDS = ("initial_error", "q", "r", "focal_length", "sample_time")


def _track_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("study", metavar="STUDY", help="study file (TOML); its [tracking] section, or defaults")
    parser.add_argument("--out", metavar="DIR", help="the study's output folder (default: exports/<study name>/)")
    parser.add_argument("--runs", type=int, metavar="N", help="Monte-Carlo runs (overrides tracking.runs)")
    parser.add_argument("--sweep", choices=SWEEP_KINDS, help="thesis §6.3.3 sensitivity: vary one setting")
    parser.add_argument("--values", metavar="V,V,...", help="the sweep's values (default: a thesis-like range)")
    parser.add_argument("--renderer", choices=RENDERERS, help="raster (VTK, holes painted dark) or pbr (Mitsuba 3 "
                        "path tracer with the [cell] light and material); overrides tracking.renderer")
    parser.add_argument("--detector", choices=DETECTORS, help="cadfeat (rim edges), edcircles (OpenCV contrib) or "
                        "blob (SimpleBlobDetector); overrides cell.detector")
    parser.add_argument("--spp", type=int, metavar="N", help="pbr: samples per pixel (overrides tracking.spp)")
    parser.add_argument("--images", metavar="DIR", help="replay recorded images of the real part (frame_NNNN.png ...) "
                        "instead of rendering; needs --poses (cadfeat.vision.replay)")
    parser.add_argument("--poses", metavar="CSV", help="with --images: the robot's reported camera pose per image "
                        "(time_s,x,y,z mm,qx,qy,qz,qw or time_s and a 3x4 matrix per line)")
    parser.add_argument("--hand-eye", metavar="YAML", help="with --images: T_flange_cam (OpenCV FileStorage node T) "
                        "when the poses are the robot's flange")
    parser.add_argument("--design", choices=("original", "optimised"), default="optimised",
                        help="with --images: the design the recorded part has (default optimised)")


def _write_json(path: Path, data: Mapping[str, object]) -> None:
    from cadfeat.study.outputs import write_json  # lazy: keeps `cadfeat --help` fast

    tmp = path.with_name(path.name + ".tmp")
    write_json(tmp, data)
    tmp.replace(path)


def summary_lines(section: TrackingData) -> list[str]:
    """Console table: per design and estimator, RMS errors with intervals; the verdict per estimator."""
    lines = []
    for name, d in section["designs"].items():
        for m, e in d["estimators"].items():
            t, r = e["trans_mm_rms"], e["rot_deg_rms"]
            lines.append(f"  {name:<7} {m:<5} translation RMS {_f(t['mean'])} mm [{_f(t['ci_low'])}, "
                         f"{_f(t['ci_high'])}]   rotation RMS {_f(r['mean'])} deg [{_f(r['ci_low'])}, "
                         f"{_f(r['ci_high'])}]   lost {_f(e['frames_lost']['mean'])} frames"
                         + (f" ({_f(100 * lost)} % after settling, counted at the last estimate's error)"
                            if (lost := (e.get("lost_frac") or {}).get("mean")) else ""))
    for m, v in section.get("verdicts", {}).items():
        lines.append(f"  {m}: {v['verdict']} (Wilcoxon p = {_f(v['translation']['p_value'])} translation, "
                     f"{_f(v['rotation']['p_value'])} rotation; {v['translation']['runs']} paired runs)")
    return lines


def _f(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.3g}"


def track(args: argparse.Namespace) -> int:
    """Does the new design track better? Images → OpenCV detection → EKF/IEKF/PnP pose, before vs after."""
    from cadfeat.study.run import default_out_dir  # lazy: keeps `cadfeat --help` fast
    from cadfeat.study.schema import load_study
    from cadfeat.study.tracking import exported_designs, run_tracking, sweep

    config = load_study(args.study)
    spec = config.tracking_settings()
    if args.runs is not None:
        if args.runs < 1:
            raise CadfeatError(f"--runs: {args.runs} is not allowed; allowed: an integer >= 1")
        spec = spec.replace(runs=args.runs)
    config, spec = _with_overrides(config, spec, args)
    values = None
    if args.values:
        try:
            values = [float(v) for v in args.values.split(",")]
        except ValueError:
            raise CadfeatError(f"--values: {args.values!r} is not allowed; allowed: numbers separated by commas") \
                from None
    out = Path(args.out) if args.out else default_out_dir(config)
    if args.images or args.poses:
        from cadfeat.cli.recording import track_recorded  # lazy: keeps `cadfeat --help` fast

        return track_recorded(config, spec, out, args)
    designs = exported_designs(config, out)
    folder = out / "tracking"
    folder.mkdir(parents=True, exist_ok=True)
    if args.sweep:
        result = sweep(config, designs, args.sweep, values, spec)
        _write_json(folder / f"sweep_{args.sweep}.json", result)
        from cadfeat.report.tracking import sweep_plot

        sweep_plot(result, folder / f"sweep_{args.sweep}.png")
        print(f"tracking sweep {args.sweep} ({config.study.name}):")
        for row in result["rows"]:
            parts = [f"{d} {m} {_f(v['trans_mm_rms'])} mm/{_f(v['rot_deg_rms'])} deg"
                     for d in ("before", "after") for m, v in row.get(d, {}).items()]
            print(f"  {row['value']:g}: " + "; ".join(parts))
        print(f"  outputs: {folder / f'sweep_{args.sweep}.json'}, {folder / f'sweep_{args.sweep}.png'}")
        return 0
    if spec.renderer == "pbr":
        from cadfeat.study.tracking import pbr_announcement  # lazy: Mitsuba

        print(pbr_announcement(config, spec, designs))
    section = run_tracking(config, designs, out, spec)
    _write_json(folder / "tracking.json", section)
    results_path = out / "results.json"
    if results_path.is_file():  # written by `cadfeat run`: add (or replace) its tracking section
        results = json.loads(results_path.read_text(encoding="utf-8"))
        results["tracking"] = section
        if "verdict" in results:  # the tracking rule may change the decision
            from cadfeat.report.verdict import verdict_json

            results["verdict"] = verdict_json(results)
        _write_json(results_path, results)
    print(f"tracking {config.study.name}: {spec.runs} Monte-Carlo runs, {section['settings']['frames']} frames")
    print("\n".join(summary_lines(section)))
    for w in section.get("warnings", []):
        print(f"  warning: {w}")
    print(f"  outputs: {folder / 'tracking.json'}" + (f", {results_path} (tracking)" if results_path.is_file() else ""))
    return 0


def _with_overrides(config: StudyConfig, spec: TrackingSpec, args: argparse.Namespace
                    ) -> tuple[StudyConfig, TrackingSpec]:
    """The study and its ``[tracking]`` with the command line's ``--renderer``, ``--spp`` and ``--detector``."""
    import dataclasses

    if args.spp is not None and args.spp < 1:
        raise CadfeatError(f"--spp: {args.spp} is not allowed; allowed: an integer >= 1")
    changes = {k: v for k, v in (("renderer", args.renderer), ("spp", args.spp)) if v is not None}
    spec = spec.replace(**changes) if changes else spec
    if args.detector is not None:
        config = dataclasses.replace(config, cell=config.cell.replace(detector=args.detector))
    return config, spec


COMMANDS = (Command("track", _track_args, track),)
