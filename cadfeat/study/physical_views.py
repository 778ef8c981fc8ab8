"""What the robot's camera will see: both designs rendered physically, with the detections drawn and the misses
named (issue 28; the report's "What the robot's camera will see").

For the first, middle and last sample of the trajectory (``vision.closed_loop.report_frames``), each design is
rendered by Mitsuba 3 in the study's cell (``[cell]``: its light, material, hole ends; ``[tracking] spp``;
metered exposure, ``render.sensor``), blurred by the lens and given the cell's sensor noise as the closed loop does
(``closed_loop.observe``), and searched by the cell's detector with the same association
(``closed_loop.detect_sequence``). A hole counts as expected where the closed loop expects it
(``closed_loop.expected_visible``: in the image with its whole rim, facing the camera, minor axis ≥ 3 px, rim not
hidden); a miss is an expected hole without an associated detection. The frames are written as PNGs under
``camera/`` (predicted rims red, detections green, associated centres yellow, missed holes named in red) and
listed in results.json ``physical_views``.

``cadfeat run`` makes them whenever its closed-loop check is on (``closed_loop_check.attach``): about
2 designs × 3 frames of one physically based render each (the flagship: ~10 s, ``benchmarks/bench_pbr.py``).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from collections.abc import Sequence

    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.camera import Camera
    from cadfeat.measures.ellipse import Ellipse
    from cadfeat.results import JsonDict
    from cadfeat.study.schema import StudyConfig, TrackingSpec
    from cadfeat.study.tracking import Design
    from cadfeat.vision.closed_loop import TrackingConfig
    from cadfeat.vision.detection import Detections

__all__ = ["FOLDER", "physical_views"]

FOLDER = "camera"
"""The frames' folder in the output folder."""


def physical_views(config: StudyConfig, designs: Mapping[str, Design], out_dir: Path | None,
                   spec: TrackingSpec | None = None, count: int = 3) -> JsonDict:
    """results.json ``physical_views`` for ``designs`` = {name: (shape, holes)} (module docstring); ``spec``: the
    ``[tracking]`` settings (its ``spp`` and seed; default the study's); ``out_dir``: where ``camera/`` goes (None:
    frames not written)."""
    from cadfeat.study.tracking import (  # (the closed loop's own scene and hole names)
        _named,  # pyright: ignore[reportPrivateUsage]
        _scene,  # pyright: ignore[reportPrivateUsage]
    )
    from cadfeat.vision.closed_loop import report_frames

    spec = (spec or config.tracking_settings()).replace(renderer="pbr")
    tc = spec.in_cell(config.cell)
    camera, T_cam_part, times, _ = _scene(config)
    idx = report_frames(len(T_cam_part), count)
    t0 = time.perf_counter()
    frames: list[JsonDict] = []
    for name, (shape, holes) in designs.items():
        frames += _design_frames(name, shape, _named(holes), camera, T_cam_part[idx], times[idx], idx, tc, out_dir)
    cell = config.cell
    return {"light": cell.light.kind, "material": cell.material.name, "hole_ends": cell.hole_ends,
            "detector": cell.detector, "spp": spec.spp, "noise_grey": cell.noise_sigma_grey, "frames": frames,
            "seconds": round(time.perf_counter() - t0, 2)}


def _design_frames(name: str, shape: Shape, holes: Sequence[Hole], camera: Camera, T: np.ndarray, times: np.ndarray,
                   idx: list[int], tc: TrackingConfig, out_dir: Path | None) -> list[JsonDict]:
    """One design's frames: rendered, detected, drawn and written (module docstring)."""
    from cadfeat.study.tracking import write_frame
    from cadfeat.vision.closed_loop import detect_sequence, expected_visible, frame_image, observe

    obs = observe(shape, holes, camera, T, tc.sensor, None, renderer="pbr", render_options=tc.render_options())
    seed = tc.seed * 1000
    pixels, dets = detect_sequence(obs, tc.sensor.noise_grey, seed, tc.gate_px, 1.0, tc.detector)
    expected = expected_visible(camera, obs, T)
    found = np.all(np.isfinite(pixels), axis=-1)
    out: list[JsonDict] = []
    for j, k in enumerate(idx):
        entry: JsonDict = {
            "design": name, "frame": int(k), "time_s": float(times[j]),
            "expected": [n for n, e in zip(obs.names, expected[j], strict=True) if e],
            "detected": [n for n, e, f in zip(obs.names, expected[j], found[j], strict=True) if e and f],
            "missed": [n for n, e, f in zip(obs.names, expected[j], found[j], strict=True) if e and not f]}
        if out_dir is not None:
            image = frame_image(camera, obs, j, tc.sensor.noise_grey, seed)
            drawn = _drawn(image, obs.predicted[j], obs.names, dets[j], pixels[j], expected[j] & ~found[j])
            entry["path"] = write_frame(out_dir, FOLDER, f"{name}_frame_{k:03d}.png", drawn)
        out.append(entry)
    return out


def _drawn(image: np.ndarray, predicted: Ellipse, names: list[str], detections: Detections, pixels: np.ndarray,
           missed: np.ndarray) -> np.ndarray:
    """``closed_loop.draw_frame`` (predicted rims red, detections green, associated centres yellow) with each
    missed hole's name written in red beside its predicted rim."""
    import cv2

    from cadfeat.vision.closed_loop import draw_frame

    rgb = draw_frame(image, predicted, detections, pixels)
    centres = np.asarray(predicted.centre_px, float)
    for j in np.flatnonzero(missed):
        u, v = centres[j]
        cv2.putText(rgb, f"{names[j]} missed", (int(u) + 8, int(v) - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                    (230, 40, 40), 1, cv2.LINE_AA)
    return rgb
