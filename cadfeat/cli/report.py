"""``cadfeat report RESULTS_JSON [--out DIR]``: (re)write report.html from a study's results.json."""

from __future__ import annotations

import argparse
from pathlib import Path

from cadfeat.cli.command import Command


def _arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("results", help="results.json written by `cadfeat run` or `cadfeat evaluate`")
    parser.add_argument("--out", default=None, help="directory for report.html and img/ (default: beside the "
                                                    "results file)")
    parser.add_argument("--force", action="store_true",
                        help="write into an existing --out folder cadfeat did not create (other files untouched)")


def report(args: argparse.Namespace) -> int:
    """Write report.html (plots and tables; no renders: those need the study's shapes) from a results.json."""
    from cadfeat.output_folder import REPORT_NAMES, staged_output
    from cadfeat.report import read_results, write_report  # lazy: keeps `cadfeat --help` fast

    results_path = Path(args.results)
    results = read_results(results_path)
    out = Path(args.out) if args.out else results_path.parent
    # beside the results file: added to that folder; --out: a new folder, or one cadfeat made (or --force)
    with staged_output(out, force=args.force or not args.out, merge=True, names=REPORT_NAMES) as stage:
        write_report(stage, results, None)
    print(out / "report.html")
    return 0


COMMANDS = (
    Command("report", _arguments, report),
)
