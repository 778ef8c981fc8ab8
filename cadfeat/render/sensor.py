"""The sensor after the light: exposure, shot and read noise, saturation and quantisation of a radiance image.

``render.pbr`` returns linear radiance (a white Lambertian face lit by the light's ``intensity`` 1 reads 1.0).
A camera turns it into grey levels:

1. **exposure**: ``grey = gain · radiance`` on the 8-bit scale (0 … 255 = full scale whatever the bit depth).
   ``exposure="fixed"``: ``gain`` as given (grey levels per unit radiance). ``exposure="auto"``: the gain puts
   the ``auto_percentile``-th percentile of the frame's radiance (the brightest lit faces; specular highlights
   above it saturate, as in a real auto-exposed frame) at ``auto_fraction`` of full scale. ``exposure="meter"``:
   the median radiance of the part (the pixels above ``METER_FLOOR`` of the median of the lit pixels: the
   cell's background is black; under a dome or ambient light it is metered too) at ``meter_fraction`` of full
   scale — an averaging meter on the part, as an engineer sets a cell's exposure: it follows the faces, which
   fill the part's image, not a hole's highlight (a small bright blind hole saturates instead of darkening the
   part), so two designs of one part get the same exposure.
2. **saturation**: the well holds at most full scale: clip to 0 … 255.
3. **shot noise**: the signal in electrons, ``grey / 255 · full_well_e``, is Poisson distributed (none when
   ``full_well_e`` = 0); **read noise**: additive Gaussian of σ ``read_noise_grey`` grey levels (8-bit scale).
4. **quantisation**: clip again and round to the ``bits``-bit code ``round(grey / 255 · (2^bits − 1))``;
   ``capture`` returns the codes back on the 0 … 255 scale (float32, what the detectors and the closed loop
   read; ``codes=True``: the integer codes, uint8 or uint16).

Deterministic: the noise of frame k comes from ``numpy.random.default_rng([seed, k])``.
"""

from __future__ import annotations

from typing import Self

import numpy as np
from pydantic import model_validator

from cadfeat.settings import Settings, choice, integer, number, reject

__all__ = ["Sensor", "capture", "expose", "exposure_gain"]

FULL_SCALE_GREY = 255.0
#: Metered exposure: a pixel belongs to the part when its radiance exceeds this fraction of the median of the lit
#: pixels (path-tracing noise in the black background stays below it).
METER_FLOOR = 1e-3


class Sensor(Settings):
    """Exposure, noise, saturation and bit depth of the camera's sensor (module docstring; grey levels on the
    8-bit scale whatever ``bits``)."""

    section = "sensor"

    exposure: str = choice("auto", ("auto", "fixed", "meter"),
                           description="auto: percentile to a fraction; fixed: gain; meter: the part's median")
    gain: float = number(200.0, 0.0, lo_open=True, description="fixed exposure: grey levels per unit radiance")
    auto_fraction: float = number(0.8, 0.0, 1.0, lo_open=True, description="auto: level of the percentile")
    auto_percentile: float = number(99.0, 0.0, 100.0, lo_open=True, description="auto: percentile of radiance")
    meter_fraction: float = number(0.45, 0.0, 1.0, lo_open=True, description="meter: level of the part's median")
    full_well_e: float = number(10000.0, 0.0, description="electrons at full scale (shot noise); 0: none")
    read_noise_grey: float = number(1.0, 0.0, description="σ of the read noise, grey levels (8-bit scale)")
    bits: int = choice(8, "8 or 12", description="bit depth of the codes")
    seed: int = integer(0, 0, description="noise seed (frame k uses default_rng([seed, k]))")

    @model_validator(mode="after")
    def _bit_depth(self) -> Self:
        if self.bits not in (8, 12):
            raise reject("bits", f"{self.bits} is not allowed", "8 or 12")
        return self


def exposure_gain(radiance: np.ndarray, sensor: Sensor) -> float:
    """Grey levels per unit radiance for ``radiance`` (H, W) under ``sensor``'s exposure (module docstring)."""
    if sensor.exposure == "fixed":
        return sensor.gain
    if sensor.exposure == "meter":
        r = np.asarray(radiance, dtype=np.float64)
        lit = r[r > 0]
        part = lit[lit > METER_FLOOR * float(np.median(lit))] if lit.size else lit
        level = float(np.median(part)) if part.size else 0.0
        return sensor.gain if level <= 0 else sensor.meter_fraction * FULL_SCALE_GREY / level
    level = float(np.percentile(radiance, sensor.auto_percentile))
    return sensor.gain if level <= 0 else sensor.auto_fraction * FULL_SCALE_GREY / level


def expose(radiance: np.ndarray, sensor: Sensor, gain: float | None = None) -> np.ndarray:
    """Noiseless grey (H, W) float32 in 0 … 255: ``gain`` (default ``exposure_gain``) × radiance, saturated."""
    g = exposure_gain(radiance, sensor) if gain is None else gain
    return np.clip(np.asarray(radiance, np.float32) * np.float32(g), 0.0, FULL_SCALE_GREY).astype(np.float32)


def capture(radiance: np.ndarray, sensor: Sensor, frame: int = 0, *, gain: float | None = None,
            codes: bool = False) -> np.ndarray:
    """The sensor's frame ``frame`` of ``radiance`` (H, W): exposed, with shot and read noise, saturated and
    quantised; grey on the 0 … 255 scale (float32) or, ``codes=True``, the ``bits``-bit integer codes."""
    grey = expose(radiance, sensor, gain)
    rng = np.random.default_rng([sensor.seed, int(frame)])
    if sensor.full_well_e > 0:
        per_grey = sensor.full_well_e / FULL_SCALE_GREY                     # electrons per grey level
        grey = (rng.poisson(grey.astype(np.float64) * per_grey) / per_grey).astype(np.float32)
    if sensor.read_noise_grey > 0:
        grey = grey + rng.standard_normal(grey.shape, dtype=np.float32) * np.float32(sensor.read_noise_grey)
    top = (1 << sensor.bits) - 1
    q = np.rint(np.clip(grey, 0.0, FULL_SCALE_GREY) * (top / FULL_SCALE_GREY))
    if codes:
        return q.astype(np.uint8 if sensor.bits == 8 else np.uint16)
    return (q * (FULL_SCALE_GREY / top)).astype(np.float32)
