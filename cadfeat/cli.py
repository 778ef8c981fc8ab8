"""Command line: ``cadfeat run | evaluate | parts | render | validate``.

Each sub-command lives in its own ``_cmd_*`` function and imports what it needs lazily, so that
``cadfeat --help`` stays fast (no CadQuery or PyVista import).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from cadfeat.errors import CadfeatError

Command = Callable[[argparse.Namespace], int]
_COMMANDS: dict[str, tuple[Callable[[argparse.ArgumentParser], None], Command]] = {}


def command(name: str, configure: Callable[[argparse.ArgumentParser], None]) -> Callable[[Command], Command]:
    """Register a sub-command: ``configure`` adds its arguments, the decorated function runs it."""

    def register(func: Command) -> Command:
        _COMMANDS[name] = (configure, func)
        return func

    return register


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cadfeat",
        description="Redesign hole features of CAD parts for vision-guided manipulation.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (configure, func) in _COMMANDS.items():
        doc = (func.__doc__ or "").strip().splitlines()
        p = sub.add_parser(name, help=doc[0] if doc else None, description=func.__doc__)
        configure(p)
        p.set_defaults(_func=func)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    _load_commands()
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


def _load_commands() -> None:
    """Import the modules that register sub-commands (cheap: they import heavy libraries lazily)."""
    from cadfeat import commands  # noqa: F401


if __name__ == "__main__":  # pragma: no cover
    from cadfeat.cli import main as _main  # the registry lives in the imported module, not __main__

    sys.exit(_main())
