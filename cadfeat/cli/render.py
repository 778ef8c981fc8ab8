"""``cadfeat render PART [--param k=v ...] [--out PNG] [--view x,y,z]``: a quick picture of a part."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from cadfeat.cli.command import Command
from cadfeat.cli.parts import build_timeout_arg
from cadfeat.errors import CadfeatError

STEP_SUFFIXES = (".step", ".stp")
MAX_SIDE_PX = 8192
"""Largest side (pixels) of a ``cadfeat render`` picture (bounds the off-screen buffer's memory)."""


def _render_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("part", help="a part script (parts/*.py) or a STEP file")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="override a part-script parameter (repeatable)")
    parser.add_argument("--out", default=None, help="PNG to write (default: <part name>.png here)")
    parser.add_argument("--view", default=None, metavar="X,Y,Z",
                        help="direction from the part towards the viewer, part frame (default: the part's "
                             "VIEW_DIRECTION or the mean hole axis, tilted to show depth)")
    parser.add_argument("--size", default="900x700", metavar="WxH",
                        help=f"image size in pixels (default 900x700, each side at most {MAX_SIDE_PX})")
    build_timeout_arg(parser)


def parse_params(items: list[str]) -> dict[str, float | int]:
    """``["a=1", "b=2.5"]`` → ``{"a": 1, "b": 2.5}`` (integers stay integers)."""
    out: dict[str, float | int] = {}
    for item in items:
        name, sep, text = item.partition("=")
        name, text = name.strip(), text.strip()
        if not sep or not name or not text:
            raise CadfeatError(f"--param: expected NAME=VALUE, got {item!r}")
        try:
            out[name] = int(text)
        except ValueError:
            try:
                out[name] = float(text)
            except ValueError:
                raise CadfeatError(f"--param {name}: {text!r} is not a number") from None
    return out


def _parse_vector(text: str | None, what: str) -> tuple[float, float, float] | None:
    if text is None:
        return None
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3:
        raise CadfeatError(f"{what}: expected three numbers X,Y,Z, got {text!r}")
    return values  # type: ignore[return-value]


def _parse_size(text: str) -> tuple[int, int]:
    w, sep, h = text.lower().partition("x")
    if not sep or not w.strip().isdigit() or not h.strip().isdigit() or int(w) < 16 or int(h) < 16:
        raise CadfeatError(f"--size: expected WIDTHxHEIGHT in pixels (each ≥ 16), got {text!r}")
    if max(int(w), int(h)) > MAX_SIDE_PX:
        raise CadfeatError(f"--size {text}: each side at most {MAX_SIDE_PX} pixels (the limit of cadfeat render)")
    return int(w), int(h)


def load_shape(path: Path, params: dict[str, float | int], time_limit_s: float | None = None
               ) -> tuple[Any, list, Any, str]:
    """(shape, holes, view direction or None, name) of a STEP file or a part script (imported and built in a
    worker process within ``time_limit_s``; None: in this process)."""
    from cadfeat.cad.features import extract_holes  # lazy: keeps `cadfeat --help` fast
    from cadfeat.cad.parts import PARTS_DIR

    if not path.is_file() and path.suffix == "" and (PARTS_DIR / f"{path}.py").is_file():
        path = PARTS_DIR / f"{path}.py"  # a library part by name, as `cadfeat parts` lists them
    if path.exists() and not path.is_file():
        raise CadfeatError(f"{path}: not a regular file (a device, folder or pipe); expected a part script .py or "
                           "a STEP file .step/.stp")
    if not path.is_file():
        raise CadfeatError(f"{path}: no such file (expected a part script .py, a STEP file .step/.stp "
                           f"or the name of a part in {PARTS_DIR})")
    if path.suffix.lower() in STEP_SUFFIXES:
        from cadfeat.cad.export import import_step

        if params:
            raise CadfeatError(f"{path}: a STEP file has no parameters; --param {', '.join(params)} not allowed")
        shape = import_step(path)
        return shape, extract_holes(shape), None, path.stem
    if path.suffix.lower() != ".py":
        raise CadfeatError(f"{path}: unknown part type {path.suffix!r}; allowed: .py (part script), .step, .stp")
    from cadfeat.cad.parts import load_part

    part = load_part(path, time_limit_s)
    shape = part.build(**params)
    return shape, extract_holes(shape, prefer_direction=part.view_direction), part.view_direction, part.name


def render(args: argparse.Namespace) -> int:
    """Render a part script or STEP file to a PNG (off-screen) and print the PNG path."""
    from cadfeat.render import render_part  # lazy: keeps `cadfeat --help` fast
    from cadfeat.render.view_geometry import default_view_direction

    path = Path(args.part)
    size = _parse_size(args.size)
    shape, holes, view, name = load_shape(path, parse_params(args.param), args.build_timeout)
    direction = _parse_vector(args.view, "--view") or default_view_direction(holes, towards=view)
    out = Path(args.out) if args.out else Path(f"{name}.png")
    if out.suffix.lower() != ".png":
        raise CadfeatError(f"--out {out}: the picture is a PNG; give a path ending in .png")
    print(render_part(shape, out, holes, view_direction=direction, size=size))
    return 0


COMMANDS = (
    Command("render", _render_arguments, render),
)
