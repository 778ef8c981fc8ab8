"""A sub-command of ``cadfeat``: its name, how it adds its arguments, and the function that runs it.

A leaf module: the command modules import it, and ``cadfeat.cli`` imports the command modules, so there is
no import circle.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass

Runner = Callable[[argparse.Namespace], int]
Configure = Callable[[argparse.ArgumentParser], None]


def no_arguments(parser: argparse.ArgumentParser) -> None:
    """A sub-command without arguments."""


@dataclass(frozen=True)
class Command:
    """``cadfeat NAME``: ``configure`` adds its arguments to its parser, ``run`` runs it (its docstring's first
    line is the help text)."""

    name: str
    configure: Configure
    run: Runner

    def add_parser(self, subparsers: argparse._SubParsersAction) -> None:
        doc = (self.run.__doc__ or "").strip().splitlines()
        parser = subparsers.add_parser(self.name, help=doc[0] if doc else None, description=self.run.__doc__)
        self.configure(parser)
        parser.set_defaults(_func=self.run)
