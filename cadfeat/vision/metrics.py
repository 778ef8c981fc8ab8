"""Tracking metrics: pose errors, their summary after convergence, Monte-Carlo intervals and the paired test.

- Errors per frame (thesis §6.3.3 measures the error in Cartesian space): translation error ‖p̂ − p‖ (mm)
  and rotation error, the angle of R̂ Rᵀ (deg), of T_cam_part.
- Lost frames (no estimate: PnP with fewer than 4 holes, a filter that failed) count against the design: at
  a lost frame the robot can only act on the pose it last knew, so ``hold_last`` replaces the missing
  estimate by the previous frame's estimate (the initial pose before the first one) and the frame's error is
  that held pose's error against the *current* true pose. The statistics below are over every frame after
  ``settle_frames``, lost ones included at that error (issue 17: leaving them out rewarded a design for
  losing the part at the poses it images worst); ``frames_lost`` and ``lost_frac`` say how many.
- Summary of one run after ``settle_frames`` frames (the thesis's "steady state in the first five sampling
  periods"): RMS, 95th percentile, max. Convergence time: the first time after which the translation error
  stays ≤ ``converged_mm`` and the rotation error ≤ ``converged_deg`` (inf if never; a lost frame is not
  converged).
- Over Monte-Carlo runs: mean of each per-run number with a percentile-bootstrap confidence interval
  (seeded, so reports are reproducible).
- Before vs after: Wilcoxon signed-rank test on the per-run RMS errors, paired by run (same noise seed and
  initial error for both designs); a verdict only when the difference is significant at ``alpha``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.vision.motion import so3_log

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import IntervalData, PairedTestData


def pose_errors(T_est: np.ndarray, T_true: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(translation error mm, rotation error deg), each (..., ) for poses (..., 4, 4); NaN where T_est is NaN."""
    T_est = np.asarray(T_est, dtype=float)
    T_true = np.asarray(T_true, dtype=float)
    dt = np.linalg.norm(T_est[..., :3, 3] - T_true[..., :3, 3], axis=-1)
    finite = np.all(np.isfinite(T_est.reshape(T_est.shape[:-2] + (16,))), axis=-1)
    dR = np.where(finite[..., None, None], T_est[..., :3, :3], np.eye(3)) @ np.swapaxes(T_true[..., :3, :3], -1, -2)
    ang = np.degrees(np.linalg.norm(so3_log(dR), axis=-1))
    return np.where(finite, dt, np.nan), np.where(finite, ang, np.nan)


def hold_last(T_est: np.ndarray, T_initial: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The estimates with each lost frame (non-finite pose) replaced by the last finite one before it, and the
    lost mask. T_est (..., F, 4, 4); T_initial (..., 4, 4), the estimators' initial pose, stands in before the
    first estimate. Returns (T_held (..., F, 4, 4), lost (..., F) bool)."""
    T = np.array(T_est, dtype=float)
    lost = ~np.all(np.isfinite(T.reshape(T.shape[:-2] + (16,))), axis=-1)
    F_ = T.shape[-3]
    # index of the last finite frame at or before k (-1: none yet), vectorised over the leading axes
    idx = np.where(~lost, np.arange(F_), -1)
    last = np.maximum.accumulate(idx, axis=-1)
    src = np.concatenate([np.broadcast_to(np.asarray(T_initial, dtype=float)[..., None, :, :],
                                          T.shape[:-3] + (1, 4, 4)), T], axis=-3)
    held = np.take_along_axis(src, (last + 1)[..., None, None], axis=-3)
    return held, lost


def convergence_time_s(trans_mm: np.ndarray, rot_deg: np.ndarray, times_s: np.ndarray, converged_mm: float,
                       converged_deg: float) -> float:
    """First time after which both errors stay within the bounds (NaN frames count as not converged)."""
    bad = ~((trans_mm <= converged_mm) & (rot_deg <= converged_deg))
    if not bad.any():
        return float(times_s[0] - times_s[0])
    last_bad = int(np.flatnonzero(bad)[-1])
    return float(times_s[last_bad + 1] - times_s[0]) if last_bad + 1 < len(times_s) else float("inf")


def run_summary(trans_mm: np.ndarray, rot_deg: np.ndarray, times_s: np.ndarray, settle_frames: int,
                converged_mm: float, converged_deg: float, lost: np.ndarray | None = None) -> dict[str, float]:
    """Numbers of one run (module docstring): rms/p95/max of both errors after ``settle_frames``, lost frames
    (``frames_lost`` over the whole run, ``lost_frac`` the fraction of the frames after ``settle_frames``),
    convergence time (s).

    ``lost`` (F,) marks the lost frames when the errors are those of the held estimates (``hold_last``; the
    lost frames then count at that error). Without it, non-finite errors are the lost frames and, having no
    fallback, are left out of the statistics (use ``hold_last`` to count them).
    """
    lost = ~(np.isfinite(trans_mm) & np.isfinite(rot_deg)) if lost is None else np.asarray(lost, dtype=bool)
    t, r = trans_mm[settle_frames:], rot_deg[settle_frames:]
    ok = np.isfinite(t) & np.isfinite(r)
    tail = lost[settle_frames:]
    out: dict[str, float] = {"frames_lost": float(np.sum(lost)),
                             "lost_frac": float(np.mean(tail)) if tail.size else float("nan")}
    for name, e in (("trans_mm", t[ok]), ("rot_deg", r[ok])):
        out[f"{name}_rms"] = float(np.sqrt(np.mean(e * e))) if e.size else float("nan")
        out[f"{name}_p95"] = float(np.percentile(e, 95)) if e.size else float("nan")
        out[f"{name}_max"] = float(np.max(e)) if e.size else float("nan")
    out["convergence_s"] = convergence_time_s(np.where(lost, np.inf, trans_mm), rot_deg, times_s, converged_mm,
                                              converged_deg)
    return out


def bootstrap_ci(values: np.ndarray, level: float = 0.95, n_boot: int = 2000, seed: int = 0) -> tuple[float, float]:
    """Percentile-bootstrap interval of the mean of the finite entries of ``values``."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return float("nan"), float("nan")
    if v.size == 1 or np.all(v == v[0]):
        return float(v[0]), float(v[0])
    rng = np.random.default_rng(seed)
    means = v[rng.integers(0, v.size, size=(n_boot, v.size))].mean(axis=1)
    lo, hi = np.percentile(means, [50 * (1 - level), 50 * (1 + level)])
    return float(lo), float(hi)


def aggregate_runs(runs: Sequence[dict[str, float]], level: float = 0.95) -> dict[str, IntervalData]:
    """Per key over runs: ``mean``, ``ci_low``, ``ci_high`` (bootstrap), ``median`` of the finite values, and
    ``runs_not_finite`` (e.g. runs that never converged, or lost every frame)."""
    out: dict[str, IntervalData] = {}
    for key in runs[0]:
        v = np.array([r[key] for r in runs], dtype=float)
        finite = v[np.isfinite(v)]
        lo, hi = bootstrap_ci(finite, level)
        out[key] = {"mean": float(np.mean(finite)) if finite.size else float("nan"), "ci_low": lo, "ci_high": hi,
                    "median": float(np.median(finite)) if finite.size else float("nan"),
                    "runs_not_finite": int(v.size - finite.size)}
    return out


def paired_verdict(before: np.ndarray, after: np.ndarray, alpha: float = 0.05,
                   min_change: float = 0.0) -> PairedTestData:
    """Wilcoxon signed-rank test of per-run errors ``after − before`` (paired by run), two-sided.

    Returns ``verdict`` ("better" = after lower, "worse", "no significant difference"), ``p_value``,
    ``median_change`` (after − before) and ``test``. Runs with a NaN/inf on either side are dropped. A
    significant change smaller than ``min_change`` × the median error before (a fraction) is reported as
    "no significant difference" too: with little noise the runs differ little, and the test then calls
    differences significant that are far below what matters.
    """
    from scipy.stats import wilcoxon

    b, a = np.asarray(before, dtype=float), np.asarray(after, dtype=float)
    ok = np.isfinite(a) & np.isfinite(b)
    d = a[ok] - b[ok]
    test, runs = "Wilcoxon signed-rank, two-sided, paired by Monte-Carlo run", int(ok.sum())
    if d.size < 5 or np.all(d == 0):
        return {"test": test, "runs": runs, "alpha": alpha, "verdict": "no significant difference", "p_value": 1.0,
                "median_change": float(np.median(d)) if d.size else 0.0}
    p = float(wilcoxon(b[ok], a[ok]).pvalue)
    med = float(np.median(d))
    small = abs(med) < min_change * float(np.median(b[ok]))
    verdict = "no significant difference" if p >= alpha or small else ("better" if med < 0 else "worse")
    return {"test": test, "runs": runs, "alpha": alpha, "verdict": verdict, "p_value": p, "median_change": med,
            "min_change": min_change}
