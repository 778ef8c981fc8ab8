"""All measures of a feature layout along a trajectory in one batched call (the optimiser's hot path).

``evaluate`` transforms the N features (part frame) into the L camera frames and computes every
per-pose, per-feature margin (FOV cone and image, focus, resolution, facing, visibility), the hole
ellipses, and the per-pose Jacobian diagnostics and resolvability — no Python loop over poses or
features. The stacked Jacobian is never formed as (L, 2N, 6) for full-rank poses: JᵀJ (L, 6, 6) is
summed from the per-point 2×6 blocks, its eigenvalues give σ_min / condition / manipulability, and
Λ = ‖J γ̇‖/‖γ̃‖ (``resolvability``); only rank-deficient poses build J̃ and take a pseudo-inverse.

Jacobian weighting: a feature's two Jacobian rows count (weight 1) only where it is ``visible`` (in
front of the camera, facing it, its rim inside the image, and not occluded when a mesh is given); the
rows of invisible features are zero — the estimator could not measure them. The diagnostics use the
scaled Jacobian J̃ = J diag(1, 1, 1, 1/ℓ, 1/ℓ, 1/ℓ) (ℓ = ``rotation_length_mm``), so every column is in px/mm;
with the default ℓ = 1 mm that is the thesis's J.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import Camera
from cadfeat.errors import CadfeatError
from cadfeat.measures.ellipse import hole_ellipse
from cadfeat.measures.focus import focus_margin
from cadfeat.measures.fov import fov_cone_margin, image_margin_from_ellipse
from cadfeat.measures.jacobian import diagnostics_from_gram, image_jacobian
from cadfeat.measures.resolution import margin_from_ellipse
from cadfeat.measures.resolvability import resolvability_from_parts, scale_screws
from cadfeat.measures.visibility import facing_margin, occluded


@dataclass(frozen=True)
class Measures:
    """Every measure of N features at L poses. Margins: positive = satisfied (see each module).

    Per pose and feature (L, N): ``fov`` cone margin (eq. 3.3), ``fov_px`` image margin (px), ``focus``
    (eq. 3.6, normalised), ``resolution_px`` (minor axis − min_axis_px), ``minor_axis_px``, ``facing``
    (cos), ``visible`` (bool), ``centre_px`` (L, N, 2), ``axes_px`` (L, N, 2), ``angle_rad``.
    Per pose (L,): ``sigma_min``, ``condition``, ``manipulability`` (eq. 4.20–4.21), ``singular`` (bool),
    ``resolvability`` Λ_k (eq. 4.32, px/mm).
    """

    fov: np.ndarray
    fov_px: np.ndarray
    focus: np.ndarray
    resolution_px: np.ndarray
    minor_axis_px: np.ndarray
    facing: np.ndarray
    visible: np.ndarray
    centre_px: np.ndarray
    axes_px: np.ndarray
    angle_rad: np.ndarray
    sigma_min: np.ndarray
    condition: np.ndarray
    manipulability: np.ndarray
    singular: np.ndarray
    resolvability: np.ndarray

    def as_dict(self) -> dict[str, np.ndarray]:
        """The arrays by field name."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


def _check_inputs(T_cam_part: ArrayLike, screws: ArrayLike, centres: ArrayLike, axes: ArrayLike,
                  radii: ArrayLike) -> tuple[np.ndarray, ...]:
    T = np.asarray(T_cam_part, dtype=float)
    s = np.asarray(screws, dtype=float)
    c = np.asarray(centres, dtype=float)
    n = np.asarray(axes, dtype=float)
    r = np.asarray(radii, dtype=float)
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise CadfeatError(f"evaluate: T_cam_part must have shape (L, 4, 4), got {T.shape}")
    L = T.shape[0]
    if s.shape != (L, 6):
        raise CadfeatError(f"evaluate: screws must have shape (L, 6) = ({L}, 6), got {s.shape}")
    if c.ndim != 2 or c.shape[1] != 3 or n.shape != c.shape or r.shape != c.shape[:1]:
        raise CadfeatError(f"evaluate: centres (N, 3), axes (N, 3) and radii (N,) must agree, got {c.shape}, "
                           f"{n.shape}, {r.shape}")
    for name, a in (("T_cam_part", T), ("screws", s), ("centres", c), ("axes", n), ("radii", r)):
        if not np.all(np.isfinite(a)):
            raise CadfeatError(f"evaluate: {name} must be finite")
    norm = np.linalg.norm(n, axis=-1)
    if np.any(norm == 0) or np.any(r <= 0):
        raise CadfeatError("evaluate: axes must be non-zero and radii positive (mm)")
    return T, s, c, n / norm[:, None], r


def evaluate(camera: Camera, T_cam_part: ArrayLike, screws: ArrayLike, centres: ArrayLike, axes: ArrayLike,
             radii: ArrayLike, *, min_axis_px: float = 5.0, rotation_length_mm: float = 1.0,
             occlusion_mesh: Any = None) -> Measures:
    """All measures (``Measures``) of holes (centres (N, 3) mm, axes (N, 3) out of the material, radii (N,) mm,
    part frame) seen from poses ``T_cam_part`` (L, 4, 4) moving with ``screws`` (L, 6) = (v mm/s, ω rad/s)
    in the camera frame. ``occlusion_mesh``: optional ``trimesh.Trimesh`` of the part (part frame) for the
    ray occlusion test of ``visible``."""
    T, s, c, n, r = _check_inputs(T_cam_part, screws, centres, axes, radii)
    R = T[:, :3, :3]
    Rt = np.swapaxes(R, 1, 2)
    P = c @ Rt + T[:, None, :3, 3]  # (L, N, 3) centres in the camera frames
    Nrm = n @ Rt  # (L, N, 3) axes in the camera frames
    ell = hole_ellipse(camera, P, Nrm, r)
    fov_px = image_margin_from_ellipse(camera, ell)
    facing = facing_margin(P, Nrm)
    visible = ell.valid & (facing > 0) & (fov_px >= 0)
    if occlusion_mesh is not None:
        cam_in_part = -np.einsum("lji,lj->li", R, T[:, :3, 3])  # −Rᵀ t
        visible &= ~occluded(occlusion_mesh, cam_in_part, c, n)
    per_pose = _jacobian_measures(camera, P, visible, s, rotation_length_mm)
    return Measures(
        fov=fov_cone_margin(camera, P), fov_px=fov_px, focus=focus_margin(camera, P),
        resolution_px=margin_from_ellipse(camera, ell, min_axis_px), minor_axis_px=ell.minor_px,
        facing=facing, visible=visible, centre_px=ell.centre_px, axes_px=ell.axes_px, angle_rad=ell.angle_rad,
        **per_pose,
    )


def _jacobian_measures(camera: Camera, P: np.ndarray, visible: np.ndarray, screws: np.ndarray,
                       rotation_length_mm: float) -> dict[str, np.ndarray]:
    """Diagnostics and Λ per pose from the visible features' Jacobians (module docstring)."""
    L, N = visible.shape
    J = image_jacobian(camera, P)  # (L, N, 2, 6)
    J *= visible[..., None, None]
    Js = J.reshape(L, 2 * N, 6)
    image_speed = np.linalg.norm(np.einsum("lmk,lk->lm", Js, screws), axis=-1)
    if rotation_length_mm != 1.0:
        Js = Js.copy()
        Js[..., 3:] /= rotation_length_mm
    G = np.swapaxes(Js, 1, 2) @ Js
    diag = diagnostics_from_gram(G)
    lam = resolvability_from_parts(Js, image_speed, scale_screws(screws, rotation_length_mm),
                                   diag["singular"], diag["sigma_min"])
    return {**diag, "resolvability": lam}
