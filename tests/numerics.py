"""Tolerances for quantities computed from the eigenvalues of JᵀJ, stated relative to their own scale.

The eigenvalues λ_i of a Gram matrix JᵀJ carry an absolute round-off of a few ε·λ_max, and its size depends on
the BLAS kernel (SkylakeX, Haswell and Prescott kernels sum in different orders). So σ_i = √λ_i is known to a
relative ε·(σ_max/σ_i)²: a well-conditioned σ to ~1e-15, a σ_min at condition 1e5 only to ~1e-6. A fixed rtol
on σ_min, the condition number or a product of σ (manipulability) passes on one kernel and fails on another.
"""

from __future__ import annotations

import numpy as np

#: relative round-off of one eigenvalue of JᵀJ in units of λ_max (a few ε, with margin for any kernel)
GRAM_EPS = 1e-13


def sigma_rtol(condition: np.ndarray, floor: float = 1e-9) -> np.ndarray:
    """Relative tolerance of σ_min (and of σ_max/σ_min) from a Gram matrix at the given condition number."""
    return floor + GRAM_EPS * np.asarray(condition, dtype=float) ** 2


def assert_close_rel(actual: np.ndarray, expected: np.ndarray, rtol: np.ndarray, what: str) -> None:
    """|actual − expected| ≤ rtol·|expected| elementwise (rtol broadcast), with the worst offender in the message."""
    actual, expected = np.asarray(actual, float), np.asarray(expected, float)
    err = np.abs(actual - expected)
    bound = np.broadcast_to(rtol, err.shape) * np.abs(expected)
    bad = err > bound
    if bad.any():
        k = int(np.argmax(np.where(bad, err / np.maximum(bound, 1e-300), 0)))
        raise AssertionError(f"{what}: {bad.sum()} of {bad.size} outside the tolerance; worst at {k}: "
                             f"{actual.flat[k]!r} vs {expected.flat[k]!r} (allowed {bound.flat[k]:.3g})")
