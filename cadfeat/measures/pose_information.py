"""Pose accuracy: Fisher information of the part's pose from its holes' image measurements (docs/design.md "Pose
accuracy"), the Cramér–Rao bound, the detection offsets propagated to a pose bias, and the filter's posterior bound.

**Parametrisation of the pose error** (the filters' error state, ``cadfeat.vision.motion``): δ = (δp, δθ) ∈ R⁶,
δp in mm, δθ in rad, perturbing T_cam_part = [R, p] as

    R ← exp([δθ]×) R,   p ← p + δp,

a *left* perturbation on SO(3) × R³: δp moves the part's origin in the camera frame, δθ rotates the part about
its own origin with the axis expressed in the camera frame. (The left SE(3) twist ξ = (ρ, φ), T ← exp(ξ^) T,
is the same first-order perturbation with φ = δθ and ρ = δp − δθ × p.) The closed loop's errors
(``vision.metrics.pose_errors``: ‖p̂ − p‖ and the angle of R̂ Rᵀ) are the norms of δp and δθ, so
σ_t = √tr Σ_pp and σ_r = √tr Σ_θθ are their RMS values.

**Measurement** of hole j at pose k: the centre z_jk (px) of its rim's image ellipse (not the image of the hole
centre), with the 2×6 Jacobian J_jk = ∂z_jk/∂δ of ``cadfeat.measures.rim_centre.measure``. Each detected hole
gives z = h(δ) + b_jk + ε, ε ~ N(0, σ_jk² I), b_jk a systematic offset of the detector (px), σ_jk its noise
(``pose_models.measurement_model``), detected with probability p_jk (``pose_models.detection_probability``).

**Fisher information** (per pose, eq. of docs/design.md "Pose accuracy"; the detection probability as the expected
weight):

    I_k = Σ_j p_jk J_jkᵀ J_jk / σ_jk²          (6×6, units 1/mm², 1/(mm·rad), 1/rad²)

and the Cramér–Rao bound of a single-frame (PnP) estimate Σ_k ≥ I_k⁻¹ (with an optional weak prior
I_k + diag(1/σ_p², 1/σ_θ²) so that the bound is finite with fewer than three holes).

**Bias** (least-squares propagation of the offsets): the weighted least-squares pose of biased measurements is
off by δ_b,k = (Σ_j p J̃ᵀJ̃)⁻¹ Σ_j p J̃ᵀ b̃ with J̃ = J/σ, b̃ = b/σ, i.e. δ_b = (JᵀWJ)⁻¹ JᵀW b. The predicted
error (RMS) per pose is √(‖δ_b,p‖² + σ_t²) mm and √(‖δ_b,θ‖² + σ_r²) rad; both parts are reported.

**Posterior CRLB** of the ch. 6 constant-velocity filter (Tichavský et al. 1998), on the 12-state error state
(δp, δθ, δṗ, δω) of ``vision.motion`` with its transition F_k and process noise Q (``FilterTuning``):

    J_k = (Q + F_k J_{k−1}⁻¹ F_kᵀ)⁻¹ + E[H_kᵀ R_k⁻¹ H_k],   E[H_kᵀ R_k⁻¹ H_k] = [[I_k, 0], [0, 0]],

``cadfeat.vision.posterior_crlb``; J₀ = P₀⁻¹ + [[I₀, 0], [0, 0]]. The recursion runs along the trajectory (a loop
over time steps, which is sequential by nature; each step is 12×12).

**Hidden and partly hidden holes** (rule of this measure): a hole behind the camera, facing away, with its rim
outside the image or hidden by the part has p = 0: it adds no information and no bias, whatever its size or
position. A partly hidden rim (``occlusion`` = the hidden fraction of the rim) is rejected by the detector
(``vision.detection``: association with the predicted occlusion), so p falls smoothly to 0 as soon as a few
per cent of the rim are hidden; it never counts as a whole hole.

Batched over L poses × N holes: one ``measure`` call (L, N, 2, 6) and einsum contractions, no Python loop over
poses or holes.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import Camera
from cadfeat.cell import defaults as D
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import JsonDict

__all__ = ["PoseInformation", "direction_words", "pose_information"]

#: Eigenvalues below this fraction of the largest (in the scaled metric) count as unobservable directions.
RANK_TOL = 1e-12
_AXES = ("x (image right)", "y (image down)", "the optical axis")


@dataclass(frozen=True)
class PoseInformation:
    """Result of ``pose_information`` (module docstring for the equations). Shapes (L poses, N holes).

    ``information`` (L, 6, 6) Fisher information of δ = (δp mm, δθ rad) (prior included when given);
    ``covariance`` (L, 6, 6) its inverse (the CRLB; inf on the diagonal where singular);
    ``sigma_translation_mm`` / ``sigma_rotation_deg`` (L,) √tr of the translation / rotation blocks;
    ``bias`` (L, 6) δ_b = (JᵀWJ)⁻¹JᵀW b; ``bias_translation_mm`` / ``bias_rotation_deg`` (L,) its norms;
    ``error_translation_mm`` / ``error_rotation_deg`` (L,) √(bias² + σ²) — the predicted RMS error;
    ``share`` (L, N) each hole's share of tr(S I S) (S = diag(1, 1, 1, ℓ, ℓ, ℓ)⁻¹ puts rotation in mm at the
    lever ``rotation_length_mm`` ℓ), summing to 1 over holes where any hole counts;
    ``weakest`` (L, 6) unit eigenvector of the smallest eigenvalue of S I S, ``weakest_sigma`` (L,) the
    standard deviation along it (mm at ℓ), ``weakest_words`` (L,) its description;
    ``probability`` (L, N) detection probability p, ``sigma_px`` (L, N), ``offset_px`` (L, N, 2),
    ``measured_px`` (L, N, 2) predicted measurements, ``jacobian`` (L, N, 2, 6) ∂z/∂δ, ``detected`` (L, N)
    the hard detection (p ≥ 0.5, for reporting).
    """

    information: np.ndarray
    covariance: np.ndarray
    sigma_translation_mm: np.ndarray
    sigma_rotation_deg: np.ndarray
    bias: np.ndarray
    bias_translation_mm: np.ndarray
    bias_rotation_deg: np.ndarray
    error_translation_mm: np.ndarray
    error_rotation_deg: np.ndarray
    share: np.ndarray
    weakest: np.ndarray
    weakest_sigma: np.ndarray
    probability: np.ndarray
    sigma_px: np.ndarray
    offset_px: np.ndarray
    measured_px: np.ndarray
    jacobian: np.ndarray
    detected: np.ndarray
    rotation_length_mm: float = 1.0

    def as_dict(self) -> JsonDict:
        return {**{f.name: getattr(self, f.name) for f in fields(self)}, "weakest_words": self.weakest_words}

    @property
    def weakest_words(self) -> tuple[str, ...]:
        """(L,) the weakest direction in words per pose (``direction_words``; built on demand, for reports)."""
        return tuple(direction_words(v) for v in self.weakest)

    def error_mm(self, rotation_length_mm: float | None = None) -> np.ndarray:
        """(L,) predicted error in one length: √(e_t² + (ℓ e_r)²), e_r in rad, ℓ mm (default: the result's)."""
        ell = self.rotation_length_mm if rotation_length_mm is None else rotation_length_mm
        return np.hypot(self.error_translation_mm, ell * np.radians(self.error_rotation_deg))


def _check(T: np.ndarray, c: np.ndarray, n: np.ndarray, r: np.ndarray) -> None:
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise CadfeatError(f"pose_information: T_cam_part must have shape (L, 4, 4), got {T.shape}")
    per_pose = c.ndim == 3 and c.shape[0] == T.shape[0]  # one hole set per pose (designs stacked along L)
    if (c.ndim != 2 and not per_pose) or c.shape[-1] != 3 or n.shape != c.shape or r.shape != c.shape[:-1]:
        raise CadfeatError(f"pose_information: centres (N, 3), normals (N, 3) and radii_mm (N,) (or (L, N, 3), "
                           f"(L, N, 3), (L, N): one hole set per pose) must agree, got {c.shape}, {n.shape}, {r.shape}")
    for name, a in (("T_cam_part", T), ("centres", c), ("normals", n), ("radii_mm", r)):
        if not np.all(np.isfinite(a)):
            raise CadfeatError(f"pose_information: {name} must be finite")
    if np.any(r < 0) or np.any(np.linalg.norm(n, axis=-1)[r > 0] == 0):
        raise CadfeatError("pose_information: radii_mm must be >= 0 and normals non-zero where radii_mm > 0")


def _metric(ell: float) -> np.ndarray:
    """S = diag(1, 1, 1, 1/ℓ, 1/ℓ, 1/ℓ): S I S is the information of (δp, ℓ δθ), both in mm."""
    return np.array([1.0, 1.0, 1.0, 1.0 / ell, 1.0 / ell, 1.0 / ell])


def _inverse(info: np.ndarray, ell: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Covariance (L, 6, 6) (inf on the diagonal where singular), eigenvalues (L, 6) ascending and
    eigenvectors (L, 6, 6) of S I S (scaled so translation and rotation are commensurate)."""
    s = _metric(ell)
    scaled = info * s[:, None] * s[None, :]
    w, V = np.linalg.eigh(0.5 * (scaled + np.swapaxes(scaled, -1, -2)))
    top = np.maximum(w[..., -1:], 1e-300)
    ok = w > RANK_TOL * top
    inv_w = np.where(ok, 1.0 / np.where(ok, w, 1.0), 0.0)
    cov_scaled = np.einsum("lij,lj,lkj->lik", V, inv_w, V)
    cov = cov_scaled * s[:, None] * s[None, :]
    singular = ~ok.all(axis=-1)
    if singular.any():  # a direction with no information: infinite variance on every coordinate it touches
        d = np.arange(6)
        touched = np.einsum("lij,lj->li", V ** 2, (~ok).astype(float)) > 1e-12
        cov[:, d, d] = np.where(touched, np.inf, cov[:, d, d])
    return cov, w, V


def direction_words(v: np.ndarray) -> str:
    """Words for a unit direction v (6,) of (δp, ℓ δθ) in the camera frame: its dominant part (translation or
    rotation) and the camera axis it is closest to, e.g. "rotation about the optical axis"."""
    v = np.asarray(v, dtype=float)
    t2, r2 = float(v[:3] @ v[:3]), float(v[3:] @ v[3:])
    part = v[:3] if t2 >= r2 else v[3:]
    axis = int(np.argmax(np.abs(part)))
    purity = float(np.abs(part[axis]) / max(np.linalg.norm(part), 1e-300))
    kind = "translation along" if t2 >= r2 else "rotation about"
    words = f"{kind} {_AXES[axis]}"
    mix = min(t2, r2) / max(t2 + r2, 1e-300)
    if purity < 0.9:
        words += " (mixed with other axes)"
    if mix > 0.2:
        words += " coupled with " + ("rotation" if t2 >= r2 else "translation")
    return words


def pose_information(camera: Camera, T_cam_part: ArrayLike, centres: ArrayLike, normals: ArrayLike,
                     radii_mm: ArrayLike, *, sigma_px: float | ArrayLike | None = None, detection: bool = True,
                     occlusion: ArrayLike | None = None, depth_ratio: ArrayLike | None = None,
                     kinds: Any = None, through: ArrayLike | None = None, noise_grey: float = D.NOISE_SIGMA_GREY,
                     offsets: bool = True, rotation_length_mm: float = 50.0,
                     prior_sigma: tuple[float, float] | None = None, offset_px: ArrayLike | None = None,
                     model: Any = None, contrast_rate: ArrayLike | None = None) -> PoseInformation:
    """Fisher information, CRLB and predicted pose error (module docstring) of holes seen from L poses.

    Parameters
    ----------
    camera : the camera (intrinsics, distortion, focus and aperture for the defocus blur).
    T_cam_part : (L, 4, 4) poses of the part in the camera frame, mm.
    centres, normals, radii_mm : (N, 3) rim centres (mm), (N, 3) axes out of the material, (N,) rim radii (mm;
        0 = a point feature, measured at its projection); or (L, N, 3), (L, N, 3), (L, N): one hole set per pose
        (several designs' trajectories stacked along L; ``depth_ratio`` may then be (L, N)).
    sigma_px : a number (or (L, N) array) fixes the centre noise σ (px) and switches the offsets off; None
        uses the measurement model (``pose_models``).
    detection : False counts every hole in front of the camera (p = 1 where the hole faces the camera and, when
        ``occlusion`` is given, its rim is not hidden; for checks); True uses the smooth detection model.
    occlusion : (L, N) hidden fraction of each rim in [0, 1] (``rim_occlusion``), or bool (hidden); None = none.
    depth_ratio, kinds, through : per hole (N,) depth/diameter, kind ("plain", "counterbore", ...) and through
        flag for the offset model; None = shallow plain blind holes.
    noise_grey : the sensor's grey-level noise (the σ model scales with it).
    offsets : include the detector's systematic offsets (bias); False = noise only.
    rotation_length_mm : ℓ, the lever that turns rotation into length (share, weakest direction, ``error_mm``).
    prior_sigma : (mm, rad) a weak prior added to the information (finite bound with < 3 holes); None = none.
    offset_px : (L, N, 2) measured or assumed offsets b (px) replacing the model's (e.g. a closed loop's
        measured detection offsets, to propagate them through the pose Jacobians).
    model : a ``pose_models.PoseModels`` (default: the committed calibration).
    contrast_rate : (L, N) a factor on the detection rate from the part's own light (``measures.glare``:
        a blind rim in a conductor against a bright face); None = 1.
    """
    # lazy: import cycle (cadfeat.measures.pose_models imports cadfeat.measures.pose_information)
    from cadfeat.measures import pose_models
    from cadfeat.measures.rim_centre import measure

    T = np.asarray(T_cam_part, dtype=float)
    c = np.asarray(centres, dtype=float)
    n = np.asarray(normals, dtype=float)
    r = np.asarray(radii_mm, dtype=float)
    _check(T, c, n, r)
    if not (rotation_length_mm > 0):
        raise CadfeatError(f"pose_information: rotation_length_mm must be > 0, got {rotation_length_mm!r}")
    L, N = T.shape[0], c.shape[-2]
    models = model or pose_models.default_models()
    geo = pose_models.hole_geometry(camera, T, c, n, r)
    z, J = measure(camera, T, c, n, r)                                    # (L, N, 2), (L, N, 2, 6)
    assert J is not None  # (measure with jacobian=True)
    occ = np.zeros((L, N)) if occlusion is None else np.broadcast_to(np.asarray(occlusion, dtype=float), (L, N))
    if detection:
        p = models.detection_probability(geo, occ, depth_ratio=depth_ratio, through=through)
        if contrast_rate is not None:
            p = p * np.broadcast_to(np.asarray(contrast_rate, dtype=float), (L, N))
    else:
        p = (geo.in_front & (geo.facing > 0) & (occ <= models.o0)).astype(float)
    sig, off = _noise_and_offsets(models, geo, (L, N), sigma_px, depth_ratio, kinds, through, noise_grey, offsets,
                                  offset_px)
    p, per_hole, rhs = weighted_information(p, J, sig, off)
    info = per_hole.sum(axis=1)
    if prior_sigma is not None:
        info = info + np.diag(np.repeat([1.0 / prior_sigma[0] ** 2, 1.0 / prior_sigma[1] ** 2], 3))
    cov, w, V = _inverse(info, rotation_length_mm)
    bias, sig_t, sig_r, b_t, b_r = pose_errors(cov, rhs)
    share = _information_share(per_hole, rotation_length_mm)
    weakest = V[:, :, 0]
    weakest_sigma = np.where(w[:, 0] > RANK_TOL * np.maximum(w[:, -1], 1e-300),
                             1.0 / np.sqrt(np.maximum(w[:, 0], 1e-300)), np.inf)
    return PoseInformation(info, cov, sig_t, sig_r, bias, b_t, b_r, np.hypot(b_t, sig_t), np.hypot(b_r, sig_r),
                           share, weakest, weakest_sigma, p, sig, off, z, J, p >= 0.5,
                           float(rotation_length_mm))


def weighted_information(p: np.ndarray, J: np.ndarray, sig: np.ndarray,
                         off: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per hole and pose: the detection weights p (L, N) (0 where the Jacobian is not finite), the information
    p J̃ᵀJ̃ (L, N, 6, 6) with J̃ = J/σ, and the bias right-hand side Σ_j p J̃ᵀ b/σ (L, 6) (module docstring)."""
    p = np.where(np.all(np.isfinite(J), axis=(-1, -2)), p, 0.0)
    Jw = np.where(p[..., None, None] > 0, J, 0.0) / sig[..., None, None]      # J̃ = J/σ (L, N, 2, 6)
    per_hole = np.einsum("ln,lnai,lnaj->lnij", p, Jw, Jw)                     # p J̃ᵀJ̃ (L, N, 6, 6)
    rhs = np.einsum("ln,lnai,lna->li", p, Jw, off / sig[..., None])            # JᵀW b (L, 6)
    return p, per_hole, rhs


def pose_errors(cov: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, ...]:
    """From the covariance (L, 6, 6) and the bias right-hand side (L, 6): the bias δ_b = cov · rhs (L, 6), the
    noise σ of translation (mm) and rotation (deg) and the bias norms b_t (mm), b_r (deg), each (L,)."""
    bias = np.einsum("lij,lj->li", np.where(np.isfinite(cov), cov, 0.0), rhs)
    sig_t = np.sqrt(np.trace(cov[:, :3, :3], axis1=-2, axis2=-1))
    sig_r = np.degrees(np.sqrt(np.trace(cov[:, 3:, 3:], axis1=-2, axis2=-1)))
    b_t, b_r = np.linalg.norm(bias[:, :3], axis=-1), np.degrees(np.linalg.norm(bias[:, 3:], axis=-1))
    return bias, sig_t, sig_r, b_t, b_r


def _noise_and_offsets(models: Any, geo: Any, shape: tuple[int, int], sigma_px: float | ArrayLike | None,
                       depth_ratio: ArrayLike | None, kinds: Any, through: ArrayLike | None, noise_grey: float,
                       offsets: bool, offset_px: ArrayLike | None) -> tuple[np.ndarray, np.ndarray]:
    """Each hole's centre noise σ_j (L, N) px and systematic offset b_j (L, N, 2) px: a fixed ``sigma_px`` (no
    offsets), else the measurement model (``offsets`` False: σ only); ``offset_px`` replaces the offsets."""
    L, N = shape
    if sigma_px is not None:
        sig = np.broadcast_to(np.asarray(sigma_px, dtype=float), (L, N)).copy()
        if np.any(~(sig > 0)):
            raise CadfeatError(f"pose_information: sigma_px must be > 0 px, got {sigma_px!r}")
        off = np.zeros((L, N, 2))
    else:
        sig, off = models.measurement_model(geo, depth_ratio=depth_ratio, kinds=kinds, through=through,
                                            noise_grey=noise_grey)
        if not offsets:
            off = np.zeros_like(off)
    if offset_px is not None:
        off = np.broadcast_to(np.asarray(offset_px, dtype=float), (L, N, 2))
        off = np.where(np.isfinite(off), off, 0.0)
    return sig, off


def _information_share(per_hole: np.ndarray, rotation_length_mm: float) -> np.ndarray:
    """Each hole's share of the information (L, N): tr(S I_j S) / Σ_k tr(S I_k S), S = ``_metric(ℓ)`` putting
    rotation and translation in mm (0 where no hole is informative)."""
    s = _metric(rotation_length_mm)
    tr_hole = np.einsum("lnii,i->ln", per_hole, s * s)
    total = tr_hole.sum(axis=1, keepdims=True)
    return np.where(total > 0, tr_hole / np.where(total > 0, total, 1.0), 0.0)
