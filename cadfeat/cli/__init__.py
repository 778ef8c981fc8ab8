"""Command line: ``cadfeat run | evaluate | validate | track | parts | render | report | cameras | trajectories |
calibrate | plan-recording | detect``.

One module per command group (``study``, ``track``, ``parts``, ``render``, ``report``, ``listing``), each with a
``COMMANDS`` table of ``Command`` entries; the parser is built from those tables. The command modules import
their heavy dependencies inside the functions, so that ``cadfeat --help`` stays fast (no CadQuery or PyVista
import).
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import threading
import warnings
from collections.abc import Callable, Iterator, Sequence
from typing import TextIO

from cadfeat._version import __version__
from cadfeat.cli import calibrate, campaign, detect, explore, listing, parts, recording, render, report, study, track
from cadfeat.cli.command import Command
from cadfeat.errors import CadfeatError, CadfeatWarning, Terminated

__all__ = ["COMMANDS", "build_parser", "main", "run_guarded"]

#: Every sub-command, in the order ``cadfeat --help`` lists them.
COMMANDS: tuple[Command, ...] = (*listing.COMMANDS, *parts.COMMANDS, *render.COMMANDS, *report.COMMANDS,
                                 *study.COMMANDS, *track.COMMANDS, *explore.COMMANDS,
                                 *campaign.COMMANDS, *calibrate.COMMANDS, *recording.COMMANDS,
                                 *detect.COMMANDS)


def build_parser() -> argparse.ArgumentParser:
    """The ``cadfeat`` argument parser with every sub-command of ``COMMANDS``."""
    parser = argparse.ArgumentParser(
        prog="cadfeat",
        description="Redesign hole features of CAD parts for vision-guided manipulation.",
    )
    parser.add_argument("--version", action="version", version=f"cadfeat {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for cmd in COMMANDS:
        cmd.add_parser(sub)
    return parser


@contextlib.contextmanager
def sigterm_as_exception() -> Iterator[None]:
    """Within the block, SIGTERM raises ``Terminated`` in the main thread: it unwinds like Ctrl-C (staging
    folders removed, worker processes killed) and the CLI exits with status 143."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def on_term(signum: int, frame: object) -> None:
        raise Terminated

    previous = signal.signal(signal.SIGTERM, on_term)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def warnings_as_lines(prog: str = "cadfeat") -> Iterator[None]:
    """Within the block, cadfeat's own warnings (``CadfeatWarning``) print as one ``prog: warning: ...`` line on
    stderr; other warnings as Python prints them."""
    previous = warnings.showwarning

    def show(message: Warning | str, category: type[Warning], filename: str, lineno: int, file: TextIO | None = None,
             line: str | None = None) -> None:
        if issubclass(category, CadfeatWarning):
            print(f"{prog}: warning: {message}", file=sys.stderr)
        else:
            previous(message, category, filename, lineno, file, line)

    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = previous


def run_guarded(func: Callable[[], int], prog: str = "cadfeat") -> int:
    """``func()`` with the CLI's error handling: one line for bad input (status 2), ``interrupted`` (130),
    ``terminated`` (143, SIGTERM). Each command gives its part-script imports and CAD builds their time limit
    (``[study] build_timeout_s``, ``--build-timeout``)."""
    try:
        with sigterm_as_exception(), warnings_as_lines(prog):
            return int(func() or 0)
    except Terminated:
        print(f"{prog}: terminated (SIGTERM); nothing half-written was left", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except CadfeatError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into `head` and the like
        sys.stderr.close()
        return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``cadfeat`` with ``argv`` (default: the process arguments); returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_func", None):
        parser.print_help()
        return 0
    return run_guarded(lambda: args._func(args))
