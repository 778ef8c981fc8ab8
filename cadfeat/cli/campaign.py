"""Sub-command ``cadfeat campaign CAMPAIGN.toml`` (heavy imports inside the function)."""

from __future__ import annotations

import argparse

from cadfeat.cli.command import Command
from cadfeat.errors import CadfeatError


def _args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("campaign", metavar="CAMPAIGN", help="campaign file (TOML), see docs/guide/campaigns.md")
    parser.add_argument("--out", metavar="DIR", help="output folder (default: exports/<campaign name>/); re-running "
                                                     "into it skips the cases already finished")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="attach to a running Dask scheduler (tcp://host:8786) instead of a local cluster")
    parser.add_argument("--workers", type=int, metavar="N",
                        help="local worker processes, one study each at a time (default: the CPU count)")
    parser.add_argument("--quiet", action="store_true", help="no progress display, only the summary")


def campaign(args: argparse.Namespace) -> int:
    """Run many studies (parts x cameras x paths x objective settings) on Dask, resumable; campaign.csv/.html."""
    from cadfeat.campaign.runner import run_campaign  # lazy: keeps `cadfeat --help` fast

    if args.workers is not None and args.workers < 1:
        raise CadfeatError(f"--workers: {args.workers} is not allowed; allowed: a number of processes >= 1")
    if args.workers is not None and args.scheduler:
        raise CadfeatError("--workers: not with --scheduler (the cluster has its own workers); allowed: one of them")
    result = run_campaign(args.campaign, args.out, scheduler=args.scheduler, workers=args.workers,
                          quiet=args.quiet, progress=not args.quiet)
    print(result.summary())
    return 0 if result.count("done") == len(result.records) else 1


COMMANDS = (Command("campaign", _args, campaign),)
