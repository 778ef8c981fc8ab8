"""The sub-commands of ``cadfeat``. Each imports its heavy dependencies inside the function."""

from __future__ import annotations

import argparse

from cadfeat.cli.command import Command, no_arguments


def cameras(args: argparse.Namespace) -> int:
    """List the camera presets with their intrinsics and sources."""
    from cadfeat.camera import PRESETS, Camera  # lazy: keeps `cadfeat --help` fast

    for name in sorted(PRESETS):
        cam = Camera.preset(name)
        print(f"{name}: {cam.width}x{cam.height} px, fx={cam.fx:g} fy={cam.fy:g} cx={cam.cx:g} cy={cam.cy:g}, "
              f"f={cam.focal_length_mm:g} mm f/{cam.f_number:g}, focus {cam.focus_distance_mm:g} mm")
        print(f"    {cam.source}")
    return 0


def trajectories(args: argparse.Namespace) -> int:
    """List the library trajectory kinds with their arguments (for [trajectory] in study files)."""
    from cadfeat.trajectory import TRAJECTORY_KINDS, kind_arguments  # lazy: keeps `cadfeat --help` fast

    for kind, func in TRAJECTORY_KINDS.items():
        summary = " ".join((func.__doc__ or "").strip().split("\n\n")[0].split())
        print(f"{kind}: {summary}")
        for a in kind_arguments(kind):
            default = "required" if a.required else "optional" if a.default is None else \
                f"default {_plain(a.default)}"
            print(f"    {a.name:<20} {a.arg_type.description:<34} {default}")
    print('Or a CSV file of poses: csv = "path.csv" (see cadfeat.trajectory for the columns).')
    return 0


def _plain(value: object) -> str:
    """A default value as it would be written in a TOML study file."""
    if isinstance(value, tuple):
        return "[" + ", ".join(f"{v:g}" for v in value) + "]"
    return f"{value:g}" if isinstance(value, float) else str(value)


COMMANDS = (
    Command("cameras", no_arguments, cameras),
    Command("trajectories", no_arguments, trajectories),
)
