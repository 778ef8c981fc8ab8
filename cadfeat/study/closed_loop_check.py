"""The closed-loop confirmation inside ``cadfeat run`` (issue 17): does the recommended design track better?

After the export, ``cadfeat run`` renders the original and the recommended design along the study's trajectory,
detects the holes and tracks the part pose (``study.tracking.run_tracking``, ``cadfeat.vision.closed_loop``),
and writes the results.json ``tracking`` section. The verdict's tracking rule is decisive
(``report.verdict``): an estimator that tracks significantly worse after the redesign makes the decision
"do not adopt", whatever the proxy objectives say.

Modes (``[tracking] check``, ``cadfeat run --track MODE`` / ``--no-track``):

- ``fast`` (the default for a study without a ``[tracking]`` table): PnP and the IEKF, ``FAST_RUNS`` paired
  Monte-Carlo runs on at most ``FAST_FRAMES`` frames of the trajectory (every k-th sample), statistics after
  ``FAST_SETTLE`` frames; the sensor, initial error and filter tuning are the study's ``[tracking]`` values
  (or the vision defaults). 8 runs is the fewest for which a two-sided Wilcoxon test can reach p < 0.01
  (2/2⁸ = 0.0078).
- ``full``: the study's ``[tracking]`` settings as they are (the default when the study has that table; what
  ``cadfeat track`` runs).
- ``pbr``: the fast check rendered physically (``[tracking] renderer = "pbr"``: Mitsuba 3 with the ``[cell]``'s
  light, material and hole ends; the time it takes is announced before it starts).
- ``off``: no closed loop (the verdict then rests on the proxies).

Precedence: the command line, then the study's ``check``, then the environment variable ``CADFEAT_TRACKING_CHECK``
(fast | full | off; read for studies without a ``[tracking]`` table only — the test suite sets it to ``off`` so
its many small studies stay fast), then the default above.

Where it runs: each design is tracked in a worker process (``start_design``; ``cad.sandbox.BackgroundCall``)
while the run goes on — the original from the end of the set-up, beside the optimiser (on one thread: the
optimiser has the other core), the recommended design from the end of its CAD rebuild, beside the analysis,
the export and the report's renders; ``closed_loop_check`` then only collects them (a worker that failed leaves
its design to this process). The numbers are those of the check run here (``CADFEAT_TRACKING_BACKGROUND=0``);
the cost on the flagship is in docs/guide/closed-loop.md ("Time budget") and ``benchmarks/bench_study.py``.

"Whenever the part can be rendered": the fast check is skipped — with a warning in results.json and the
printout, never an error after the optimisation — when fewer than ``MIN_HOLES`` holes exist (a pose needs at
least 3 points) or the renderer / detector fails (e.g. no off-screen OpenGL). A requested ``full`` check fails
loudly, as ``cadfeat track`` does.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.errors import CadfeatError
from cadfeat.study.schema import StudyConfig, StudyError, TrackingSpec
from cadfeat.study.settings.sections import CHECK_MODES

if TYPE_CHECKING:  # pragma: no cover
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.cad.sandbox import BackgroundCall
    from cadfeat.results import (
        EstimatorVerdictData,
        GlareCaveatData,
        JsonDict,
        PairedTestData,
        ResultsData,
        TrackingData,
    )
    from cadfeat.study.delivery import Delivery
    from cadfeat.study.progress import StudyProgress
    from cadfeat.study.tracking import Design, TrackArguments, Tracked

ENV = "CADFEAT_TRACKING_CHECK"
FAST_ESTIMATORS = ("pnp", "iekf")
FAST_RUNS = 8
FAST_FRAMES = 20
FAST_SETTLE = 3
MIN_HOLES = 3
SKIPPED = "closed-loop check skipped"
TRACKED_MIN = 0.5
BACKGROUND_ENV = "CADFEAT_TRACKING_BACKGROUND"
BACKGROUND_WAIT_S = 3600.0
#: With added target holes (``[add_targets]``, issue 31) the delivered design ("after") is the move-only optimum
#: with the holes drilled; the move-only optimum is tracked too, in the same paired runs, and compared both ways.
ADDED_PAIRS = {"move_only_vs_original": ("before", "move_only"), "added_vs_move_only": ("move_only", "after")}


def with_mode(config: StudyConfig, mode: str | None) -> StudyConfig:
    """``config`` with ``[tracking] check = mode`` (the command line's ``--track``/``--no-track``); None keeps it."""
    if mode is None:
        return config
    if mode not in CHECK_MODES:
        raise StudyError(f"{config.label}: --track {mode!r} is not allowed; allowed: {', '.join(CHECK_MODES)}")
    return dataclasses.replace(config, tracking=config.tracking_settings().replace(check=mode))


def check_mode(config: StudyConfig) -> str:
    """The mode this run uses (module docstring: precedence)."""
    spec = config.tracking
    if spec is not None and spec.check is not None:
        return spec.check
    if spec is not None:
        return "full"
    env = os.environ.get(ENV, "").strip().lower()
    if env and env not in CHECK_MODES:
        raise StudyError(f"environment variable {ENV}={env!r} is not allowed; allowed: {', '.join(CHECK_MODES)}")
    return env or "fast"


def fast_spec(config: StudyConfig, n_samples: int) -> TrackingSpec:
    """The fast check's settings: the study's sensor/tuning with PnP + IEKF, ``FAST_RUNS`` runs, at most
    ``FAST_FRAMES`` frames and ``FAST_SETTLE`` settling frames (fewer when the trajectory is short)."""
    base = config.tracking_settings()
    step = max(base.frame_step, math.ceil(n_samples / FAST_FRAMES))
    frames = len(range(0, n_samples, step))
    return base.replace(estimators=FAST_ESTIMATORS, runs=FAST_RUNS, frame_step=step,
                        settle_frames=max(0, min(base.settle_frames, FAST_SETTLE, frames - 3)))


def attach(config: StudyConfig, results: ResultsData, delivery: Delivery, stage: Path | None,
           progress: StudyProgress | None = None) -> None:
    """Run this study's closed-loop check and put it into ``results``: the ``tracking`` section (with a ``check``
    block: mode, runs, frames, estimators, seconds), nothing when the mode is ``off``, or a ``warnings`` line
    saying why it was skipped. ``delivery``: ``pipeline.compute``'s (shape0/holes0 the original, shape1/holes1 the
    recommended design, setup, the workers); ``stage``: the output folder (the frames' PNGs)."""
    section, skipped = closed_loop_check(config, delivery, stage, progress)
    if section is not None:
        results["tracking"] = section
        check = section.get("check")
        caveat = None if check is None else glare_caveat(config, delivery, check["mode"],
                                                         section["settings"].get("renderer"))
        if check is not None and caveat is not None:
            check["glare"] = caveat
            results["warnings"].append(caveat["warning"])
    if skipped:
        results["warnings"].append(skipped)
    views, why = camera_views(config, delivery, stage, progress)
    if views is not None:
        results["physical_views"] = views
    if why:
        results["warnings"].append(why)


#: A hole is named by ``glare_caveat`` when g_POSE's glare factor is below ``GLARE_RATE`` at ``GLARE_SHARE`` or more
#: of the study's poses where it faces the camera (its axis within ``FACING_DEG`` of the line of sight).
GLARE_RATE = 0.5
GLARE_SHARE = 0.1
FACING_DEG = 75.0


def glare_caveat(config: StudyConfig, delivery: Delivery, mode: str, renderer: str | None
                 ) -> GlareCaveatData | None:
    """What the raster check cannot see (issue 28): the raster renderer paints every bore dark, so in a metal cell
    (``cell.material.bores_return_light``) a blind rim the part's own light leaves without contrast
    (``measures.glare``: g_POSE's factor on its detection rate, from the set-up's physically based maps) is
    found there all the same. Returns, for a raster check whose designs have such holes, ``{"holes": {design:
    {hole: share of the facing poses with factor < GLARE_RATE}}, "warning": one line}`` naming them and the
    physically based check that sees them; None otherwise (a PBR check, plastics, through holes, ``[cell] glare
    = false``, no maps)."""
    from cadfeat.cell.material import bores_return_light

    problem = delivery.setup.problem
    maps = problem.glare
    if renderer == "pbr" or maps is None or not bores_return_light(config.cell.material):
        return None
    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.design.pose_terms import designs_glare_rate
    from cadfeat.measures.visibility import facing_margin
    from cadfeat.poses import points_in_frames, rotate_vectors

    T = np.asarray(problem.T_cam_part, float)
    if maps.n_poses != len(T):
        return None
    found: dict[str, dict[str, float]] = {}
    for label, (_, holes) in _designs(delivery).items():
        c, a, r = holes_to_arrays(list(holes))
        through = np.array([bool(h.through) for h in holes])
        rate = designs_glare_rate(maps, config.cell, T, c[None], a[None], np.asarray(r, float)[None], through,
                                  config.cell.noise_sigma_grey)
        if rate is None:
            return None
        facing = facing_margin(points_in_frames(T, c), rotate_vectors(T[:, None], a)) > np.cos(np.radians(FACING_DEG))
        share = np.sum(facing & (rate < GLARE_RATE), axis=0) / np.maximum(np.sum(facing, axis=0), 1)
        named = {h.name or f"hole {j + 1}": round(float(share[j]), 3) for j, h in enumerate(holes)
                 if share[j] >= GLARE_SHARE}
        if named:
            found[label] = named
    if not found:
        return None
    what = "; ".join(f"{DESIGN_WORDS.get(k, k)}: {', '.join(f'{h} ({100 * v:.0f} %)' for h, v in d.items())}"
                     for k, d in found.items())
    warning = (f"the {mode} check renders bores dark, but in this {config.cell.material.name} cell the part's own "
               f"light leaves these blind rims without contrast at the share of poses given ({what}): the raster "
               "verdict cannot see it; confirm under physical light with `cadfeat run --track pbr` or `cadfeat "
               "track --renderer pbr`")
    return {"holes": found, "warning": warning}


DESIGN_WORDS = {"before": "original", "after": "recommended", "move_only": "move-only"}


def camera_views(config: StudyConfig, delivery: Delivery, stage: Path | None,
                 progress: StudyProgress | None = None) -> tuple[JsonDict | None, str | None]:
    """(results.json ``physical_views``: both designs rendered physically at three poses, detections drawn and
    misses named — ``study.physical_views`` —, or None; why they are missing, or None). Made whenever the check
    is on; a renderer that fails leaves a warning (an error in mode ``pbr``, which asked for physics by name)."""
    from cadfeat.study.physical_views import physical_views  # lazy: Mitsuba

    mode, spec = check_spec(config, len(delivery.setup.trajectory.times_s))
    if spec is None or min(len(delivery.holes0), len(delivery.holes1)) < MIN_HOLES:
        return None, None
    designs = {"before": (delivery.shape0, delivery.holes0), "after": (delivery.shape1, delivery.holes1)}
    try:
        with progress.phase("camera views") if progress is not None else contextlib.nullcontext():
            return physical_views(config, designs, stage, spec), None
    except (CadfeatError, ImportError, RuntimeError, OSError, ValueError) as exc:
        if mode == "pbr":
            raise
        return None, f"no physically rendered camera views ({type(exc).__name__}: {exc})"


def check_spec(config: StudyConfig, n_samples: int) -> tuple[str, TrackingSpec | None]:
    """(mode, the tracking settings the check runs with; None when the mode is ``off``)."""
    mode = check_mode(config)
    if mode == "off":
        return mode, None
    if mode == "full":
        return mode, config.tracking_settings()
    if mode == "pbr":
        return mode, fast_spec(config, n_samples).replace(renderer="pbr")
    return mode, fast_spec(config, n_samples)


def start_design(config: StudyConfig, name: str, shape: Shape, holes: Sequence[Hole], n_samples: int
                 ) -> BackgroundCall[Tracked] | None:
    """Start tracking one design (``shape``, ``holes``; ``name`` "before" or "after") in a worker process, so
    that the check runs on another core while this process goes on: the original while the optimiser runs,
    the recommended design during the analysis, export and the report's renders (neither depends on what this
    process does meanwhile). None when there is nothing to track (mode ``off``, too few holes),
    ``CADFEAT_TRACKING_BACKGROUND=0``, or the worker cannot start (the check then tracks the design itself). Its
    numbers are those the check computes in this process (``closed_loop.track_one`` of
    ``tracking.track_arguments``; tests/study/test_closed_loop_check.py)."""
    from cadfeat.cad.sandbox import BackgroundCall
    from cadfeat.study.tracking import track_arguments

    _, spec = check_spec(config, n_samples)
    if spec is None or len(holes) < MIN_HOLES or os.environ.get(BACKGROUND_ENV, "1").strip() == "0":
        return None
    threads = 1 if name == "before" else None  # beside the optimiser (one core): the renderer and OpenCV on one
    try:
        what = DESIGN_WORDS.get(name, "recommended")
        return BackgroundCall(_track_design, (threads, track_arguments(config, spec, (shape, list(holes)))),
                              f"the closed loop of the {what} design")
    except Exception:  # noqa: BLE001 - an optimisation: the check then runs here, where errors are reported
        return None


def _track_design(threads: int | None, arguments: TrackArguments) -> Tracked:
    """In a worker: ``closed_loop.track_one(*arguments)`` with the software renderer (llvmpipe,
    ``LP_NUM_THREADS``, read when the worker's OpenGL context is made), OpenCV and Mitsuba's Dr.Jit on ``threads``
    threads (None: theirs); the images and numbers do not depend on it (tests/study/test_closed_loop_check.py)."""
    if threads is not None:
        import cv2

        os.environ["LP_NUM_THREADS"] = str(threads)
        cv2.setNumThreads(threads)
        _drjit_threads(threads)
    from cadfeat.vision.closed_loop import track_one  # lazy: scipy.optimize

    return track_one(*arguments)


def _drjit_threads(threads: int) -> None:
    """Mitsuba's LLVM back end (Dr.Jit) on ``threads`` threads in this worker, when it is installed: a physically
    based check beside the optimiser would otherwise take every core (the flagship's optimiser ran 3× slower)."""
    try:
        import drjit
    except ImportError:
        return
    drjit.set_thread_count(threads)


def _collect(pending: Mapping[str, BackgroundCall[Tracked] | None], progress: StudyProgress | None
             ) -> dict[str, Tracked]:
    """{design name: its worker's tracking} for the workers ``start_design`` started that delivered (a design
    whose worker failed is tracked here by the check, where a failure is reported as the check reports it)."""
    out: dict[str, Tracked] = {}
    for name, call in pending.items():
        if call is None:
            continue
        try:
            out[name] = call.result(BACKGROUND_WAIT_S)
        except CadfeatError as exc:
            if progress is not None:
                progress.log(f"{exc}; tracking it in this process")
    return out


def _designs(delivery: Delivery) -> dict[str, Design]:
    """The designs the check tracks: "before" (the original) and "after" (the delivered design), and
    "move_only" (the move-only optimum) when the delivered design has added target holes."""
    return delivery.designs()


def closed_loop_check(config: StudyConfig, delivery: Delivery, stage: Path | None,
                      progress: StudyProgress | None = None) -> tuple[TrackingData | None, str | None]:
    """(the results.json ``tracking`` section or None, why it was skipped or None) — ``attach``. The designs
    ``delivery.workers`` track are not tracked again here (a worker that failed leaves its design to this
    process); the workers are collected or cancelled."""
    from cadfeat.study.tracking import run_tracking  # lazy: would import scipy.optimize at module load

    mode, spec = check_spec(config, len(delivery.setup.trajectory.times_s))
    designs = _designs(delivery)
    few = min(len(holes) for _, holes in designs.values())
    if spec is None:
        delivery.workers.cancel()
        return None, None
    if mode in ("fast", "pbr") and few < MIN_HOLES:
        delivery.workers.cancel()
        return None, f"{SKIPPED}: the part has {few} hole(s); a pose needs at least {MIN_HOLES}"
    if spec.renderer == "pbr" and progress is not None:
        from cadfeat.study.tracking import pbr_announcement  # lazy: Mitsuba

        progress.log(pbr_announcement(config, spec, designs))
    t0, c0 = time.perf_counter(), time.process_time()
    pending = delivery.workers.pending(designs)
    try:
        with _phase(progress):
            section = run_tracking(config, designs, stage, spec, tracked=_collect(pending, progress),
                                   pairs=ADDED_PAIRS if "move_only" in designs else None)
    except (CadfeatError, ImportError, RuntimeError, OSError, ValueError) as exc:
        if mode in ("full", "pbr"):  # asked for by name: fail loudly
            raise
        return None, f"{SKIPPED}: the part could not be rendered and tracked ({type(exc).__name__}: {exc})"
    section["check"] = {"mode": mode, "runs": spec.runs, "frames": section["settings"]["frames"],
                        "estimators": list(spec.estimators), "seconds": round(time.perf_counter() - t0, 2),
                        "cpu_seconds": round(time.process_time() - c0, 2),
                        "in_worker": sorted(k for k, v in pending.items() if v is not None)}
    _inconclusive(section)
    return section, None


def _inconclusive(section: TrackingData) -> None:
    """When neither design is tracked — at least 3 holes detected in fewer than ``TRACKED_MIN`` of the frames of
    both (e.g. holes a few pixels wide in a small sensor's image) — the paired test compares two failures: its
    verdicts are kept under ``check.verdicts_not_used`` and the verdict's tracking rule stays silent (a warning
    says why). One design tracked and the other not is a real difference and stays decisive."""
    frames = max(int(section["settings"]["frames"]), 1)
    tracked = {k: 1.0 - float(d.get("frames_under_3_holes") or 0.0) / frames for k, d in section["designs"].items()}
    if tracked and max(tracked.values()) < TRACKED_MIN and section.get("verdicts"):
        if "check" in section:
            section["check"]["verdicts_not_used"] = section["verdicts"]
        section["verdicts"] = {}
        for c in section.get("comparisons", {}).values():
            c["verdicts_not_used"], c["verdicts"] = c["verdicts"], {}
        share = ", ".join(f"{k} {100 * v:.0f} %" for k, v in tracked.items())
        section.setdefault("warnings", []).append(
            f"the closed loop detects 3 or more holes in too few frames of either design (frames tracked: {share}; "
            f"needed: {100 * TRACKED_MIN:.0f} %): no tracking verdict (the holes are too small or hidden in this "
            "camera's images)")


def _phase(progress: StudyProgress | None) -> contextlib.AbstractContextManager[object]:
    return progress.phase("tracking") if progress is not None else contextlib.nullcontext()


def summary_lines(results: ResultsData) -> list[str]:
    """The printout's lines about the closed loop (``run.summarise``): mode, cost and each estimator's paired
    verdict with its p-values, or why it was skipped / that it was off."""
    tr = results.get("tracking")
    if tr is None:
        if any(str(w).startswith(SKIPPED) for w in results.get("warnings", [])):
            return []  # the warning line says why
        return ["  closed loop: off (the verdict rests on the predicted objectives; `cadfeat run --track fast` "
                "or `cadfeat track` confirms it)"]
    check = tr.get("check")
    mode, runs, frames, seconds = (("full", "?", "?", "?") if check is None else
                                   (check["mode"], check["runs"], check["frames"], check["seconds"]))
    head = (f"  closed loop ({mode}: {runs} paired runs, {frames} frames, {seconds} s), "
            + ("the delivered design (with the added holes) vs the original:" if tr.get("comparisons")
               else "after vs before:"))
    lines = [head] + [f"    WARNING: {w}" for w in tr.get("warnings", []) if "no tracking verdict" in str(w)]
    for m, v in tr["verdicts"].items():
        rms = _rms(tr, m)
        lines.append(f"    {m.upper():<5} {_verdict_line(v)}{rms}")
    for label, c in tr.get("comparisons", {}).items():
        lines.append(f"  closed loop, {COMPARISON_TEXT.get(label, label)}:")
        for m, v in c["verdicts"].items():
            lines.append(f"    {m.upper():<5} {_verdict_line(v)}{_rms(tr, m, c['before'], c['after'])}")
    return lines


def _verdict_line(v: EstimatorVerdictData) -> str:
    """'better (translation p = 0.0078, rotation p = 0.02)'."""
    return f"{v['verdict']} (translation p = {_p(v['translation'])}, rotation p = {_p(v['rotation'])})"


#: How the printout and the report name the comparisons of ``ADDED_PAIRS``.
COMPARISON_TEXT = {"move_only_vs_original": "the move-only optimum vs the original",
                   "added_vs_move_only": "the delivered design (with the added holes) vs the move-only optimum"}


def _p(v: PairedTestData) -> str:
    """'0.0078', with ' (change under 5 %)' when significant but too small to count (``metrics.paired_verdict``)."""
    p = v.get("p_value")
    if p is None:
        return "n/a"
    small = p < v.get("alpha", 0.05) and v.get("verdict") == "no significant difference"
    return f"{p:.2g}" + (f" (change under {100 * v.get('min_change', 0.0):.0f} %)" if small else "")


def _rms(tr: TrackingData, m: str, before: str = "before", after: str = "after") -> str:
    """'; RMS 0.039 → 0.034 mm, 0.027° → 0.027°' from the designs' Monte-Carlo means."""
    try:
        b, a = (tr["designs"][k]["estimators"][m] for k in (before, after))
        return (f"; RMS {b['trans_mm_rms']['mean']:.4f} → {a['trans_mm_rms']['mean']:.4f} mm, "
                f"{b['rot_deg_rms']['mean']:.4f}° → {a['rot_deg_rms']['mean']:.4f}°")
    except (KeyError, TypeError):
        return ""
