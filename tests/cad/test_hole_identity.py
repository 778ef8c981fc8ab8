"""Hole identity (``cadfeat.cad.features.identity``): names, the one pairing function, holes at a design.

References are planted: a known permutation of exact holes (with small perturbations well inside the
tolerances) must be recovered; a through hole reported from its other end (centre moved by its depth along
the axis, axis reversed) pairs only along the axis line; an inadmissible candidate is refused by name.
"""

from __future__ import annotations

import numpy as np
import pytest

from cadfeat.cad.features import Hole, match_holes
from cadfeat.cad.features.identity import hole_names, holes_at, named, pair_holes, take_names
from cadfeat.errors import CadfeatError


def _hole(x: float, y: float, r: float = 2.0, name: str = "", axis=(0.0, 0.0, 1.0), depth: float = 5.0) -> Hole:
    return Hole(np.array([x, y, 5.0]), np.array(axis, float), r, r, depth, True, "plain", 0, None, name)


REFERENCE = [_hole(0, 0, name="A"), _hole(10, 0), _hole(0, 10, r=3.0), _hole(10, 10, name="D")]


def test_names_default_to_their_place():
    assert hole_names(REFERENCE) == ["A", "H2", "H3", "D"]
    assert [h.name for h in named(REFERENCE)] == ["A", "H2", "H3", "D"]


def test_a_permutation_is_recovered_and_names_follow_the_holes():
    perm = [2, 0, 3, 1]
    rng = np.random.default_rng(0)
    candidates = [_hole(*(REFERENCE[k].centre[:2] + rng.normal(0, 0.01, 2)), r=REFERENCE[k].radius_mm)
                  for k in perm]
    idx = pair_holes(REFERENCE, candidates)
    assert [perm[i] for i in idx] == [0, 1, 2, 3]
    assert list(match_holes(REFERENCE, candidates)) == list(idx)  # the public name is the same function
    assert [h.name for h in take_names(REFERENCE, candidates, idx)] == ["A", "", "", "D"]


def test_a_through_hole_seen_from_its_other_end_pairs_along_its_axis():
    flipped = [_hole(h.centre[0], h.centre[1], h.radius_mm, axis=(0.0, 0.0, -1.0)) for h in REFERENCE[::-1]]
    flipped = [Hole(h.centre - np.array([0, 0, 5.0]), h.axis, h.radius_mm, h.bore_radius_mm, 5.0, True, "plain",
                    0, None) for h in flipped]
    with pytest.raises(CadfeatError, match="reference hole A"):
        pair_holes(REFERENCE, flipped)  # 5 mm away and reversed: not the same hole for the plain pairing
    assert list(pair_holes(REFERENCE, flipped, 1e-3, along_axis=True)) == [3, 2, 1, 0]


def test_no_admissible_candidate_names_the_hole():
    far = [_hole(0, 0), _hole(10, 0), _hole(0, 10, r=3.0), _hole(11, 10)]
    with pytest.raises(CadfeatError, match=r"check: reference hole D .* no candidate"):
        pair_holes(REFERENCE, far, what="check")


def test_holes_at_a_design():
    class Model:
        holes = REFERENCE

        @staticmethod
        def features(x):
            n = len(REFERENCE)
            return (np.array([h.centre for h in REFERENCE]) + x[0], np.tile([0.0, 0.0, 1.0], (n, 1)),
                    np.full(n, x[1]))

    out = holes_at(Model, np.array([1.0, 4.0]))
    np.testing.assert_allclose(out[1].centre, [11.0, 1.0, 6.0])
    assert [h.radius_mm for h in out] == [4.0] * 4 and [h.name for h in out] == ["A", "", "", "D"]


def test_unbounded_pairing_follows_holes_moved_far_and_leaves_extras_unpaired():
    """``bounded=False`` (Part.name_holes: the default build vs a build at other parameters): holes moved by a
    parameter well past any tolerance (a uniform 3 mm shift, planted permutation) keep their pairing; a hole
    flipped end for end still pairs (sign-free axis term); the hole with no counterpart is left unpaired."""
    perm = [3, 1, 0, 2]
    moved = [_hole(*(REFERENCE[k].centre[:2] + 3.0), r=REFERENCE[k].radius_mm,
                   axis=(0.0, 0.0, -1.0) if k == 1 else (0.0, 0.0, 1.0)) for k in perm]
    with pytest.raises(CadfeatError):
        pair_holes(REFERENCE, moved)  # 4.2 mm away: not the same holes for the bounded pairing
    assert [perm[i] for i in pair_holes(REFERENCE, moved, bounded=False)] == [0, 1, 2, 3]
    three = [moved[i] for i in (0, 1, 3)]  # REFERENCE[0] has no counterpart
    idx = pair_holes(REFERENCE, three, bounded=False)
    assert idx[0] == -1 and [perm[(0, 1, 3)[i]] for i in idx[1:]] == [1, 2, 3]
