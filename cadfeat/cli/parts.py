"""``cadfeat parts [DIR | SCRIPT | PART.step] [--holes] [--view X,Y,Z] [--params]``: list the part scripts with their
parameters, or a STEP part's holes (the names a study's ``design.holes`` selectors use); ``--view``: the side the
camera looks from (a through hole's entrance is the end on that side, as a study with that view extracts it;
default: the script's ``VIEW_DIRECTION``); ``--params``: one script's parameters as cq-cli's ``--getparams``
JSON."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path
from typing import TYPE_CHECKING

from cadfeat.cad.sandbox import DEFAULT_BUILD_TIMEOUT_S, start_workers
from cadfeat.cli.command import Command
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np

    from cadfeat.results import JsonDict


def _arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("directory", nargs="?", default=None,
                        help="folder of part scripts, one script, or a STEP part (default: the parts/ library)")
    parser.add_argument("--holes", action="store_true", help="also build each part and list its holes at the defaults")
    parser.add_argument("--view", default=None, metavar="X,Y,Z",
                        help="direction towards the camera (part frame): a through hole's entrance is the end on "
                             "that side, as in a study seen from there (default: the script's VIEW_DIRECTION)")
    parser.add_argument("--params", action="store_true",
                        help="print one script's parameters as cq-cli --getparams JSON (CQGI scripts: as cq-cli)")
    build_timeout_arg(parser)


def build_timeout_arg(parser: argparse.ArgumentParser) -> None:
    """``--build-timeout S``: the time limit of one part-script import or build (worker process)."""
    parser.add_argument("--build-timeout", type=float, default=DEFAULT_BUILD_TIMEOUT_S, metavar="S",
                        help=f"time limit of one part-script import or build, s (default {DEFAULT_BUILD_TIMEOUT_S:g})")


def parts(args: argparse.Namespace) -> int:
    """List the part scripts: description, parameters (default, bounds, unit), fixed holes."""

    start_workers()
    return _list_parts(args)


def _list_parts(args: argparse.Namespace) -> int:
    from cadfeat.cad.parts import find_parts, load_part  # lazy: keeps `cadfeat --help` fast

    target = Path(args.directory) if args.directory else None
    if getattr(args, "params", False):
        return _params_json(target, args.build_timeout)
    view = _view(getattr(args, "view", None))
    if target is not None and target.suffix.lower() in (".step", ".stp"):
        return _step_part(target, args.holes, view)
    paths = [target] if target is not None and target.is_file() else find_parts(target)
    for path in paths:
        part = load_part(path, args.build_timeout)
        if view is not None:
            part = dataclasses.replace(part, view_direction=view)
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


def _params_json(target: object, time_limit_s: float | None) -> int:
    """``--params``: the parameters of one script as cq-cli's ``--getparams`` JSON."""
    if target is None or not Path(str(target)).is_file():
        raise CadfeatError(f"--params: {target or '(no script)'} is not a script file; allowed: one part script "
                           "(cadfeat parts SCRIPT.py --params)")
    print(json.dumps(parameter_listing(Path(str(target)), time_limit_s)))
    return 0


def parameter_listing(path: Path, time_limit_s: float | None = None) -> list[JsonDict]:
    """``cadfeat parts SCRIPT --params``: cq-cli's ``--getparams`` JSON objects. A CQGI script: exactly
    ``cqgi_parts.getparams``. A cadfeat part script (``PARAMETERS`` + ``build``, which CQGI cannot list): the same
    fields from its ``PARAMETERS`` — ``type`` number, ``name``, ``caption`` (description), ``initial`` (default)
    and ``min`` / ``max`` (bounds)."""
    from cadfeat.cad.cqgi_parts import getparams, is_cqgi_script  # lazy: keeps `cadfeat --help` fast
    from cadfeat.cad.parts import load_part

    if is_cqgi_script(path):
        return getparams(path)
    part = load_part(path, time_limit_s)
    return [{"type": "number", "name": p.name, **({"caption": p.description} if p.description else {}),
             "initial": p.default, "min": p.lower, "max": p.upper} for p in part.parameters.values()]


def _view(text: str | None) -> np.ndarray | None:
    """``--view X,Y,Z`` as a unit vector (part frame), or None; ``CadfeatError`` for anything else."""
    if text is None:
        return None
    from cadfeat.cad.cqgi_parts import unit_view_direction

    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3:
        raise CadfeatError(f"--view: expected three numbers X,Y,Z (towards the camera, part frame), got {text!r}")
    return unit_view_direction(values, "--view")


def _step_part(path: object, holes: bool, view: np.ndarray | None = None) -> int:
    """A STEP part: its holes (names, kind, entrance, host face) and the near-round openings it skips."""
    from cadfeat.cad.step_parts import load_step  # lazy: keeps `cadfeat --help` fast

    part = load_step(path, prefer_direction=view)  # type: ignore[arg-type]
    print(f"{part.name}: STEP part, {len(part.holes)} hole(s), {len(part.skipped)} skipped opening(s)")
    print(f"    file: {part.path}")
    print(f"    tolerances: {part.tolerance.describe()}")
    if holes:
        for line in part.listing():
            print(f"    {line}")
    else:
        print(f"    holes: {', '.join(h.name for h in part.holes) or 'none'} (--holes lists them)")
    return 0


COMMANDS = (
    Command("parts", _arguments, parts),
)
