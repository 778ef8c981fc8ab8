"""Posterior Cramér–Rao bound of the thesis's constant-velocity pose filter (ch. 6), from per-frame pose information.

The information recursion of Tichavský, Muravchik and Nehorai (1998) for the 12-state constant-velocity model of
``vision.motion`` (error state δ = (δp mm, δθ rad, δv mm/s, δω rad/s)):

.. math::  J_k = (Q_k + F_k J_{k-1}^{-1} F_k^T)^{-1} + \begin{bmatrix} I_k & 0 \\ 0 & 0 \\end{bmatrix},
           \\qquad J_0 = P_0^{-1} + [I_0],

with :math:`I_k` the Fisher information of the pose from frame k's measurements
(``cadfeat.measures.pose_information``), F_k the transition Jacobian and Q_k the process noise of the filter's
own tuning (``FilterTuning``). :math:`J_k^{-1}` bounds the covariance of any unbiased tracker of this model; the
EKF/IEKF of ``vision.estimate`` reach it on noise-only data (tests).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.errors import CadfeatError
from cadfeat.vision.estimate import FilterTuning
from cadfeat.vision.motion import PoseState, predict, process_noise

__all__ = ["posterior_crlb"]


def posterior_crlb(information: ArrayLike, times_s: ArrayLike, tuning: FilterTuning | None = None,
                   omega_rad_s: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Posterior CRLB of the constant-velocity filter along the trajectory (module docstring).

    information : (..., L, 6, 6) per-frame measurement information I_k
        (``cadfeat.measures.PoseInformation.information``, without a prior), δ = (δp mm, δθ rad); leading axes
        batch independent trajectories (e.g. Monte-Carlo truths).
    times_s : (L,) increasing frame times, s.
    tuning : ``vision.FilterTuning`` (P₀, Q: ``q_rate_mm2_s2``, ``q_omega_rad2_s2``, ``q_pose_*``); default
        the closed loop's.
    omega_rad_s : (..., L, 3) the true angular rates (camera frame) for F_k (``motion.predict``); None = 0.

    Returns (bound (..., L, 12, 12) on the filter's error-state covariance, (..., L, 2) the √tr of its
    translation and rotation blocks as (σ_t mm, σ_r deg)).
    """
    I_ = np.asarray(information, dtype=float)
    t = np.asarray(times_s, dtype=float)
    L = len(t)
    if I_.shape[-3:] != (L, 6, 6) or t.ndim != 1 or np.any(np.diff(t) <= 0):
        raise CadfeatError(f"posterior_crlb: information (..., L, 6, 6) and increasing times_s (L,) must agree, "
                           f"got {I_.shape}, {t.shape}")
    tuning = tuning or FilterTuning()
    Q = process_noise(0.0, tuning.q_rate_mm2_s2, tuning.q_omega_rad2_s2, (tuning.q_pose_mm2, tuning.q_pose_rad2))
    batch = I_.shape[:-3]
    w = np.zeros(batch + (L, 3)) if omega_rad_s is None else np.broadcast_to(np.asarray(omega_rad_s, float),
                                                                              batch + (L, 3))
    H = np.zeros(batch + (L, 12, 12))
    H[..., :6, :6] = I_
    P = np.linalg.inv(np.linalg.inv(tuning.P0()) + H[..., 0, :, :])
    out = np.empty(batch + (L, 12, 12))
    out[..., 0, :, :] = P
    eye = np.broadcast_to(np.eye(4), batch + (4, 4))
    for k in range(1, L):  # the time recursion (sequential by nature), batched over the leading axes
        state = PoseState.at_rest(eye)
        state.omega_rad_s = np.array(w[..., k - 1, :])
        _, F = predict(state, float(t[k] - t[k - 1]))
        P_pred = F @ P @ np.swapaxes(F, -1, -2) + Q
        P = np.linalg.inv(np.linalg.inv(P_pred) + H[..., k, :, :])
        P = 0.5 * (P + np.swapaxes(P, -1, -2))
        out[..., k, :, :] = P
    sig = np.stack([np.sqrt(np.trace(out[..., :3, :3], axis1=-2, axis2=-1)),
                    np.degrees(np.sqrt(np.trace(out[..., 3:6, 3:6], axis1=-2, axis2=-1)))], axis=-1)
    return out, sig
