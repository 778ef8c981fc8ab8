"""Directional motion resolvability Λ_k (thesis eq. 4.27–4.32).

The camera moves with the screw γ̇_k = (v, ω) (mm/s, rad/s, camera frame); the image features move with
J_k γ̇_k and the image-path direction is D_k = J_k γ̇_k / ‖J_k γ̇_k‖ (eq. 4.30). The measure is
Λ_k = 1 / ‖J_k⁺ D_k‖ (eq. 4.32): how much image motion (px) one unit of camera motion along the path
produces, as seen through the pseudo-inverse that a pose estimator would use.

Units. ‖γ̇‖ mixes mm/s and rad/s (the thesis's choice). ``rotation_length_mm`` ℓ scales ω to a
velocity, γ̃ = (v, ℓ ω), and the Jacobian columns to J̃ = J diag(1, 1, 1, 1/ℓ, 1/ℓ, 1/ℓ) so J̃ γ̃ = J γ̇.
ℓ = 1 mm (the default) reproduces the thesis; a length of the order of the feature spread (or the
working distance) weighs rotations as the image motion they produce at that radius.

Computation. When J̃ has full column rank, J̃⁺ J̃ = I and Λ_k = ‖J γ̇‖ / ‖γ̃‖ exactly; rank is read from
the eigenvalues of J̃ᵀJ̃ (6×6). Only the rank-deficient poses go through ``numpy.linalg.pinv`` (with
relative cut-off ``SINGULAR_RTOL``). Conventions: a pose with γ̇ = 0 has no direction, its Λ is the
worst-direction value σ_min(J̃); a pose with J γ̇ = 0 (no image motion, e.g. no visible feature) has Λ = 0.

Hidden and partly hidden holes (``evaluate``'s Jacobian weights): each feature's two rows are scaled by the
seen fraction 1 − h of its rim (``Measures.seen``; 0 past the fold radius, facing away or outside the image):
a hole the part hides whole gives no rows, so Λ is the same whatever its size and position, and as if it were
not there; a partly hidden one adds (1 − h)² of its image speed² — less than the same hole seen, more as more
of its rim shows.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.errors import CadfeatError
from cadfeat.measures.jacobian import SINGULAR_RTOL, diagnostics_from_gram, gram


def scale_screws(screws: ArrayLike, rotation_length_mm: float) -> np.ndarray:
    """γ̃ = (v, ℓ ω) (..., 6), all in mm/s."""
    check_length(rotation_length_mm)
    s = np.array(screws, dtype=float)
    s[..., 3:] *= rotation_length_mm
    return s


def scale_jacobian(J: ArrayLike, rotation_length_mm: float) -> np.ndarray:
    """J̃ = J diag(1, 1, 1, 1/ℓ, 1/ℓ, 1/ℓ) (..., 6): px per mm in every column."""
    check_length(rotation_length_mm)
    J = np.asarray(J, dtype=float)
    if rotation_length_mm == 1.0:
        return J
    J = J.copy()
    J[..., 3:] /= rotation_length_mm
    return J


def check_length(rotation_length_mm: float) -> None:
    if not (np.isfinite(rotation_length_mm) and rotation_length_mm > 0):
        raise CadfeatError(f"rotation_length_mm must be a positive finite length in mm, got {rotation_length_mm!r}")


def resolvability(J: ArrayLike, screws: ArrayLike, rotation_length_mm: float = 1.0) -> np.ndarray:
    """Λ_k (L,) of stacked Jacobians J (L, 2N, 6) along velocity screws (L, 6) (eq. 4.27–4.32), px/mm."""
    J = np.asarray(J, dtype=float)
    screws = np.asarray(screws, dtype=float)
    Js = scale_jacobian(J, rotation_length_mm)
    diag = diagnostics_from_gram(gram(Js))
    image_speed = np.linalg.norm(np.einsum("lmk,lk->lm", J, screws), axis=-1)
    return resolvability_from_parts(Js, image_speed, scale_screws(screws, rotation_length_mm),
                                    diag["singular"], diag["sigma_min"])


def resolvability_from_parts(Js: np.ndarray | Callable[[np.ndarray], np.ndarray], image_speed: np.ndarray,
                             screws_scaled: np.ndarray, singular: np.ndarray, sigma_min: np.ndarray) -> np.ndarray:
    """Λ from precomputed parts: J̃ (L, 2N, 6) (read only on singular poses), ‖J γ̇‖ (L,), γ̃ (L, 6),
    the singular flags and σ_min(J̃) (L,). Full-rank poses use Λ = ‖J γ̇‖/‖γ̃‖, others 1/‖J̃⁺ D‖. ``Js`` may be a
    function of the pose indices returning J̃ (M, 2N, 6) of those poses (built only when needed)."""
    speed = np.linalg.norm(screws_scaled, axis=-1)
    moving = speed > 0.0
    lam = np.where(moving, image_speed / np.where(moving, speed, 1.0), sigma_min)
    redo = np.flatnonzero(singular & moving)
    if redo.size:
        lam[redo] = _pinv_resolvability(Js(redo) if callable(Js) else Js[redo], screws_scaled[redo])
    return lam


def _pinv_resolvability(Js: np.ndarray, screws_scaled: np.ndarray) -> np.ndarray:
    """1/‖J̃⁺ D‖ with D = J̃γ̃/‖J̃γ̃‖ for rank-deficient J̃ (M, 2N, 6); 0 where the image does not move."""
    flow = np.einsum("lmk,lk->lm", Js, screws_scaled)
    norm = np.linalg.norm(flow, axis=-1)
    ok = norm > 0.0
    D = flow / np.where(ok, norm, 1.0)[:, None]
    back = np.linalg.norm(np.einsum("lkm,lm->lk", np.linalg.pinv(Js, rcond=SINGULAR_RTOL), D), axis=-1)
    good = ok & (back > 0.0)
    return np.where(good, 1.0 / np.where(good, back, 1.0), 0.0)
