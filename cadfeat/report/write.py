"""Assemble report.html: summary, renders, tables, plots and provenance; images beside it in ``img/``.

The page is self-contained (inline CSS, images embedded as data URIs, also written to ``img/``) and opens
from the file system without a server or network. A section whose data is absent is left out; a section
that fails on malformed data is replaced by a note and a logged warning: writing the report never stops a
study.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from cadfeat.errors import CadfeatError
from cadfeat.report import tables, trust
from cadfeat.report.added_targets import added_targets_section
from cadfeat.report.context import ReportContext
from cadfeat.report.holes import hole_table
from cadfeat.report.html import Relative, data_uri, esc, figure, fmt, note, page, section
from cadfeat.report.patterns import patterns_section
from cadfeat.report.plots import Plot, make_plots
from cadfeat.report.pose import pose_section
from cadfeat.report.renders import Renders, make_renders
from cadfeat.report.requirements import requirements_table
from cadfeat.report.robust_designs import robust_designs_section
from cadfeat.report.robustness import robustness_section
from cadfeat.report.tracking import physical_views_section, tracking_section
from cadfeat.report.verdict import verdict_section
from cadfeat.report.view3d import view3d_section
from cadfeat.results import StudyRecord, value
from cadfeat.results import section as typed_section

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import JsonDict

log = logging.getLogger(__name__)

REPORT_NAME = "report.html"
IMG_DIR = "img"


@dataclass
class ReportOutput:
    """What ``build_report`` wrote: the page, its images, notes, and the time per phase (s)."""

    path: Path
    images: list[Path] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    timings_s: dict[str, float] = field(default_factory=dict)


def write_report(out_dir: str | Path, results: JsonDict, context: ReportContext | None = None) -> Path:
    """Write ``out_dir/report.html`` (images in ``out_dir/img/``) for a study's results; returns its path.

    ``results`` has the keys of results.json (contracts.md); ``context`` holds the shapes, holes, camera
    and trajectory for the renders (without it the report has no renders, only a note).
    """
    return build_report(out_dir, results, context).path


def report_renders(out_dir: str | Path, results: JsonDict, context: ReportContext | None) -> Renders:
    """The report's renders (``make_renders`` into ``out_dir/img``) on their own, for ``build_report``'s
    ``renders``: they need the designs and their measures, not the closed loop."""
    results, context = _single_design(results, context)
    return make_renders(context, results, Path(out_dir) / IMG_DIR)


def problem_line(exc: Exception) -> str:
    """One line saying what is wrong with a results.json section: for a pydantic ``ValidationError`` the first
    error's dotted key (the section's record, then the keys inside it), the value found and what was expected (not
    pydantic's multi-line dump with its link); otherwise the exception's type and first line."""
    from pydantic import ValidationError

    if isinstance(exc, ValidationError) and exc.errors():
        err = exc.errors()[0]
        key = ".".join([exc.title, *(str(x) for x in err["loc"])])
        value = repr(err.get("input"))
        value = value if len(value) <= 60 else value[:57] + "..."
        expected = str(err["msg"]).removeprefix("Input should be ")
        return f"{key}: {value} is not allowed; expected: {expected}"
    return f"{type(exc).__name__}: {exc}".splitlines()[0]


def read_results(path: str | Path) -> dict:
    """Read a results.json; a missing or malformed file raises CadfeatError naming it."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CadfeatError(f"{path}: results file not found (written by `cadfeat run` as results.json)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CadfeatError(f"{path}: not a readable JSON results file: {exc}") from None
    if not isinstance(data, dict):
        raise CadfeatError(f"{path}: a results file holds a JSON object (keys study, measures, ...), "
                           f"got {type(data).__name__}")
    return data


def build_report(out_dir: str | Path, results: JsonDict, context: ReportContext | None = None, *,
                 parallel: bool | None = None, self_contained: bool = True,
                 renders: Renders | None = None) -> ReportOutput:
    """``write_report`` that also returns the images, notes and the time of each phase (s).

    ``parallel`` (default: off unless ``CADFEAT_REPORT_PARALLEL=1``): when there are renders, draw the plots
    meanwhile in a child process (``python -m cadfeat.report.plots``; if that fails they are drawn here).
    Off by default: with software OpenGL (llvmpipe, no GPU) the renders already use the cores; on the 2-core
    test machine bench_report measured 6 % less wall time when idle (1.71 s vs 1.83 s) but more under load.
    ``self_contained`` (default True): images embedded as data URIs, so report.html is one file that can be
    mailed; the PNGs are written to ``img/`` all the same (False: the page links them).
    ``timings_s``: "renders" (with "renders: part"/"renders: views"), "plots" (drawing time, wherever it ran),
    "plots: wait" (time spent waiting for the child after the renders), "html", "total" (wall).
    ``renders``: ``report_renders``'s images, made earlier (``cadfeat run`` renders them while the closed loop
    runs in its workers); None renders them here.
    """
    t0 = time.perf_counter()
    results, context = _single_design(results, context)
    out_dir = Path(out_dir)
    img_dir = out_dir / IMG_DIR
    img_dir.mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}
    if parallel is None:
        parallel = os.environ.get("CADFEAT_REPORT_PARALLEL", "0") == "1"
    has_renders = context is not None and context.shape_before is not None
    child = _PlotProcess.start(results, img_dir) if parallel and has_renders else None

    start = time.perf_counter()
    try:
        renders = make_renders(context, results, img_dir) if renders is None else renders
    except BaseException:  # Ctrl-C during the renders: leave no plot process behind
        if child is not None:
            child.kill()
        raise
    timings["renders"] = time.perf_counter() - start
    timings.update({f"renders: {k}": v for k, v in renders.timings_s.items()})

    start = time.perf_counter()
    outcome = child.finish() if child is not None else None
    if outcome is not None:
        plots, plot_notes, timings["plots"] = outcome
        timings["plots: wait"] = time.perf_counter() - start
    else:
        plots, plot_notes = make_plots(results, img_dir)
        timings["plots"] = time.perf_counter() - start

    start = time.perf_counter()
    notes = renders.notes + plot_notes
    try:
        view = view3d_section(context, results)
    except Exception as exc:  # the interactive view is an extra: its failure is a note
        log.warning("report: 3-D view not built: %s", exc)
        notes.append(f"interactive 3-D view not built: {type(exc).__name__}: {exc}")
        view = ""
    timings["view3d"] = time.perf_counter() - start
    start = time.perf_counter()
    document = _document(out_dir, results, renders, plots, notes, timings, self_contained, view)
    path = out_dir / REPORT_NAME
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(document, encoding="utf-8")
    os.replace(tmp, path)
    timings["html"] = time.perf_counter() - start
    timings["total"] = time.perf_counter() - t0

    images = [*renders.comparison.values(), *(p for ps in renders.views.values() for p in ps),
              *(p.path for p in plots)]
    return ReportOutput(path, images, notes, timings)


def _single_design(results: JsonDict, context: ReportContext | None) -> tuple[dict, ReportContext | None]:
    """For ``evaluation_only`` results: drop any "after" copy of the current design (the report then shows one
    design, "current", and renders it once)."""
    if not value(results, "evaluation_only"):
        return results, context
    results = dict(results)
    for key in ("holes", "measures", "objectives"):
        if isinstance(results.get(key), dict):
            results[key] = {k: v for k, v in results[key].items() if k not in ("after", "combined_after")}
    if context is not None and context.shape_after is not None:
        context = dataclasses.replace(context, shape_after=None, holes_after=None)
    return results, context


class _PlotProcess:
    """The plots drawn by a child Python process (a clean interpreter: no fork of a process holding an
    OpenGL context or threads, no re-import of the caller's main module)."""

    def __init__(self, proc: subprocess.Popen, tmp: Path) -> None:
        self.proc, self.tmp = proc, tmp

    @classmethod
    def start(cls, results: JsonDict, img_dir: Path) -> _PlotProcess | None:
        tmp = Path(tempfile.mkdtemp(prefix="cadfeat-plots-"))
        try:
            (tmp / "results.json").write_text(json.dumps(results), encoding="utf-8")
            env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [_package_root(),
                                                                              os.environ.get("PYTHONPATH")]))}
            proc = subprocess.Popen([sys.executable, "-m", "cadfeat.report.plots", str(tmp / "results.json"),
                                     str(img_dir)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                    env=env)
        except Exception as exc:  # not serialisable, no interpreter...: draw the plots in this process
            log.info("report: plots drawn in-process (%s)", exc)
            shutil.rmtree(tmp, ignore_errors=True)
            return None
        return cls(proc, tmp)

    def finish(self, timeout_s: float = 600.0) -> tuple[list[Plot], list[str], float] | None:
        """The child's plots, notes and drawing time; None (after a logged warning) if it failed."""
        try:
            out, err = self.proc.communicate(timeout=timeout_s)
            if self.proc.returncode != 0:
                raise RuntimeError(f"exit {self.proc.returncode}: {err.strip()[-500:]}")
            data = json.loads(out.strip().splitlines()[-1])
            plots = [Plot(d["key"], d["title"], d["caption"], Path(d["path"])) for d in data["plots"]]
            return plots, list(data["notes"]), float(data["time_s"])
        except Exception as exc:
            self.kill()
            log.warning("report: the plot process failed (%s); drawing the plots here", exc)
            return None
        finally:
            shutil.rmtree(self.tmp, ignore_errors=True)


    def kill(self) -> None:
        """Stop the child (if still running) and remove its temporary folder."""
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        shutil.rmtree(self.tmp, ignore_errors=True)


def _package_root() -> str:
    """The directory holding this ``cadfeat`` package (so the child imports the same code)."""
    return str(Path(__file__).resolve().parents[2])


# ------------------------------------------------------------------------------------------------ sections
def _document(out_dir: Path, results: JsonDict, renders: Renders, plots: list[Plot], notes: list[str],
              timings: dict[str, float], embed: bool = True, view3d: str = "") -> str:
    study = typed_section(results, "study", StudyRecord, partial=True)
    kind = "evaluation" if tables.is_evaluation(results) else "report"
    name, part = (study.name, study.part) if study else (None, None)
    title = f"cadfeat {kind} — {name or 'study'}"
    subtitle = f"Part {part or '?'}" + (f": {study.description}" if study and study.description else "")
    rel = _relative(out_dir, embed)
    builders: list[tuple[str, str, Callable[[], str]]] = [
        ("decision", "Decision", lambda: "" if tables.is_evaluation(results) else verdict_section(results)),
        ("summary", "Summary", lambda: tables.summary(results)),
        ("trust", "What limits the answer", lambda: trust.section(results)),
        ("requirements", "Kept requirements (checked on the rebuilt geometry)",
         lambda: requirements_table(results)),
        ("holes", "Hole table (shop-ready)", lambda: "" if tables.is_evaluation(results) else hole_table(results)),
        ("patterns", "Hole patterns", lambda: patterns_section(results)),
        ("robustness", "Robustness of the optimum",
         lambda: robustness_section(results) + robust_designs_section(results, out_dir, rel)),  # issue 18
        ("view3d", "Interactive 3-D view, before and after", lambda: view3d),
        ("renders", "The part before and after", lambda: _renders_section(renders, rel)),
        ("views", "What the camera sees", lambda: _views_section(renders, rel)),
        ("features", "Per-feature measures (worst over the trajectory)", lambda: _features_section(results)),
        ("setup", "Study, camera and trajectory", lambda: tables.setup_table(results)),
        ("plots", "Plots", lambda: "".join(f"<h3>{esc(p.title)}</h3>" + figure(rel(p.path), p.caption)
                                           for p in plots)),
        ("pose", "How well will the robot know the part's pose?", lambda: pose_section(results, out_dir, rel)),
        ("tracking", "Does the new design track better?", lambda: tracking_section(results, out_dir, rel)),
        ("added_targets", "Where would new target holes help?",
         lambda: added_targets_section(results, out_dir, rel)),  # issue 31
        ("camera", "What the robot's camera will see", lambda: physical_views_section(results, out_dir, rel)),
        ("appendix", "Appendix: design matrix and normalisation", lambda: _appendix(results)),
        ("files", "Exported files", lambda: tables.files_table(results) + tables.verification_table(results)),
        ("provenance", "Versions and timings", lambda: _provenance(results, timings)),
    ]
    sections = []
    for sid, heading, build in builders:
        try:
            body = build()
        except Exception as exc:  # malformed results: say so in one line, keep the rest of the report
            why = problem_line(exc)
            log.warning("report: section %s failed: %s", sid, why)
            notes.append(f"section '{heading}' could not be built: {why}")
            body = note(f"This section could not be built: {why}", "warning")
        if body:
            sections.append(section(heading, body, sid))
    if notes:
        sections.append(section("Notes", "".join(note(n) for n in notes), "notes"))
    return page(title, subtitle, sections)


def _relative(out_dir: Path, embed: bool = True) -> Relative:
    """Image source for ``figure``: the path relative to report.html, or (data URI, that path) when ``embed``."""
    def rel(path: Path) -> str | tuple[str, str]:
        relpath = Path(os.path.relpath(Path(path).resolve(), out_dir.resolve())).as_posix()
        return (data_uri(path), relpath) if embed else relpath
    return rel


def _renders_section(renders: Renders, rel: Relative) -> str:
    if not renders.comparison:
        return note("No renders of the part: " + ("; ".join(renders.notes) or "rendering unavailable."))
    captions = {"current": "The current design (evaluation: nothing was moved).",
                "before": "Before: the original layout.",
                "after": "After: moved holes with arrows from the old to the new centre, fixed holes marked, "
                         "the camera trajectory with frusta."}
    closeup = {k: p for k, p in renders.comparison.items() if k.endswith("_closeup")}
    overview = {k: p for k, p in renders.comparison.items() if k not in closeup}
    out = []
    if closeup:
        captions_closeup = {
            "before_closeup": "Before (close-up, part alone): holes that will move in orange, fixed holes in blue.",
            "after_closeup": "After (close-up, same viewpoint): moved holes in green at their new place, the old "
                             "rim as an orange ring, red arrows from the old centre to the new hole, fixed holes in "
                             "blue; labels in italics mark holes hidden from this viewpoint."}
        figs = "".join(figure(rel(p), captions_closeup.get(k, k), f"part {k.replace('_', ' ')}")
                       for k, p in closeup.items())
        out.append(f'<div class="pair closeup">{figs}</div>')
        if overview:
            out.append("<h3>With the camera trajectory</h3>")
    figs = "".join(figure(rel(p), captions.get(k, k), f"part {k}") for k, p in overview.items())
    out.append(f'<div class="pair">{figs}</div>')
    return "".join(out)


def _views_section(renders: Renders, rel: Relative) -> str:
    if not renders.views:
        return note("No camera views: " + ("; ".join(renders.notes) or "rendering unavailable.")) \
            if renders.samples else ""
    out = ["<p>Synthetic images with the study camera's intrinsics at each hole's worst pose (the trajectory "
           "sample of its smallest margin); predicted hole ellipses and names overlaid.</p>"]
    for i, (sample, t) in enumerate(zip(renders.samples, renders.sample_times_s, strict=True)):
        worst = renders.worst.get(sample)
        why = f" — worst pose of {', '.join(worst)}" if worst else ""
        figs = "".join(figure(rel(paths[i]), f"{which}: sample {sample} (t = {fmt(t)} s){why}",
                              f"{which} view {sample}")
                       for which, paths in renders.views.items() if i < len(paths))
        out.append(f'<div class="pair">{figs}</div>')
    return "".join(out)


def _features_section(results: JsonDict) -> str:
    body = tables.feature_table(results)
    if not body:
        return ""
    return ("<p>Worst margin of each hole over the trajectory: positive = satisfied, negative = the hole is out "
            "of view, out of focus or too small in the image at its worst pose (the trajectory sample named in "
            "the last column).</p>" + body
            + "<details><summary>Definitions (thesis)</summary><p>Thesis Table 5.1. FOV cone margin "
            "cos β − cos(α/2) (eq. 3.1-3.3); FOV image margin: distance of the projected rim to the image border "
            "(px); focus margin relative to half the depth of field (eq. 3.4-3.6); resolution = minor ellipse "
            "axis − required (px).</p></details>")


def _provenance(results: JsonDict, timings: dict[str, float]) -> str:
    report_t = {f"report: {k}": v for k, v in timings.items()}
    return (tables.key_value_table(value(results, "versions"), "versions", ("library", "version"))
            + tables.key_value_table({**(value(results, "timings_s") or {}), **report_t}, "timings",
                                     ("phase", "seconds")))


def _appendix(results: JsonDict) -> str:
    """Design matrix (thesis §2.2.4) and normalisation: background, folded away."""
    body = tables.design_matrix_table(results) + tables.normalisation_note(results)
    return f"<details><summary>Design matrix and normalisation of the objectives</summary>{body}</details>" \
        if body else ""
