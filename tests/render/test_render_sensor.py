"""The sensor after the light (``render.sensor``): exposure, noise statistics, saturation, bit depth, seeding.

References: the Poisson law (variance = mean, in electrons) plus the Gaussian read noise's σ², measured on a flat
field of 200 000 pixels; the exposure's definition (a percentile to a fraction of full scale).
"""

from __future__ import annotations

import numpy as np
import pytest

from cadfeat.errors import CadfeatError
from cadfeat.render.sensor import Sensor, capture, expose, exposure_gain


def test_auto_exposure_puts_the_percentile_at_the_fraction():
    radiance = np.linspace(0.0, 2.0, 10001, dtype=np.float32).reshape(1, -1)
    s = Sensor(auto_fraction=0.5, auto_percentile=50.0)
    assert exposure_gain(radiance, s) == pytest.approx(0.5 * 255 / 1.0, rel=1e-4)
    grey = expose(radiance, Sensor(exposure="fixed", gain=200.0))
    assert grey.max() == 255.0 and grey[0, 2500] == pytest.approx(100.0, rel=1e-3)    # saturated, linear below


def test_noise_statistics_and_quantisation():
    flat = np.full((400, 500), 0.5, np.float32)
    s = Sensor(exposure="fixed", gain=200.0, full_well_e=5000.0, read_noise_grey=1.5, bits=12, seed=3)
    grey = capture(flat, s, frame=0)
    per_grey = 5000.0 / 255.0
    expected_var = 100.0 / per_grey + 1.5 ** 2 + (255.0 / 4095) ** 2 / 12       # shot + read + quantisation
    assert grey.mean() == pytest.approx(100.0, abs=0.02)
    assert grey.var() == pytest.approx(expected_var, rel=0.02)
    codes = capture(flat, s, frame=0, codes=True)
    assert codes.dtype == np.uint16 and codes.max() <= 4095
    np.testing.assert_allclose(codes * (255.0 / 4095), grey, atol=1e-4)
    eight = capture(flat, s.replace(bits=8), codes=True)
    assert eight.dtype == np.uint8


def test_deterministic_per_seed_and_frame():
    img = np.random.default_rng(0).random((50, 60)).astype(np.float32)
    s = Sensor(seed=7)
    np.testing.assert_array_equal(capture(img, s, 2), capture(img, s, 2))
    assert not np.array_equal(capture(img, s, 2), capture(img, s, 3))
    assert not np.array_equal(capture(img, s, 2), capture(img, s.replace(seed=8), 2))


def test_bad_settings_are_refused():
    with pytest.raises(CadfeatError, match="sensor.bits"):
        Sensor(bits=10)
    with pytest.raises(CadfeatError, match="sensor.exposure"):
        Sensor(exposure="manual")


def test_metered_exposure_follows_the_part_not_a_hole_highlight():
    """``exposure="meter"``: the part's median radiance lands at ``meter_fraction`` of full scale whatever a small
    highlight does (a mirror-bright blind hole saturates instead of darkening the part); the black background is
    not metered."""
    from cadfeat.render.sensor import Sensor, expose

    frame = np.zeros((100, 100), np.float32)
    frame[20:80, 20:80] = 0.04                      # a dim machined face
    plain = expose(frame, Sensor(exposure="meter"))
    frame[45:50, 45:50] = 40.0                       # a blind hole's floor mirroring the ring light
    lit = expose(frame, Sensor(exposure="meter"))
    assert plain[30, 30] == pytest.approx(0.45 * 255, rel=1e-6) and lit[30, 30] == pytest.approx(0.45 * 255, rel=1e-6)
    assert lit[47, 47] == 255.0 and lit[0, 0] == 0.0
