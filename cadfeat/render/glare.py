"""The glare maps of g_POSE (``measures.glare``): the part at the study's poses, rendered physically in its cell.

``glare_maps`` renders the part (as loaded: the original design) with the cell's light, material and hole ends
at each nominal pose — Mitsuba 3 (``render.pbr``) at ``SPP`` samples per pixel, the closed loop's metered
exposure (``render.sensor``: the part's median at a fixed share of full scale), no sensor noise — and smooths each
image by a Gaussian of ``SMOOTH_PX`` px (the path tracer's noise at few samples; the clipped regions are tens of
pixels wide), on a film of ``1/SCALE`` the camera's resolution (the same view: fx, fy, cx, cy scaled, the
distortion the same). Cost: about 1/(SCALE² · 16/SPP) of a closed-loop frame per pose — ~0.05 s on the LLVM
variant, 2 cores quiet (``benchmarks/bench_pbr.py``: ~0.4 s per full frame at 16 spp); made once per set-up.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.camera import Camera
from cadfeat.cell.model import Cell
from cadfeat.measures.glare import GlareMaps

if TYPE_CHECKING:  # pragma: no cover
    from cadquery import Shape

    from cadfeat.cad.features import Hole

__all__ = ["SCALE", "SPP", "glare_maps", "reduced"]

#: samples per pixel of the glare renders (smoothed afterwards)
SPP = 8
#: Gaussian σ (px of the reduced film) applied to each render
SMOOTH_PX = 1.0
#: the film's reduction: 1/SCALE of the camera's width and height
SCALE = 2


def glare_maps(shape: Shape, holes: Sequence[Hole], camera: Camera, T_cam_part: np.ndarray, cell: Cell) -> GlareMaps:
    """``GlareMaps`` of ``shape`` (its ``holes``) seen by ``camera`` at poses ``T_cam_part`` (L, 4, 4) in ``cell``
    (module docstring)."""
    import cv2

    from cadfeat.cad.features import holes_to_arrays
    from cadfeat.render.pbr import PbrRenderer
    from cadfeat.render.sensor import Sensor

    T = np.asarray(T_cam_part, float)
    film = reduced(camera, SCALE)
    grey = np.empty((len(T), film.height, film.width), dtype=np.float32)
    with PbrRenderer(shape, holes, film, light=cell.light, material=cell.material, spp=SPP,
                     hole_ends=cell.hole_ends, sensor=Sensor(exposure="meter"), crop=False) as renderer:
        # (the whole film, as when the contrast curve was fitted: the part's window gives the same maps up to the
        # sampler's noise, which would move the studies' optima by round-off-sized steps)
        for k, pose in enumerate(T):
            grey[k] = cv2.GaussianBlur(renderer.render_grey(pose), (0, 0), SMOOTH_PX)
    centres, _, radii = holes_to_arrays(holes)
    return GlareMaps(grey, film, np.asarray(centres, float), np.asarray(radii, float))


def reduced(camera: Camera, k: int) -> Camera:
    """``camera`` on a film k× coarser: the same view (pixel edges scale by 1/k: c' + ½ = (c + ½)/k), the same
    lens."""
    from dataclasses import replace

    return replace(camera, width=camera.width // k, height=camera.height // k, fx=camera.fx / k, fy=camera.fy / k,
                   cx=(camera.cx + 0.5) / k - 0.5, cy=(camera.cy + 0.5) / k - 0.5)
