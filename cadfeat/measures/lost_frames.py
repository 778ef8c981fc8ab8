"""Frames a single-frame estimator loses, and what they cost: PnP needs four detected holes.

``cv2.solvePnP`` gives no pose from fewer than ``MIN_HOLES`` = 4 measured holes; the closed loop then holds the
last estimate (``vision.metrics.hold_last``), whose error at frame k is about the part's motion in the camera
frame since the last frame on top of that estimate's own error. The pose prediction (``pose_information``) is
the error of a frame *with* a pose. On a part that shows four or five holes per frame, a target the camera
misses half the time decides how many frames are lost — and those frames dominate PnP's RMS error (on the
flagship under physical light one lost frame of 20 puts a run at ~0.46 mm against ~0.09 mm with a pose each
frame; docs/results.md, "Under physical light").

With the holes' detection probabilities p_kj (independent per hole), the number detected at frame k is
Poisson-binomial; its distribution is the product of (1 − p_kj + p_kj z) over the holes, evaluated at the N + 1
roots of unity and transformed back (one FFT over the holes, no loop). P_k = P(fewer than ``MIN_HOLES``). The
expected squared error at frame k of an estimator that holds its last pose when it has none is then

    E[e_k²] = (1 − P_k) e_k² + P_k (m_k² + e_{k−1}²),

m_k the motion between frames k − 1 and k (translation ‖t_k − t_{k−1}‖ mm; rotation the angle of R_k R_{k−1}ᵀ),
e the prediction with a pose (a run of lost frames compounds; the first-order form counts one). Checked against a
Monte-Carlo of Bernoulli detections held as the closed loop holds them (tests/measures/test_lost_frames.py).
"""

from __future__ import annotations

import numpy as np

__all__ = ["MIN_HOLES", "frame_motion", "held_errors", "lost_share"]

#: holes PnP needs for a pose
MIN_HOLES = 4


def lost_share(probability: np.ndarray, min_holes: int = MIN_HOLES) -> np.ndarray:
    """(L,) P(fewer than ``min_holes`` of the N holes detected) per frame, from independent detection
    probabilities (L, N) (module docstring)."""
    p = np.clip(np.nan_to_num(np.asarray(probability, float)), 0.0, 1.0)
    N = int(p.shape[1])
    phase: np.ndarray = 2.0 * np.pi * np.arange(N + 1) / (N + 1)
    z: np.ndarray = np.cos(phase) + 1j * np.sin(phase)                                 # (N + 1,) roots of unity
    g = np.prod(1.0 - p[:, :, None] + p[:, :, None] * z[None, None, :], axis=1)       # (L, N + 1)
    pmf = np.clip(np.real(np.fft.fft(g, axis=1)) / (N + 1), 0.0, 1.0)                 # P(n = 0 … N)
    return np.clip(pmf[:, :min_holes].sum(axis=1), 0.0, 1.0)


def frame_motion(T_cam_part: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(L,) translation (mm) and rotation (deg) of the part in the camera frame since the previous frame (the
    first frame: since the second, the same step)."""
    T = np.asarray(T_cam_part, float)
    dt = np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=-1)
    R = np.einsum("lij,lkj->lik", T[1:, :3, :3], T[:-1, :3, :3])
    cos = np.clip((np.trace(R, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    dr = np.degrees(np.arccos(cos))
    return np.concatenate([dt[:1], dt]), np.concatenate([dr[:1], dr])


def held_errors(T_cam_part: np.ndarray, probability: np.ndarray, error_t: np.ndarray, error_r: np.ndarray,
                min_holes: int = MIN_HOLES) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(translation mm (L,), rotation deg (L,), P_lost (L,)): the RMS error per frame of a single-frame estimator
    that holds its last pose when fewer than ``min_holes`` holes are detected (module docstring), from the poses
    (L, 4, 4), the detection probabilities (L, N) and the errors with a pose (L,)."""
    lost = lost_share(probability, min_holes)
    mt, mr = frame_motion(T_cam_part)
    et, er = np.asarray(error_t, float), np.asarray(error_r, float)
    prev_t, prev_r = np.concatenate([et[:1], et[:-1]]), np.concatenate([er[:1], er[:-1]])
    t = np.sqrt((1 - lost) * et ** 2 + lost * (mt ** 2 + prev_t ** 2))
    r = np.sqrt((1 - lost) * er ** 2 + lost * (mr ** 2 + prev_r ** 2))
    return t, r, lost
