"""``cadfeat parts [DIR] [--holes]``: list the part scripts with their parameters."""

from __future__ import annotations

import argparse

from cadfeat.cli.command import Command


def _arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("directory", nargs="?", default=None,
                        help="folder of part scripts, or one script (default: the parts/ library)")
    parser.add_argument("--holes", action="store_true", help="also build each part and list its holes at the defaults")


def parts(args: argparse.Namespace) -> int:
    """List the part scripts: description, parameters (default, bounds, unit), fixed holes."""
    from pathlib import Path

    from cadfeat.cad.parts import find_parts, load_part

    target = Path(args.directory) if args.directory else None
    paths = [target] if target is not None and target.is_file() else find_parts(target)
    for path in paths:
        part = load_part(path)
        print(f"{part.name}: {part.description}")
        print(f"    file: {part.path}")
        if part.view_direction is not None:
            print(f"    view direction: ({', '.join(f'{v:.3g}' for v in part.view_direction)})")
        if part.fixed_holes:
            print(f"    fixed holes: {part.fixed_holes}")
        for p in part.parameters.values():
            print(f"    {p.describe()}")
        if args.holes:
            for i, h in enumerate(part.holes()):
                c = ", ".join(f"{v:.3f}" for v in h.centre)
                a = ", ".join(f"{v:.3f}" for v in h.axis)
                print(f"    {h.name or f'H{i + 1}'}: centre ({c}) mm, axis ({a}), r {h.radius_mm:.3f} mm, {h.kind}, "
                      f"{'through' if h.through else f'blind {h.depth_mm:.3f} mm'}")
    return 0


COMMANDS = (
    Command("parts", _arguments, parts),
)
