"""Command line: ``cadfeat run | evaluate | validate | track | parts | render | report | cameras | trajectories``.

One module per command group (``study``, ``track``, ``parts``, ``render``, ``report``, ``listing``), each with a
``COMMANDS`` table of ``Command`` entries; the parser is built from those tables. The command modules import
their heavy dependencies inside the functions, so that ``cadfeat --help`` stays fast (no CadQuery or PyVista
import).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from cadfeat.cli import listing, parts, render, report, study, track
from cadfeat.cli.command import Command
from cadfeat.errors import CadfeatError

__all__ = ["COMMANDS", "build_parser", "main"]

#: Every sub-command, in the order ``cadfeat --help`` lists them.
COMMANDS: tuple[Command, ...] = (*listing.COMMANDS, *parts.COMMANDS, *render.COMMANDS, *report.COMMANDS,
                                 *study.COMMANDS, *track.COMMANDS)


def build_parser() -> argparse.ArgumentParser:
    """The ``cadfeat`` argument parser with every sub-command of ``COMMANDS``."""
    parser = argparse.ArgumentParser(
        prog="cadfeat",
        description="Redesign hole features of CAD parts for vision-guided manipulation.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for cmd in COMMANDS:
        cmd.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``cadfeat`` with ``argv`` (default: the process arguments); returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_func", None):
        parser.print_help()
        return 0
    try:
        return int(args._func(args) or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except CadfeatError as exc:
        print(f"cadfeat: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into `head` and the like
        sys.stderr.close()
        return 0
