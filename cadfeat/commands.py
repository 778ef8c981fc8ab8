"""The sub-commands of ``cadfeat``. Each imports its heavy dependencies inside the function."""

from __future__ import annotations

import argparse

from cadfeat.cli import command


def _no_args(parser: argparse.ArgumentParser) -> None:
    """Sub-command without arguments."""


@command("cameras", _no_args)
def cameras(args: argparse.Namespace) -> int:
    """List the camera presets with their intrinsics and sources."""
    from cadfeat.camera import PRESETS, Camera

    for name in sorted(PRESETS):
        cam = Camera.preset(name)
        print(f"{name}: {cam.width}x{cam.height} px, fx={cam.fx:g} fy={cam.fy:g} cx={cam.cx:g} cy={cam.cy:g}, "
              f"f={cam.focal_length_mm:g} mm f/{cam.f_number:g}, focus {cam.focus_distance_mm:g} mm")
        print(f"    {cam.source}")
    return 0
