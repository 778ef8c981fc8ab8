"""Compiled (numba) kernel of the Jacobian part of ``evaluate``: JᵀJ and ‖J γ̇‖ per pose, fused.

Same entries as ``jacobian.fill_jacobian`` (eq. 4.9–4.11, J = D · L, distortion Jacobian D) accumulated point
by point into the 6×6 Gram matrix J̃ᵀJ̃ (J̃ = J diag(1, 1, 1, 1/ℓ, 1/ℓ, 1/ℓ)) and the image speed ‖J γ̇‖,
without the (L, 6, 2N) stacked Jacobian and the ~50 full-size temporaries of the numpy path. Only
feature-poses of non-zero weight contribute (their rows are zero in the numpy path). Results agree with
the numpy path to rounding (different summation order). numba comes with cadquery; without it
``gram_and_speed()`` is None and ``evaluate`` uses the numpy path. Compiled on first use (cached on disk).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def _gram_and_speed(x: np.ndarray, y: np.ndarray, inv_z: np.ndarray, d00: np.ndarray, d01: np.ndarray,
                    d10: np.ndarray, d11: np.ndarray, w: np.ndarray, screws: np.ndarray, ell: float,
                    gram: np.ndarray, speed: np.ndarray) -> None:
    """Per pose l: gram[l] = Σ_j w J̃_jᵀ J̃_j (6×6) and speed[l] = ‖J γ̇_l‖ over features j with w[l, j] ≠ 0.

    x, y normalised coordinates, inv_z = 1/Z (1/mm), d.. the pixel distortion Jacobian (all (L, N), the
    d.. may be broadcast views), w (L, N) bool, screws (L, 6), ell = ℓ (mm)."""
    L, N = x.shape
    ju = np.empty(6)
    jv = np.empty(6)
    for l in range(L):
        g = np.zeros((6, 6))
        sq = 0.0
        for j in range(N):
            if not w[l, j]:
                continue
            xl, yl, iz = x[l, j], y[l, j], inv_z[l, j]
            xy = xl * yl
            xx1 = 1.0 + xl * xl
            yy1 = 1.0 + yl * yl
            xiz, yiz = xl * iz, yl * iz
            for row in range(2):
                if row == 0:
                    da, db, jr = d00[l, j], d01[l, j], ju
                else:
                    da, db, jr = d10[l, j], d11[l, j], jv
                jr[0] = -(da * iz)
                jr[1] = -(db * iz)
                jr[2] = da * xiz + db * yiz
                jr[3] = da * xy + db * yy1
                jr[4] = -(da * xx1 + db * xy)
                jr[5] = da * yl - db * xl
            fu = 0.0
            fv = 0.0
            for k in range(6):
                fu += screws[l, k] * ju[k]
                fv += screws[l, k] * jv[k]
            sq += fu * fu + fv * fv
            for k in range(3, 6):
                ju[k] /= ell
                jv[k] /= ell
            for a in range(6):
                for b in range(a, 6):
                    g[a, b] += ju[a] * ju[b] + jv[a] * jv[b]
        for a in range(6):
            for b in range(a, 6):
                gram[l, a, b] = g[a, b]
                gram[l, b, a] = g[a, b]
        speed[l] = np.sqrt(sq)


_COMPILED: list = []


def gram_and_speed() -> Callable[..., None] | None:
    """The compiled kernel (numba imported and the kernel compiled on first call), or None without numba."""
    if not _COMPILED:
        try:  # numba is a cadquery dependency; fall back to numpy without it
            import numba
        except ImportError:  # pragma: no cover - exercised only without numba
            _COMPILED.append(None)
        else:
            _COMPILED.append(numba.njit(cache=True, nogil=True)(_gram_and_speed))
    return _COMPILED[0]
