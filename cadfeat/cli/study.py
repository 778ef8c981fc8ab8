"""Sub-commands ``cadfeat run | evaluate | validate STUDY`` (heavy imports inside the functions)."""

from __future__ import annotations

import argparse

from cadfeat.cli.command import Command


def _study_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("study", metavar="STUDY", help="study file (TOML), see README 'Study files'")


def _run_args(parser: argparse.ArgumentParser) -> None:
    _study_arg(parser)
    parser.add_argument("--out", metavar="DIR", help="output folder (default: exports/<study name>/)")
    parser.add_argument("--seed", type=int, metavar="N", help="random seed (overrides study.seed and optimizer.seed)")
    parser.add_argument("--quiet", action="store_true", help="no progress display, only the summary")


def _evaluate_args(parser: argparse.ArgumentParser) -> None:
    _study_arg(parser)
    parser.add_argument("--out", metavar="DIR", help="also write results.json and the report into DIR")
    parser.add_argument("--pose", type=int, metavar="K",
                        help="score one trajectory sample only (0-based), like the thesis GUI's single-pose mode")
    parser.add_argument("--quiet", action="store_true", help="no progress display")


def run(args: argparse.Namespace) -> int:
    """Run a redesign study: optimise the movable holes, verify and export STEP/STL, results.json, report."""
    from cadfeat.study.run import run_study

    result = run_study(args.study, args.out, seed=args.seed, quiet=args.quiet, progress=not args.quiet)
    print(result.summary())
    return 0


def evaluate(args: argparse.Namespace) -> int:
    """Score the study's current design without optimising; print the per-feature table (thesis Table 5.1)."""
    from cadfeat.study.run import evaluate_study

    evaluate_study(args.study, args.out, pose=args.pose, quiet=args.quiet, echo=True)
    return 0


def validate(args: argparse.Namespace) -> int:
    """Check a study file (sections, keys, types, ranges, files, part parameters) without running it."""
    from cadfeat.study.schema import load_study

    config = load_study(args.study)
    names = ", ".join(p.name for p in config.design.parameters) or \
        f"{len(config.design.holes)} STEP hole(s)"
    pre = _preflight_if_buildable(config)
    print(f"{config.label}: ok — study '{config.study.name}', {config.study.part_kind} part {config.study.part}, "
          f"varying {names}; objective {config.objective.combine}/{config.objective.aggregate} of "
          f"{', '.join(config.objective.measures)}; optimizer {config.optimizer.method}")
    for line in ([] if pre is None else [f"ASSUMED: {a}" for a in pre.assumptions] +
                 [f"WARNING: {w}" for w in pre.warnings]):
        print(f"  {line}")
    return 0


def _preflight_if_buildable(config: object) -> object:
    """The study's pre-flight (``cadfeat.study.preflight``) when the part can be built; its refusal is the
    command's error. A part that does not build is left to ``run``/``evaluate`` (validate checks the file)."""
    from cadfeat.errors import CadfeatError
    from cadfeat.study.run import preflight_study
    from cadfeat.study.schema import StudyError

    try:
        return preflight_study(config)
    except StudyError:
        raise
    except (CadfeatError, ImportError):
        return None


COMMANDS = (
    Command("run", _run_args, run),
    Command("evaluate", _evaluate_args, evaluate),
    Command("validate", _study_arg, validate),
)
