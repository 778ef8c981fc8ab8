"""Lost PnP frames (``measures.lost_frames``) against a Monte-Carlo of the closed loop's rule.

Independent detections (Bernoulli per hole and frame) are drawn; a frame with fewer than 4 holes has no pose
and holds the previous frame's estimate (``vision.metrics.hold_last``'s rule, written out here): its error is the
truth's motion plus the held estimate's error, in a random direction. The share of lost frames and the RMS errors
per frame agree with ``lost_share`` / ``held_errors`` within the Monte-Carlo's scatter.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from cadfeat.measures.lost_frames import frame_motion, held_errors, lost_share


def _path(L: int) -> np.ndarray:
    T = np.tile(np.eye(4), (L, 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(np.outer(np.linspace(0, 0.3, L), [0.2, 1.0, 0.1])).as_matrix()
    T[:, :3, 3] = np.stack([np.linspace(-20, 20, L), np.linspace(0, 5, L), np.full(L, 300.0)], axis=1)
    return T


def test_lost_share_is_the_poisson_binomial_tail():
    rng = np.random.default_rng(0)
    p = rng.uniform(0.3, 1.0, (6, 7))
    draws = rng.random((200_000, 6, 7)) < p
    mc = (draws.sum(axis=-1) < 4).mean(axis=0)
    np.testing.assert_allclose(lost_share(p), mc, atol=0.005)
    assert abs(lost_share(np.ones((2, 4)))[0]) < 1e-12 and abs(lost_share(np.ones((2, 3)))[0] - 1) < 1e-12


def test_frame_motion_is_the_relative_pose_step():
    T = _path(5)
    dt, dr = frame_motion(T)
    step = np.linalg.inv(T[1]) @ T[2]  # same relative rotation angle as R2 R1ᵀ
    assert dt[2] == np.linalg.norm(T[2, :3, 3] - T[1, :3, 3])
    assert np.isclose(dr[2], np.degrees(np.linalg.norm(Rotation.from_matrix(step[:3, :3]).as_rotvec())))


def test_held_errors_match_a_monte_carlo_of_held_frames():
    L, N, runs = 12, 5, 40_000
    rng = np.random.default_rng(1)
    T = _path(L)
    p = np.clip(rng.uniform(0.6, 1.0, (L, N)), 0, 1)
    p[5:8, :2] = 0.1                                     # a stretch where two holes are rarely seen
    et, er = rng.uniform(0.05, 0.1, L), rng.uniform(0.03, 0.06, L)
    t, r, lost = held_errors(T, p, et, er)
    mt, mr = frame_motion(T)
    ok = (rng.random((runs, L, N)) < p).sum(axis=-1) >= 4
    # per run: a frame with a pose has an error of RMS e_k (random direction in 3-D); a lost frame holds the
    # previous frame's estimate, whose error adds to the truth's motion in an independent direction
    def unit(shape):
        v = rng.normal(size=shape + (3,))
        return v / np.linalg.norm(v, axis=-1, keepdims=True)
    own_t, own_r = et[None, :, None] * unit((runs, L)), er[None, :, None] * unit((runs, L))
    move_t, move_r = mt[None, :, None] * unit((runs, L)), mr[None, :, None] * unit((runs, L))
    prev_t = np.concatenate([own_t[:, :1], own_t[:, :-1]], axis=1)
    prev_r = np.concatenate([own_r[:, :1], own_r[:, :-1]], axis=1)
    sim_t = np.where(ok[..., None], own_t, prev_t + move_t)
    sim_r = np.where(ok[..., None], own_r, prev_r + move_r)
    np.testing.assert_allclose(lost, 1 - ok.mean(axis=0), atol=0.01)
    np.testing.assert_allclose(t, np.sqrt(np.mean(np.sum(sim_t ** 2, -1), axis=0)), rtol=0.03)
    np.testing.assert_allclose(r, np.sqrt(np.mean(np.sum(sim_r ** 2, -1), axis=0)), rtol=0.03)
