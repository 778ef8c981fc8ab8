"""All measures of a feature layout along a trajectory in one batched call (the optimiser's hot path).

``evaluate`` transforms the N features (part frame) into the L camera frames and computes every
per-pose, per-feature margin (FOV cone and image, focus, resolution, facing, visibility), the hole
ellipses, and the per-pose Jacobian diagnostics and resolvability — no Python loop over poses or
features. The stacked Jacobian is never formed as (L, 2N, 6) for full-rank poses: JᵀJ (L, 6, 6) is
summed from the per-point 2×6 blocks, its eigenvalues give σ_min / condition / manipulability, and
Λ = ‖J γ̇‖/‖γ̃‖ (``resolvability``); only rank-deficient poses build J̃ and take a pseudo-inverse.

Jacobian weighting: a feature's two Jacobian rows are scaled by ``seen`` — the seen fraction 1 − h of its rim
where it is in front of the camera, facing it, its rim inside the image and inside the lens's valid field
(``Camera.fold_radius``: past it rays fold back into the image), else 0: 1 for a feature seen whole (h = 0
without a mesh), 0 for one the part hides whole — the estimator could not measure it. (A hole the part hides
whole gives no rows, so Λ is the same whatever its size and position.) The diagnostics use the scaled Jacobian
J̃ = J diag(1, 1, 1, 1/ℓ, 1/ℓ, 1/ℓ) (ℓ = ``rotation_length_mm``), so every column is in px/mm; with the default
ℓ = 1 mm that is the thesis's J.

The measures are the thesis's equations, also where the camera cannot see a hole (issue 32 item 7): FOV cone
(eq. 3.2–3.3), focus (eq. 3.6), the image margin and the resolution margin (§3.3.3) are what the equations give
for a hole facing away, hidden by the part or past the lens's fold radius, and ``visible`` is the visibility of
docs/design.md (in front of the camera, facing it, its rim inside the image as the camera model projects it, its
centre's ray not blocked by the part). What the camera cannot see is reported beside them — ``hidden`` (the
centre's ray blocked), ``folded`` (past the fold radius), ``rim_hidden`` (the hidden fraction h of the rim),
``facing`` — and the objectives score it: the unseen-hole rule (a hidden hole never scores better than the same
hole seen, docs/design.md "Trust rules") is ``cadfeat.design.unseen``'s, applied by the objectives
(``design.unseen.scored_measures``), not here.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import MIN_DEPTH_MM, Camera
from cadfeat.errors import CadfeatError
from cadfeat.measures.ellipse import ellipse_parts, rim_conic_xyz, sphere_conic_xyz
from cadfeat.measures.focus import focus_margin_depth, focus_scale_mm
from cadfeat.measures.fov import behind_px, image_margin_px
from cadfeat.measures.jacobian import diagnostics_from_gram, fill_jacobian
from cadfeat.measures.kernels import features, gram_and_speed
from cadfeat.measures.lens import distort_terms
from cadfeat.measures.resolution import minor_axis_margin
from cadfeat.measures.resolvability import check_length, resolvability_from_parts, scale_screws
from cadfeat.measures.unseen import rim_hidden_fraction
from cadfeat.measures.visibility import occluded

#: Feature-poses per slab in ``evaluate`` (temporaries of 16k doubles = 128 kB stay in the L2 cache).
BLOCK_ELEMENTS = 16384

#: Hole models of the resolution measure (docs/design.md "The measures"): the exact rim circle, or the thesis's sphere.
RESOLUTION_MODELS = ("circle", "sphere")


@dataclass(frozen=True)
class Measures:
    """Every measure of N features at L poses. Margins: positive = satisfied (see each module).

    Per pose and feature (L, N): ``fov`` cone margin (eq. 3.3), ``fov_px`` image margin (px), ``focus``
    (eq. 3.6, normalised), ``resolution_px`` (minor axis − min_axis_px), ``minor_axis_px``, ``facing``
    (cos), ``visible`` (bool: in front, facing, the rim inside the image as projected, the centre not hidden; the
    lens's fold is ``folded``), ``centre_px`` (L, N, 2), ``axes_px`` (L, N, 2), ``angle_rad``.
    Per pose (L,): ``sigma_min``, ``condition``, ``manipulability`` (eq. 4.20–4.21), ``singular`` (bool),
    ``resolvability`` Λ_k (eq. 4.32, px/mm). ``hidden`` (L, N) bool: the centre hidden by the part (occlusion
    mesh); ``folded`` (L, N) bool: past the lens's fold radius; ``rim_hidden`` (L, N) in [0, 1]: the hidden
    fraction h of the rim (0 without a mesh, and where facing away, folded or behind the camera; module
    docstring, ``measures.unseen``); ``seen`` (L, N) in [0, 1]: the Jacobian rows' weight (module docstring).
    The margins are the thesis's equations wherever the hole is (module docstring); the objectives' unseen rule
    is ``cadfeat.design.unseen.scored_measures``.
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
    hidden: np.ndarray
    folded: np.ndarray
    rim_hidden: np.ndarray
    seen: np.ndarray

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
             occlusion_mesh: Any = None, resolution_model: str = "circle") -> Measures:
    """All measures (``Measures``) of holes (centres (N, 3) mm, axes (N, 3) out of the material, radii (N,) mm,
    part frame) seen from poses ``T_cam_part`` (L, 4, 4) moving with ``screws`` (L, 6) = (v mm/s, ω rad/s)
    in the camera frame. ``occlusion_mesh``: optional ``trimesh.Trimesh`` of the part (part frame) for the
    exact ray occlusion test of ``visible``, or ``measures.depth.DepthMaps`` of the part at these same poses
    (the optimiser's fast test). ``resolution_model``: "circle" (default, the rim's exact ellipse) or
    "sphere" (the thesis's eq. 3.13–3.18: ``minor_axis_px`` and ``resolution_px`` from the outline of a
    sphere of the rim's radius; the reported ellipses stay the rim's).

    Works on contiguous (L, N) component arrays (X, Y, Z, n_x, …, each one (L, 3) @ (3, N) product) rather
    than (L, N, 3) stacks; same formulas as the public per-measure functions (tests compare them). Large
    batches are cut into slabs of about ``BLOCK_ELEMENTS`` feature-poses (whole blocks of poses, each slab
    fully batched) so the temporaries stay in the CPU cache; the results are concatenated."""
    T, s, c, n, r = _check_inputs(T_cam_part, screws, centres, axes, radii)
    check_length(rotation_length_mm)
    if resolution_model not in RESOLUTION_MODELS:
        raise CadfeatError(f"evaluate: resolution_model must be one of {', '.join(RESOLUTION_MODELS)}, "
                           f"got {resolution_model!r}")
    if not np.isfinite(min_axis_px):
        raise CadfeatError(f"evaluate: min_axis_px must be a finite number of pixels, got {min_axis_px!r}")
    L, N = T.shape[0], c.shape[0]
    kernel = features()
    # compiled per-feature pass (no temporaries, no slabs) — except for large pinhole batches, where the numpy
    # path's few distortion-free array operations are faster than the kernel's chain of divisions per element
    if kernel is not None and (camera.has_distortion or L * N <= BLOCK_ELEMENTS):
        return _evaluate_compiled(kernel, camera, T, s, c, n, r, min_axis_px, rotation_length_mm, occlusion_mesh,
                                  resolution_model == "sphere")
    out = _allocate(L, N)
    step = max(1, BLOCK_ELEMENTS // max(1, N))
    for i in range(0, L, step):  # slabs of whole pose blocks (cache blocking), each fully batched
        sl = slice(i, i + step)
        occ = occlusion_mesh.select(sl) if hasattr(occlusion_mesh, "select") else occlusion_mesh
        _evaluate(camera, T[sl], s[sl], c, n, r, min_axis_px, rotation_length_mm, occ,
                  {k: v[sl] for k, v in out.items()}, resolution_model == "sphere")
    return Measures(**out)


_PER_FEATURE = ("fov", "fov_px", "focus", "resolution_px", "minor_axis_px", "facing", "angle_rad")
_PER_POSE = ("sigma_min", "condition", "manipulability", "resolvability")


def _allocate(L: int, N: int) -> dict[str, np.ndarray]:
    out = {k: np.empty((L, N)) for k in _PER_FEATURE}
    out.update({k: np.empty(L) for k in _PER_POSE})
    out.update(visible=np.empty((L, N), dtype=bool), singular=np.empty(L, dtype=bool),
               hidden=np.zeros((L, N), dtype=bool), folded=np.zeros((L, N), dtype=bool), rim_hidden=np.zeros((L, N)),
               seen=np.empty((L, N)),
               centre_px=np.empty((L, N, 2)), axes_px=np.empty((L, N, 2)))
    return out


def _frames(T: np.ndarray, c: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, ...]:
    """X, Y, Z, n_x, n_y, n_z (camera frame, (L, N)), Rᵀt (L, 3), n·c and ‖c‖² (camera frame, (L, N))."""
    R, t = T[:, :3, :3], T[:, :3, 3]
    X, Y, Z = (R[:, i, :] @ c.T + t[:, i, None] for i in range(3))  # centres in the camera frames (L, N)
    nx, ny, nz = (R[:, i, :] @ n.T for i in range(3))  # axes in the camera frames
    rt = np.einsum("lji,lj->li", R, t)  # Rᵀ t = −(camera centre in the part frame)
    nc = np.sum(n * c, axis=-1) + rt @ n.T  # n·c in the camera frame
    dist2 = np.sum(c * c, axis=-1) + 2.0 * (rt @ c.T) + np.sum(t * t, axis=-1)[:, None]
    return X, Y, Z, nx, ny, nz, rt, nc, dist2


def _evaluate_compiled(kernel: Any, camera: Camera, T: np.ndarray, s: np.ndarray, c: np.ndarray, n: np.ndarray,
                       r: np.ndarray, min_axis_px: float, rotation_length_mm: float, occlusion_mesh: Any,
                       sphere: bool) -> Measures:
    """``evaluate`` through the compiled kernels (``kernels``): same formulas and operation order as
    ``_evaluate`` per feature-pose (results equal to rounding)."""
    L, N = T.shape[0], c.shape[0]
    X, Y, Z, nx, ny, nz, rt, nc, dist2 = _frames(T, c, n)
    k1, k2, p1, p2, k3 = camera.dist
    mode = 0 if not any(camera.dist) else 3 if k3 else 2 if k2 else 1
    cam = np.array([camera.fx, camera.fy, camera.cx, camera.cy, k1, k2, p1, p2, k3], dtype=float)
    near, far = camera.depth_of_field_mm
    consts = np.array([MIN_DEPTH_MM, camera.width, camera.height, np.cos(0.5 * camera.fov_rad), near, far,
                       focus_scale_mm(camera), min_axis_px, float(max(camera.width, camera.height)),
                       behind_px(camera)], dtype=float)
    f = np.empty((7, L, N))
    visible, valid = np.empty((L, N), dtype=bool), np.empty((L, N), dtype=bool)
    centre, axes_px, lens = np.empty((L, N, 2)), np.empty((L, N, 2)), np.empty((7, L, N))
    kernel(X, Y, Z, nx, ny, nz, nc, dist2, r, cam, mode, consts, sphere, f, visible, valid, centre, axes_px, lens)
    if not valid.all():  # invalid ellipses: the (depth-clamped) projection of the centre
        bad = ~valid
        centre[bad] = camera.distort_normalized(np.stack([lens[0][bad], lens[1][bad]], axis=-1))
    out = dict(zip(("fov", "fov_px", "focus", "resolution_px", "minor_axis_px", "facing", "angle_rad"), f,
                   strict=True))
    out.update(visible=visible, centre_px=centre, axes_px=axes_px)
    out.update(_unseen(camera, lens[0], lens[1], r * lens[2], Z, occlusion_mesh, T, c, n, r, out))
    out.update({k: np.empty(L) for k in _PER_POSE}, singular=np.empty(L, dtype=bool))
    D = list(lens[3:]) if mode else [camera.fx, 0.0, 0.0, camera.fy]
    _jacobian_measures(lens[0], lens[1], lens[2], D, out["seen"], s, rotation_length_mm, out)
    return Measures(**out)


def _evaluate(camera: Camera, T: np.ndarray, s: np.ndarray, c: np.ndarray, n: np.ndarray, r: np.ndarray,
              min_axis_px: float, rotation_length_mm: float, occlusion_mesh: Any, out: dict[str, np.ndarray],
              sphere: bool = False) -> None:
    """``evaluate`` on one slab of poses (validated inputs), written into the views ``out``."""
    X, Y, Z, nx, ny, nz, rt, nc, dist2 = _frames(T, c, n)
    dist = np.sqrt(np.maximum(dist2, 0.0))
    in_front = Z - r * np.sqrt(np.maximum(1.0 - nz * nz, 0.0)) > MIN_DEPTH_MM
    ell = ellipse_parts(camera, rim_conic_xyz(X, Y, Z, nx, ny, nz, nc, dist2 - r * r), in_front)
    fov_px = out["fov_px"]
    fov_px[...] = image_margin_px(camera, ell.u, ell.v, ell.hu, ell.hv, ell.valid)
    inv_dist = 1.0 / np.where(dist > 0, dist, 1.0)
    facing = out["facing"]
    np.multiply(nc, -inv_dist, out=facing)
    visible = out["visible"]
    np.greater(facing, 0.0, out=visible)
    visible &= ell.valid
    visible &= fov_px >= 0
    np.subtract(Z * inv_dist, np.cos(0.5 * camera.fov_rad), out=out["fov"])
    out["focus"][...] = focus_margin_depth(camera, Z)
    res = ell
    if sphere:
        res = ellipse_parts(camera, sphere_conic_xyz(X, Y, Z, dist2 - r * r), Z - r > MIN_DEPTH_MM)
    out["resolution_px"][...] = minor_axis_margin(camera, res.minor, res.valid, min_axis_px)
    out["minor_axis_px"][...] = res.minor
    out["angle_rad"][...] = ell.angle
    out["axes_px"][..., 0] = ell.major
    out["axes_px"][..., 1] = ell.minor
    inv_z = 1.0 / np.maximum(Z, MIN_DEPTH_MM)
    x, y = X * inv_z, Y * inv_z
    D = distort_terms(camera, x, y, positions=False)[2:]
    centre = out["centre_px"]
    centre[..., 0] = ell.u
    centre[..., 1] = ell.v
    if not ell.valid.all():  # invalid ellipses: the (depth-clamped) projection of the centre
        bad = ~ell.valid
        centre[bad] = camera.distort_normalized(np.stack([x[bad], y[bad]], axis=-1))
    flags = _unseen(camera, x, y, r * inv_z, Z, occlusion_mesh, T, c, n, r, out)
    for key in ("hidden", "folded", "rim_hidden", "seen"):
        out[key][...] = flags[key]
    _jacobian_measures(x, y, inv_z, D, out["seen"], s, rotation_length_mm, out)


def _unseen(camera: Camera, x: np.ndarray, y: np.ndarray, rim_reach: np.ndarray, Z: np.ndarray, mesh: Any,
            T: np.ndarray, c: np.ndarray, n: np.ndarray, r: np.ndarray, out: dict[str, np.ndarray]
            ) -> dict[str, np.ndarray]:
    """Hidden (the centre's ray, by ``mesh``), folded (past ``camera.fold_radius``: the centre's normalised
    radius plus the rim's angular reach R/Z) and partly hidden (``rim_hidden``: ``unseen.rim_hidden_fraction``
    where facing the camera, in front and not folded) feature-poses; hidden ones are not ``visible`` (the margins
    are left as the equations give them: the objectives' rule is ``design.unseen``'s). Modifies ``out["visible"]``
    in place; returns {"hidden", "folded"} (L, N) bool and {"rim_hidden", "seen"} (L, N) float (``seen``:
    1 − rim_hidden where ``visible`` but for the centre test and not folded, else 0)."""
    L, N = x.shape
    r_fold = camera.fold_radius
    folded = np.zeros((L, N), dtype=bool)
    if np.isfinite(r_fold):
        folded = (np.hypot(x, y) + np.abs(rim_reach) > r_fold) & (Z > MIN_DEPTH_MM)
    rim_hidden = np.zeros((L, N))
    if mesh is None:
        hidden = np.zeros((L, N), dtype=bool)
    else:
        if hasattr(mesh, "hidden"):  # depth maps of the part at these poses (``measures.depth.DepthMaps``)
            hidden = mesh.hidden(x * Z, y * Z, Z)
        else:  # the exact ray test against the mesh
            hidden = occluded(mesh, -np.einsum("lji,lj->li", T[:, :3, :3], T[:, :3, 3]), c, n)
        rim_hidden = rim_hidden_fraction(mesh, T, c, n, r, (out["facing"] > 0.0) & (Z > MIN_DEPTH_MM) & ~folded)
    seen = np.where(out["visible"] & ~folded, 1.0 - rim_hidden, 0.0)
    out["visible"] &= ~hidden
    return {"hidden": hidden, "folded": folded, "rim_hidden": rim_hidden, "seen": seen}


def _jacobian_measures(x: np.ndarray, y: np.ndarray, inv_z: np.ndarray, D: list, weights: np.ndarray,
                       screws: np.ndarray, rotation_length_mm: float, out: dict[str, np.ndarray]) -> None:
    """Diagnostics and Λ per pose from the features' Jacobians, rows scaled by ``weights`` (L, N) (module
    docstring: ``seen``), into ``out``.

    JᵀJ (L, 6, 6) and ‖J γ̇‖ come from the compiled kernel (``kernels.gram_and_speed``) when numba is
    available, else from the transposed stacked Jacobian (``_stacked_transposed``); J̃ itself is built
    only for the rank-deficient poses that need a pseudo-inverse."""
    kernel = gram_and_speed()
    if kernel is None:
        Jt = _stacked_transposed(x, y, inv_z, D, weights)
        image_speed = np.linalg.norm(np.einsum("lk,lkm->lm", screws, Jt), axis=-1)
        if rotation_length_mm != 1.0:
            Jt[:, 3:, :] /= rotation_length_mm
        G = Jt @ np.swapaxes(Jt, 1, 2)
        rows = np.swapaxes(Jt, 1, 2)
    else:
        L, N = x.shape
        G, image_speed = np.empty((L, 6, 6)), np.empty(L)
        Dfull = [d if isinstance(d, np.ndarray) else np.full((L, N), d) for d in D]
        kernel(x, y, inv_z, *Dfull, weights, np.ascontiguousarray(screws), float(rotation_length_mm), G,
               image_speed)

        def rows(idx: np.ndarray) -> np.ndarray:
            Jt = _stacked_transposed(x[idx], y[idx], inv_z[idx], [d[idx] if isinstance(d, np.ndarray) else d
                                                                  for d in D], weights[idx])
            if rotation_length_mm != 1.0:
                Jt[:, 3:, :] /= rotation_length_mm
            return np.swapaxes(Jt, 1, 2)

    diag = diagnostics_from_gram(G)
    out["resolvability"][...] = resolvability_from_parts(rows, image_speed,
                                                         scale_screws(screws, rotation_length_mm),
                                                         diag["singular"], diag["sigma_min"])
    for key, value in diag.items():
        out[key][...] = value


def _stacked_transposed(x: np.ndarray, y: np.ndarray, inv_z: np.ndarray, D: list, weights: np.ndarray) -> np.ndarray:
    """Jᵀ (L, 6, 2N) of the features, rows scaled by ``weights`` (L, N), held transposed (rows of one column
    contiguous) so JᵀJ is one batched (6, 2N) @ (2N, 6) product; row order within 2N is irrelevant."""
    L, N = weights.shape
    w = np.asarray(weights, dtype=float)
    Dw = [d * w if not (np.isscalar(d) and d == 0.0) else 0.0 for d in D]  # zero weight → zero rows
    Jt = np.empty((L, 12, N))
    fill_jacobian([Jt[:, j] for j in range(12)], x, y, inv_z, Dw)  # the 12 entries of the 2×6 blocks
    return Jt.reshape(L, 6, 2 * N)
