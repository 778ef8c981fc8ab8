"""Sub-commands ``cadfeat run | evaluate | validate STUDY`` (heavy imports inside the functions)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cadfeat.cli.command import Command
from cadfeat.errors import CadfeatError


def _study_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("study", metavar="STUDY", help="study file (TOML), see docs/guide/study-files.md")


def _run_args(parser: argparse.ArgumentParser) -> None:
    _study_arg(parser)
    parser.add_argument("--out", metavar="DIR", help="output folder (default: exports/<study name>/)")
    parser.add_argument("--seed", type=int, metavar="N", help="random seed (overrides study.seed and optimizer.seed)")
    parser.add_argument("--quiet", action="store_true", help="no progress display, only the summary")
    _force_arg(parser)
    _track_arg(parser)
    cache_arg(parser)


def cache_arg(parser: argparse.ArgumentParser) -> None:
    """``--no-cache``: set the study up without the set-up cache (``cadfeat.study.setup_cache``)."""
    parser.add_argument("--no-cache", dest="cache", action="store_const", const=False, default=None,
                        help="set the study up again instead of reading the set-up of unchanged inputs from the "
                             "set-up cache (also: CADFEAT_CACHE=off; `cadfeat cache` shows where it is)")


def _track_arg(parser: argparse.ArgumentParser) -> None:
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--track", choices=("fast", "full", "off", "pbr"), default=None,
                       help="closed-loop check of the recommended design (default: the study's [tracking] check; "
                            "fast: PnP + IEKF, 8 runs, <= 20 frames; pbr: the fast check rendered physically)")
    group.add_argument("--no-track", dest="track", action="store_const", const="off",
                       help="no closed-loop check (same as --track off)")


def _force_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--force", action="store_true",
                        help="write into an existing folder cadfeat did not create: cadfeat's files are added, every "
                             "other file is left untouched (a file of the same name not written by cadfeat is "
                             "never overwritten)")


def _evaluate_args(parser: argparse.ArgumentParser) -> None:
    _study_arg(parser)
    parser.add_argument("--out", metavar="DIR", help="also write results.json and the report into DIR")
    parser.add_argument("--pose", type=int, metavar="K",
                        help="score one trajectory sample only (0-based), like the thesis GUI's single-pose mode")
    parser.add_argument("--quiet", action="store_true", help="no progress display")
    _force_arg(parser)
    cache_arg(parser)


def run(args: argparse.Namespace) -> int:
    """Run a redesign study: optimise the movable holes, verify and export STEP/STL, results.json, report."""
    from cadfeat.study.run import run_study  # lazy: keeps `cadfeat --help` fast

    result = run_study(args.study, args.out, seed=args.seed, quiet=args.quiet, progress=not args.quiet,
                       force=args.force, track=args.track, cache=args.cache)
    print(result.summary())
    if result.results.get("interrupted"):  # Ctrl-C: the best design so far was written (study.interrupts)
        print(f"cadfeat: interrupted; the best design so far is in {result.out_dir} (results.json: "
              '"interrupted": true)', file=sys.stderr)
        return 130
    return 0


def evaluate(args: argparse.Namespace) -> int:
    """Score the study's current design without optimising; print the per-feature table (thesis Table 5.1)."""
    from cadfeat.study.run import evaluate_study  # lazy: keeps `cadfeat --help` fast

    evaluate_study(args.study, args.out, pose=args.pose, quiet=args.quiet, echo=True, force=args.force,
                   cache=args.cache)
    return 0


def validate(args: argparse.Namespace) -> int:
    """Check a study file (sections, keys, types, ranges, files, part parameters, the part builds / the STEP
    file reads) without running it."""
    from cadfeat.study.schema import load_study  # lazy: keeps `cadfeat --help` fast

    config = load_study(args.study)
    _check_part(config)
    names = ", ".join(p.name for p in config.design.parameters) or \
        f"{len(config.design.holes)} STEP hole(s)"
    if config.study.part_kind == "step":  # re-drill every movable hole once now, not after the optimisation
        from cadfeat.study.setup import check_step_study

        names += f"; {check_step_study(config)}"
    pre = _preflight_if_buildable(config)
    print(f"{config.label}: ok — study '{config.study.name}', {config.study.part_kind} part {config.study.part}, "
          f"varying {names}; objective {config.objective.combine}/{config.objective.aggregate} of "
          f"{', '.join(config.objective.measures)}; optimizer {config.optimizer.method}")
    for line in ([] if pre is None else [f"ASSUMED: {a}" for a in pre.assumptions] +
                 [f"WARNING: {w}" for w in pre.warnings]):
        print(f"  {line}")
    added = None if pre is None else pre.numbers.get("add_targets")  # type: ignore[attr-defined]
    if added:
        print(f"  add_targets: {added['sites']} candidate sites on {'; '.join(added['faces'])}; at most "
              f"{added['most_that_fit']} holes fit at once; a dry-run hole drilled and verified")
    return 0


def _preflight_if_buildable(config: object) -> object:
    """The study's pre-flight (``cadfeat.study.preflight``) when the part can be built; its refusal is the
    command's error. A part that does not build is left to ``run``/``evaluate`` (validate checks the file)."""
    from cadfeat.study.run import preflight_study  # lazy: keeps `cadfeat --help` fast
    from cadfeat.study.schema import StudyError

    try:
        return preflight_study(config, config.study.build_timeout_s)  # type: ignore[attr-defined]
    except StudyError:
        raise
    except (CadfeatError, ImportError):
        return None


def _check_part(config: object) -> None:
    """Load the part as the run will: a script is imported and built at its defaults (worker process, time
    limit), a STEP file is read and its holes extracted."""
    study = config.study  # type: ignore[attr-defined]
    try:
        if study.part_kind == "step":
            from cadfeat.cad.step_parts import load_step

            load_step(study.part_path)
        else:
            from cadfeat.cad.parts import load_part

            load_part(study.part_path, study.build_timeout_s).build()
    except CadfeatError as exc:
        raise CadfeatError(f"{config.label}: study.part: {exc}") from exc  # type: ignore[attr-defined]


def _schema_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", metavar="FILE", help="write the schema to FILE (default: print it)")
    parser.add_argument("--results", action="store_true",
                        help="the schema of results.json (versioned by schema_version) instead of a study file's")


def schema(args: argparse.Namespace) -> int:
    """Write the JSON Schema of a study file (editor completion and checking: docs/guide/study-files.md), or with
    ``--results`` of results.json (``cadfeat.results.StudyResults``)."""
    if args.results:
        from cadfeat.results import results_json_schema as make
    else:
        from cadfeat.study.json_schema import study_json_schema as make

    text = json.dumps(make(), indent=2, ensure_ascii=False) + "\n"
    if args.out:
        Path(args.out).write_text(text, encoding="utf-8")
    else:
        print(text, end="")
    return 0


def _cache_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--clear", action="store_true",
                        help="delete the set-up cache's entries (only the files cadfeat wrote there)")


def cache(args: argparse.Namespace) -> int:
    """Show where the study set-up cache is and how big it is (--clear: delete its entries).

    ``run``, ``evaluate`` and ``explore`` keep a study's set-up there (CAD builds, design map, normaliser,
    occlusion mesh) and read it back when the same inputs come again; see docs/guide/commands.md."""
    from cadfeat.study.setup_cache import CACHE_DIR_ENV, CACHE_ENV, SetupCache, cache_enabled, cache_root

    root = cache_root()
    store = SetupCache(root)
    state = "on" if cache_enabled() else f"off ({CACHE_ENV}=off)"
    if args.clear:
        print(f"set-up cache {root}: {store.clear()} entries deleted")
        return 0
    entries = store.listing()
    size = sum(p.stat().st_size for p in entries)
    print(f"set-up cache: {root} ({state}; {CACHE_DIR_ENV} moves it)\n  {len(entries)} entries, "
          f"{size / 1e6:.1f} MB")
    return 0


COMMANDS = (
    Command("run", _run_args, run),
    Command("evaluate", _evaluate_args, evaluate),
    Command("validate", _study_arg, validate),
    Command("schema", _schema_args, schema),
    Command("cache", _cache_args, cache),
)
