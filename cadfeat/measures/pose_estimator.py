"""The error of the estimators cadfeat's closed loop runs: least squares with every detected hole weighted alike.

``pose_information`` gives the Cramér–Rao bound: the error of the *optimal* estimator, which weights hole j by
1/σ_j². ``cv2.solvePnP`` minimises the unweighted reprojection error and the ch. 6 EKF/IEKF use R = r I, so they
weight every detected hole alike; when the σ_j differ (a large counterbore rim beside small holes) their error is
above the bound. For that estimator, per pose (the same Jacobians J_j (2×6), detection probabilities p_j, noise σ_j
and offsets b_j as ``pose_information``; δ = (δp mm, δθ rad)):

    A = Σ_j p_j J_jᵀ J_j / s² + P₀⁻¹,   G_j = A⁻¹ p_j J_jᵀ / s²,   δ = Σ_j G_j (b_j + ε_j),
    bias = Σ_j G_j b_j,   Cov = Σ_j G_j σ_j² G_jᵀ,   error = √(|bias|² + tr Cov)   (translation, rotation apart),

with s the median σ_j of the pose's holes (it only scales the weak prior P₀ = diag(20 mm, 0.1 rad)²). Its
``information`` Cov⁻¹ feeds the filter's posterior bound (``vision.posterior_crlb``) in place of Σ p JᵀJ/σ².
Checked against a ``cv2.solvePnP`` Monte-Carlo with unequal σ_j and fixed offsets (tests/measures/
test_pose_equal_weights.py); ``tools/pose_panel.py`` ranks designs by it against the closed loop.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["EqualWeightErrors", "equal_weight_errors"]

#: The weak prior (mm, rad) of the equal-weight estimate: a pose with fewer than 3 holes stays finite.
PRIOR_SIGMA = (20.0, 0.1)


@dataclass(frozen=True)
class EqualWeightErrors:
    """Per pose (L,): RMS error translation (mm) and rotation (deg) of the equal-weight least squares, its bias
    (L, 6) (mm, rad) and the information (L, 6, 6) of its noise (Cov⁻¹)."""

    translation_mm: np.ndarray
    rotation_deg: np.ndarray
    bias: np.ndarray
    information: np.ndarray


def equal_weight_errors(info: Any) -> EqualWeightErrors:
    """The equal-weight estimator's errors (module docstring) from a ``pose_information`` result ``info`` (its
    ``jacobian`` (L, N, 2, 6), ``probability``, ``sigma_px`` (L, N) and ``offset_px`` (L, N, 2))."""
    G, p = _gain(info)
    var = np.where(p > 0, np.asarray(info.sigma_px, float) ** 2, 0.0)
    cov = np.einsum("lnia,ln,lnja->lij", G, var, G)
    bias = np.einsum("lnia,lna->li", G, np.nan_to_num(np.asarray(info.offset_px, float)))
    t = np.sqrt(np.trace(cov[:, :3, :3], axis1=1, axis2=2) + np.sum(bias[:, :3] ** 2, axis=-1))
    r = np.degrees(np.sqrt(np.trace(cov[:, 3:, 3:], axis1=1, axis2=2) + np.sum(bias[:, 3:] ** 2, axis=-1)))
    return EqualWeightErrors(t, r, bias, _inverse(cov + np.eye(6) * 1e-12))


def _gain(info: Any) -> tuple[np.ndarray, np.ndarray]:
    """The gain G (L, N, 6, 2) and the holes' weights p (L, N) (0 where the Jacobian is not finite)."""
    J = np.asarray(info.jacobian, float)
    p = np.where(np.all(np.isfinite(J), axis=(-1, -2)), np.asarray(info.probability, float), 0.0)
    Jz = np.where(p[..., None, None] > 0, J, 0.0)
    sig = np.asarray(info.sigma_px, float)
    s2 = np.median(np.where(p > 0, sig, np.nan), axis=1) ** 2 if p.any() else np.ones(len(p))
    s2 = np.where(np.isfinite(s2), s2, 1.0)[:, None, None]
    prior = np.diag(np.repeat([1.0 / PRIOR_SIGMA[0] ** 2, 1.0 / PRIOR_SIGMA[1] ** 2], 3))
    A = np.einsum("ln,lnai,lnaj->lij", p, Jz, Jz) / s2 + prior
    return np.einsum("lij,ln,lnaj->lnia", _inverse(A), p, Jz) / s2[..., None], p


def _inverse(a: np.ndarray) -> np.ndarray:
    """The inverse of each matrix of a stack (..., 6, 6)."""
    inverse: np.ndarray = np.linalg.inv(np.asarray(a, dtype=float))
    return inverse
