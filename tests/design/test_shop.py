"""Shop rounding (cadfeat.design.shop) on a hand-made linear feature model, against values worked out here."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from cadfeat.design.design_space import DesignSpace, Variable
from cadfeat.design.shop import ISO_273, rounding_candidates, shop_design, snap_diameters


class RowModel:
    """Three holes in a row on z = 0: centres (x0 + i·pitch, y0, 0), common radius r (variables x0, y0, pitch, r)."""

    holes = [None] * 3

    def features_batch(self, X):
        X = np.atleast_2d(X)
        i = np.arange(3)
        c = np.stack([X[:, :1] + i * X[:, 2:3], np.repeat(X[:, 1:2], 3, 1), np.zeros((len(X), 3))], axis=-1)
        a = np.broadcast_to([0.0, 0.0, 1.0], c.shape)
        return c, a, np.repeat(X[:, 3:4], 3, 1)

    def features(self, x):
        c, a, r = self.features_batch(np.asarray(x)[None])
        return c[0], a[0], r[0]


SPACE = DesignSpace([Variable("x0", -20, 0), Variable("y0", -10, 10), Variable("pitch", 6, 14),
                     Variable("r", 1.0, 3.0, kind="diameter")], np.array([-10.0, 5.0, 10.0, 2.0]))


class Limit:
    """A problem whose only requirement is x0 ≤ −7.04 and whose objective prefers x0 near −7.04."""

    def evaluate_batch(self, X):
        X = np.atleast_2d(X)
        return -np.abs(X[:, :1] + 7.04), (-7.04 - X[:, :1])

    def constraints(self, x):
        return self.evaluate_batch(x)[1][0]

    def combined_from(self, G):
        return np.asarray(G)[..., 0]


def test_snap_and_round_a_row():
    assert snap_diameters(np.array([2.906, 4.03, 5.0, 5.05]), ISO_273["medium"]).tolist() == [2.9, 4.5, 4.5, 5.5]
    sd = shop_design(SPACE, RowModel(), np.array([-7.0423, 7.6287, 7.0449, 2.0139]))
    c, _, r = RowModel().features(sd.x)
    np.testing.assert_allclose(c[:, :2], [[-7.0, 7.6], [0.0, 7.6], [7.0, 7.6]], atol=1e-9)
    np.testing.assert_allclose(2 * r, 4.5, atol=1e-9)  # Ø4.028 → M4 clearance 4.5 (ISO 273 medium)
    assert sd.residual_mm < 1e-9 and sd.moved.all() and sd.resized.all()


def test_candidates_are_every_floor_ceil_combination():
    x = np.array([-7.04, 7.63, 7.06, 2.0])
    cands = rounding_candidates(SPACE, x, 0.1)
    np.testing.assert_allclose(cands[0][:3], [-7.0, 7.6, 7.1], atol=1e-12)  # nearest first
    brute = {tuple(np.round(v, 9)) for v in itertools.product([-7.1, -7.0], [7.6, 7.7], [7.0, 7.1], [2.0])}
    assert {tuple(np.round(v, 9)) for v in cands[1:]} == brute


def test_nearest_rounding_that_breaks_a_requirement_rounds_the_other_way():
    x = np.array([-7.0423, 7.6287, 7.0449, 2.0])
    assert shop_design(SPACE, RowModel(), x).x[0] == pytest.approx(-7.0)  # nearest: breaks x0 ≤ −7.04
    sd = shop_design(SPACE, RowModel(), x, problem=Limit())
    assert sd.x[0] == pytest.approx(-7.1) and any("other way" in n for n in sd.notes)
