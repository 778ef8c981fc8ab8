"""Lost frames count against a design (issue 17): a frame without an estimate is scored at the error of the last
estimate before it (the pose the robot still holds), never left out.

References are closed forms of a scene built by hand: the part moves 1 mm per frame along x, so a held estimate
is off by exactly the distance travelled since it was made; the estimates elsewhere carry a known error.
"""

from __future__ import annotations

import numpy as np

from cadfeat.vision.metrics import hold_last, paired_verdict, pose_errors, run_summary

F_, STEP_MM = 20, 1.0


def _truth() -> np.ndarray:
    T = np.tile(np.eye(4), (F_, 1, 1))
    T[:, 0, 3] = STEP_MM * np.arange(F_)
    T[:, 2, 3] = 300.0
    return T


def _estimates(seed: int) -> np.ndarray:
    """The truth with a random 0.05–0.15 mm translation error per frame (no rotation error)."""
    rng = np.random.default_rng(seed)
    T = _truth()
    d = rng.standard_normal((F_, 3))
    T[:, :3, 3] += (0.05 + 0.1 * rng.random(F_))[:, None] * d / np.linalg.norm(d, axis=1, keepdims=True)
    return T


def _lose(T: np.ndarray, frames: list[int]) -> np.ndarray:
    out = T.copy()
    out[frames] = np.nan
    return out


def _summary(T_est: np.ndarray, T0: np.ndarray) -> dict[str, float]:
    held, lost = hold_last(T_est, T0)
    et, er = pose_errors(held, _truth())
    return run_summary(et, er, np.arange(F_) * 0.1, 2, 2.0, 1.0, lost)


def test_held_estimate_error_is_the_distance_travelled():
    T = _estimates(0)
    T0 = _truth()[0].copy()
    T0[1, 3] += 3.0                                   # the initial pose: 3 mm off in y
    lost_frames = [0, 1, 7, 8, 9]
    held, lost = hold_last(_lose(T, lost_frames), T0)
    np.testing.assert_array_equal(np.flatnonzero(lost), lost_frames)
    et, _ = pose_errors(held, _truth())
    np.testing.assert_allclose(et[[0, 1]], np.hypot(STEP_MM * np.array([0, 1]), 3.0))   # initial pose held
    p6 = T[6, :3, 3]
    for k in (7, 8, 9):                                # frame 6's estimate held against the moving truth
        np.testing.assert_allclose(et[k], np.linalg.norm(p6 - _truth()[k, :3, 3]))
    np.testing.assert_allclose(held[~lost], T[~lost])


def test_a_track_with_lost_frames_scores_worse_than_the_same_track_without():
    """Losing the frames whose estimates were worst would *lower* an RMS that leaves them out; counted at the
    held estimate's error it rises, and the lost fraction is reported."""
    T = _estimates(1)
    T0 = _truth()[0]
    et_full, _ = pose_errors(T, _truth())
    worst = sorted(int(k) for k in np.argsort(et_full[2:])[-4:] + 2)     # the 4 worst frames after settling
    full, partial = _summary(T, T0), _summary(_lose(T, worst), T0)
    tail = np.delete(et_full[2:], np.array(worst) - 2)
    assert np.sqrt(np.mean(tail ** 2)) < full["trans_mm_rms"]            # the old rule would have rewarded it
    assert partial["trans_mm_rms"] > full["trans_mm_rms"]
    assert partial["trans_mm_max"] >= STEP_MM - 0.3                      # at least one frame's travel, minus noise
    assert full["lost_frac"] == 0.0 and full["frames_lost"] == 0.0
    assert partial["lost_frac"] == len(worst) / (F_ - 2) and partial["frames_lost"] == len(worst)


def test_paired_comparison_counts_lost_frames():
    """Same runs, the 'after' design loses 3 frames per run: the paired test calls it worse."""
    before, after = [], []
    for run in range(10):
        T = _estimates(100 + run)
        before.append(_summary(T, _truth()[0])["trans_mm_rms"])
        after.append(_summary(_lose(T, [5 + run % 4, 10, 15]), _truth()[0])["trans_mm_rms"])
    assert paired_verdict(np.array(before), np.array(after), min_change=0.05)["verdict"] == "worse"


def test_run_summary_without_a_fallback_reports_lost_frames():
    T = _lose(_estimates(2), [4, 5])
    et, er = pose_errors(T, _truth())
    s = run_summary(et, er, np.arange(F_) * 0.1, 2, 2.0, 1.0)
    assert s["frames_lost"] == 2.0 and s["lost_frac"] == 2 / (F_ - 2) and np.isfinite(s["trans_mm_rms"])
