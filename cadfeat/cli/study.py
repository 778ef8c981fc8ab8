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
    if config.study.part_kind == "step":  # re-drill every movable hole once now, not after the optimisation
        from cadfeat.study.setup import check_step_study

        names += f"; {check_step_study(config)}"
    print(f"{config.label}: ok — study '{config.study.name}', {config.study.part_kind} part {config.study.part}, "
          f"varying {names}; objective {config.objective.combine}/{config.objective.aggregate} of "
          f"{', '.join(config.objective.measures)}; optimizer {config.optimizer.method}")
    return 0


COMMANDS = (
    Command("run", _run_args, run),
    Command("evaluate", _evaluate_args, evaluate),
    Command("validate", _study_arg, validate),
)
