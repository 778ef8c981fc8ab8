"""Detection and measurement models of a hole's rim-ellipse centre, calibrated on cadfeat's own detector.

Inputs per hole and pose (``hole_geometry``, camera frame): the rim's image ellipse (``hole_ellipse``: minor
axis m px, major M px), its image margin f px (``image_margin_from_ellipse``; ≥ 0 when the whole rim is in the
image), the facing cosine cos θ (θ the view angle from the hole's axis), the thin-lens defocus blur β px at the
hole's depth (``measures.focus.defocus_diameter_px``), the rim's length ρ px (Ramanujan's ellipse perimeter) and
the image direction d̂ of the hole's axis into the material.

**Detection probability** (smooth, for the optimiser; ``detected = p ≥ 0.5`` for reports), a product of
logistic terms s(x) = 1 / (1 + e⁻ˣ):

    p = s((m − κ β − m₀)/w_m) · s(f / w_f) · s((cos θ − c₀)/w_c) · o(occ) · [ellipse valid, in front]

with o(occ) = s((o₀ − occ)/w_o) / s(o₀/w_o) for the hidden fraction occ of the rim (1 at occ = 0, → 0 once a
few per cent are hidden: the detector rejects a rim that is cut or crossed by an edge — never accepts it as
whole), times s((g − g₀)/w_g) for the image gap g px between the rim and the nearest other hole's rim
(``rim_gap_px``; g₀ = ``RIM_GAP_MIN_PX``, the closed loop's association rule, not a fit): a neighbouring edge
inside the detector's surround ring either shifts the fitted centre or fails the ring test, so such a hole is
dropped, never measured as if alone.

**Association** (``vision.detection.associate``): a detection is matched to hole j only within the gate
G_j = min(G, ½ · the image distance from j's predicted rim centre to the nearest other hole's predicted centre),
G = ``gate_px``, counting every hole whose predicted rim ellipse is valid (in front of the camera), whether or
not it is seen: the closed loop's rule. The predicted centres are those of the nominal pose, and the part sits
off it by the cell's placement error (σ_t mm, σ_θ rad per axis, ``TrackingConfig.placement_mm`` /
``placement_deg``), so the detected rim lies off its prediction by Δ ~ N(0, P Σ Pᵀ): P = ∂(u, v)/∂x the
projection's 2×3 Jacobian at the hole's centre x (camera frame), Σ = σ_t² I + σ_θ² (|a|² I − a aᵀ) the centre's
displacement for a translation σ_t and a rotation σ_θ about the part's origin, a the hole's position from that
origin. With σ̄² = tr(P Σ Pᵀ)/2 per axis (isotropic approximation),

    P(|Δ| < G_j) ≈ a(G_j) = 1 − exp(−G_j² / (2 σ̄²))

multiplies p. It matters where another hole's predicted centre (a hidden one, e.g. a hole on a face turned away
that projects onto a visible hole) comes within a few σ̄ of a seen hole's: on the flagship panel that drops a
target at a frame where the other holes leave it clear (design "sobol 1": H2 at frame 6, 2.9 px from H8's
predicted centre, gate 1.45 px against σ̄ ≈ 2 px: detected in 0 of 8 runs, p = 1 before this term).

**Centre noise** (px): a least-squares ellipse through ρ boundary points, each with edge noise proportional to
the grey-level noise and to the edge width √(w₀² + β²), has a centre noise ∝ 1/√ρ:

    σ = √(σ₀² + (k_σ · (noise_grey / 2) · √(w₀² + β²))² / ρ + a² + k_a² / ρ)

The last term is the **pixel-grid (aliasing) error**: the rendered rim is a staircase on the pixel grid, so the
fitted centre is off by a few hundredths of a pixel in a direction that depends on the rim's sub-pixel
placement. It does not average out over noise draws, but it changes with the placement: over a cell's
placement tolerance (and from frame to frame as the part moves) it acts as zero-mean noise of per-axis RMS
√(a² + k_a²/ρ). ``tools/calibrate_detection.py`` measures it as the spread of the mean offset over 6 placements
per condition and fits it in log space: a = 0, k_a ≈ 0.39 px — the 1/√ρ law of a least-squares ellipse through
ρ boundary points with independent staircase errors (each ≈ the ±½ px quantisation, RMS 0.29 px: √2 · 0.29 ≈
0.41). On the flagship the closed loop's measured offsets (0.037–0.067 px per axis for rims of 1–3 mm radius)
follow the same law.

**Systematic offset** (px, along d̂): the detector fits the rim's edge where the smoothed image crosses a
threshold between the lit face and the dark hole; what remains is

    b = [(k_b · β + k_w + k_d · D · min(depth/diameter, 2)) · sin θ  +  k_i · √(w₀² + β²) · g · ΔI] · d̂

with D = 1 for through holes, 0.5 blind. The first bracket is the asymmetric blur of an oblique rim (k_b) and
what the calibration leaves of a constant and a depth term. The second is the **interior contrast** term: just
inside the rim the detector's edge sees a different grey on the two sides of an oblique hole. On the side
opposite d̂ it sees the bore's wall, lit at cos γ = sin θ; on the d̂ side the line of sight past the rim goes
down the bore and meets the floor (blind hole, lit at cos θ) or the background (through hole, black) while
depth/diameter · tan θ < 1, else the opposite wall (the same grey, no offset). A brighter interior moves that
side's threshold crossing inwards by ≈ ½ w ΔI/I (a linear edge ramp of width w, threshold at mid-grey), so the
centre moves by ≈ ¼ w ΔI/I along the side with the brighter interior — k_i ≈ ¼ for w = √(w₀² + β²), the edge
width of the σ model. With the renderer's Lambert shading under the camera's headlight (``render.camera_views``:
a directional light along the optical axis ℓ; a face at cos γ to it has the level A + (1 − A) cos γ,
A = ``SHADE_AMBIENT``) and the hole faces' albedo q relative to the part's (``HOLE_ALBEDO``):

    ΔI = q · v · (L(c_w) − L_far) / L(c_f),   L(c) = A + (1 − A) c,   v = s((1 − depth/diameter · tan θ) / 0.1)
    L_far = L(c_f) blind or counterbore (its step's floor), 0 through

with c_f = n · ℓ the face's and floor's cosine and c_w the wall's (its inward normal: the line of sight's part
across the axis); for a hole on the optical axis c_f = cos θ, c_w = sin θ, off the axis the wall is darker (a
plate square to the optical axis: c_w ≈ 0 whatever θ).

**Chamfered rims are not modelled apart** (left open): the rim's edge then meets a 45° cone, lit at
(c_f ± c_w)/√2 on the two sides, and the closed loop measures the flagship's chamfered targets at 38–42° at
+0.014–0.020 px along d̂, where the plain blind rule gives −0.011–0.017 px. The cone's contrast only takes over
once the chamfer is wider than the edge (≥ 2 px; the flagship's chamfers are 0–0.8 mm, 0–5 px), which needs the
chamfer width (the bore radius) in the batched objective's inputs; applied at full strength whatever the width
it ranked the flagship panel's rotation worse (ρ 0.75 → 0.36), and faded in with the chamfer's width (tanh(w / 2 px),
the width from the rebuilt holes' bore radii) still worse (0.51): the cone's shading alone does not describe the
chamfered rims' offsets. A chamfered rim is treated as its plain hole.

**Flat floors** (physically lit worlds): a blind hole's flat floor is parallel to the face, of the same finish
and lit alike, so inside the rim it images at the face's grey; the rim shows as an edge only where the bore's
wall shows. Detection then needs q = depth/diameter · tan θ (the wall's share of the rim's minor axis) past a
threshold: p is multiplied by s((q − q₀)/w_q) for blind holes (1 for through holes and in the raster world,
whose hole faces are painted dark: w_q = 0 turns the term off). ``detection_probability`` takes the holes'
``depth_ratio`` and ``through`` for it (``pose_information`` and ``design.pose_terms`` pass them).

Parameters (``PoseModels``) are fitted by ``tools/calibrate_detection.py`` on rendered images of a test
plate over a grid of causes; the table it measured and the fitted values are package data
(``measures/data/detection_calibration.csv`` and ``detection_model.json``: the threshold detector
``detection.detect_holes`` on raster renders, ``default_models()``).

**Per-world calibrations** (``models_for(cell, renderer)``): the closed loop's detector is now cadfeat's
rim-edge detector (``vision.detectors``), its prior the predicted rim at the nominal pose; the script calibrates
it per world — the renderer and, physically based (Mitsuba 3, 16 spp, metered exposure), the material, the
light and the hole ends — as ``detection_model_<key>.json`` + ``detection_calibration_<key>.csv``
(``model_key``). ``models_for`` takes the cell's detector, material, light and hole ends in the physical world
("pbr"), the nearest calibration of the same detector where none matches (``model_distance``; the choice is in
``source``), and ``default_models()`` where the detector has none; ``design.pose_terms.cell_models`` uses it.
Fitted on their own tables (rate: mean |p − rate| over the unoccluded rows; offset: RMS axis residual px;
``offset_rms_px``: the unexplained systematic offset per axis, added to σ, of the rims the offset model describes
— through holes and sharp-rimmed blind holes of depth/diameter 1.0 —, then of the shallow blind holes (d/D 0.3)
and the chamfered rims, ``PoseModels.unexplained_px``). The rim-edge detector's physically based worlds were
re-rendered 2026-11-28 after its refinement step read a less smoothed image (``vision.edge_detector``); the single
constant of every rim before was 0.159 px on machined aluminium, now 0.069 for the rims described, 0.255 for
shallow ones:

================================================ ===== ======= ========= ======= ===== =======================
world (key)                                      rows  rate    offset    m₀ px   q₀    offset_rms_px (shallow,
                                                                                       chamfered)
================================================ ===== ======= ========= ======= ===== =======================
threshold, raster (``detection_model.json``)     366   0.032   0.028     2.38    —     —
cadfeat, raster                                  546   0.030   0.026     4.02    —     0.000 (0.000, 0.004)
cadfeat, pbr machined_aluminium ring as_modelled 396   0.245   0.199     3.93    0.06  0.069 (0.255, 0.155)
cadfeat, pbr blasted_aluminium ring as_modelled  396   0.183   0.140     4.06    0.10  0.035 (0.170, 0.127)
cadfeat, pbr machined_aluminium ring drilled     396   0.200   0.125     3.95    −0.16 0.075 (0.030, 0.102)
cadfeat, pbr grey_plastic ring as_modelled       396   0.172   0.287     4.26    −0.27 0.137 (0.207, 0.286)
cadfeat, pbr machined_aluminium coaxial          396   0.218   0.185     3.92    0.10  0.047 (0.204, 0.171)
cadfeat, pbr grey_plastic ring drilled           396   0.134   0.207     4.11    −0.50 0.099 (0.088, 0.226)
cadfeat, pbr machined_steel ring as_modelled     396   0.225   0.236     3.97    0.11  0.109 (0.288, 0.178)
cadfeat, pbr machined_aluminium dome             396   0.224   0.266     3.81    0.37  0.040 (0.175, 0.304)
edcircles, raster                                546   0.112   0.046     7.56    —     0.021
edcircles, pbr machined_aluminium ring           396   0.199   1.403     8.36    −0.30 0.977
================================================ ===== ======= ========= ======= ===== =======================

Against the threshold detector the rim-edge detector needs a larger rim (m₀ 2.4 → 4.0 px), does not mind blur
(κ 0.30 → 0), has ~4.6× its noise σ (median 0.022 vs 0.0048 px; the pixel-grid term, 0.06 px, is the same) and
almost no interior-contrast offset (k_i 0.27 → 0.04: it takes the outermost step edge, not a threshold
crossing); the threshold model on the edge detector's table: σ off by e^1.6 RMS, rate MAE 0.069.

**What the physically based models do not describe** (measured on the tables; rate / mean axis offset px by view
angle, bores 1.5 and 3 mm at 300 and 520 mm; machined aluminium under the ring light unless said):

- *Flat-floored blind holes seen head-on are not found* (0°: rate 0.00–0.17 in aluminium and plastic; the
  floor mirrors or diffuses the light like the face) — the flat-floor term describes it; drilled ends (a 118°
  point) are found head-on (0.99–1.00): ``hole_ends`` is a first-order cause.
- *A 45° rim chamfer* (0.3 or 1.0 mm) is found by its OUTER edge on machined aluminium (ring, coaxial: the found
  ellipse's size never more than 0.4 of the way from the rim to the bore); a narrow one (0.3 mm, ~1 px at
  300 mm) on grey plastic or blasted aluminium is found at or inside the BORE edge at 45–72° (9 of ~34 rows
  each; held out, a 0.4 mm chamfer at 55° on plastic: size 0.85 of the rim, bore/rim 0.875, offset −0.80 px);
  a 1.0 mm one keeps the outer edge (2 plastic rows at 60° excepted). A chamfer makes a flat-floored blind
  hole visible head-on (0°: 0.92–1.00 vs 0.00–0.17), but its rim is off along the axis by +0.3 to +0.8 px at
  25° (aluminium +0.54 to +0.59, plastic +0.41 to +0.66; the plain model's offset there ≈ 0). The models see a
  chamfered rim as a plain hole of the rim's radius (they take no bore radius; ``design.hole_form.design_bores``
  has it per design, the chamfer width being rim − bore: the input a chamfer term would need), so they neither
  credit the head-on detection nor charge the systematic offset: a chamfered rim (``Hole.kind`` "…, chamfered
  rim") gets the chamfered rows' unexplained offset as noise instead (``offset_rms_chamfer_px``, the table
  above; measured with the single-scale detector 0.25 px aluminium, 0.44 px plastic); through the rim radius a
  chamfer lowers q and
  the PBR models penalise it slightly. **Constrain** the chamfer design variable (flagship
  ``target_chamfer_mm``) to 0 in physically based cells until a chamfer-aware term exists.
- *Shallow blind holes seen at 45–60°* are off by −0.5 to −0.7 px (d/D 0.3: aluminium −0.60 at 45°, plastic
  −0.68 at 60°; held-out d/D 0.6 at 35° on aluminium −0.22 and −0.36; d/D 1.0 flat-floored within ±0.25, drilled
  −0.42 at 25°): the wall/floor boundary pulls the fit; their unexplained offset is ``offset_rms_shallow_px``
  (interpolated towards d/D 1.0). **Constrain** blind targets to depth/diameter ≥ 0.5
  (interpolated between the grid's 0.3 and 1.0; flagship: ``target_depth_mm`` ≥ ``target_radius_mm``).
- *Through holes at 45° in aluminium* (rate 0.29 machined, 0.40 blasted, vs 0.81 plastic): the bore's wall
  lit to the face's grey hides the rim on that side (the edge detector's documented limit); not modelled.
- *A marginal detection (rate 0.5–0.6) can be off by 1–2 px* (it takes another edge): held-out, a Ø 4.4 blind
  hole d/D 0.6 at 20° on aluminium −2.1 px, at 35° on plastic −1.0 px — far outside σ; the model weights such a
  hole by p ≈ 0.6 as if its centre were good.
- *A dome on machined aluminium* hides the holes (mean rate 0.14; through holes at 0–25°: 0.00 — the polished
  face mirrors the same uniform dome the bore shows): its model (p mostly 0) is a fit to near-failure, a cell
  to avoid rather than a part to design for.
- *Path-tracing noise* at 16 spp flips marginal conditions between frames (the rates are per-placement
  averages of 4 frames): the PBR rates are coarse, and the rate residuals (12–18 % of the rows off by > 0.5)
  reflect it as much as the model's form.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from functools import lru_cache
from importlib import resources
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from cadfeat.camera import Camera
from cadfeat.cell import defaults as D
from cadfeat.measures.ellipse import hole_ellipse
from cadfeat.measures.focus import defocus_diameter_px
from cadfeat.measures.fov import image_margin_from_ellipse
from cadfeat.measures.visibility import facing_margin

if TYPE_CHECKING:  # pragma: no cover
    from numpy.typing import ArrayLike

    from cadfeat.cell import Cell

DATA = "data"
MODEL_FILE = "detection_model.json"
TABLE_FILE = "detection_calibration.csv"


class HoleGeometry(NamedTuple):
    """Per pose × hole (L, N) quantities the models use (module docstring); ``axis_dir_px`` (L, N, 2)."""

    minor_px: np.ndarray
    major_px: np.ndarray
    margin_px: np.ndarray
    facing: np.ndarray
    blur_px: np.ndarray
    rim_px: np.ndarray
    axis_dir_px: np.ndarray
    valid: np.ndarray
    in_front: np.ndarray
    rims: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None  # centre, axes, angle px, edge
    #: cosines to the camera's headlight (a directional light along the optical axis) of the hole's face and
    #: floor (axis · ℓ) and of the wall seen inside the rim (``interior_contrast``); None = those of a hole on
    #: the optical axis (cos θ, sin θ)
    light_face: np.ndarray | None = None
    light_wall: np.ndarray | None = None
    #: (L, N) the association gate's distance term: ½ · the image distance (px) to the nearest other hole's
    #: predicted rim centre, counting every valid rim (seen or not; ``associate``); inf with one hole
    half_spacing_px: np.ndarray | None = None
    #: (L, N) per-axis image shift (px) of the rim centre per mm of placement translation and per rad of
    #: placement rotation about the part's origin (RMS over directions; ``PoseModels.association``)
    shift_px_per_mm: np.ndarray | None = None
    shift_px_per_rad: np.ndarray | None = None

    def rim_gap_px(self, occlusion: ArrayLike | None = None) -> np.ndarray | None:
        """(L, N) image gap to the nearest other rim that shows as an edge (``rim_gap_px``): in front, facing
        the camera and, given the rims' hidden fractions ``occlusion`` (L, N), less than half hidden."""
        if self.rims is None:
            return None
        centre, axes, angle, edge = self.rims
        if occlusion is not None:
            edge = edge & (np.broadcast_to(np.asarray(occlusion, dtype=float), edge.shape) < EDGE_HIDDEN_MAX)
        return rim_gap_px(centre, axes, angle, edge)


def _sigmoid(x: np.ndarray | float) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * np.asarray(x, dtype=float)))


def hole_geometry(camera: Camera, T_cam_part: np.ndarray, centres: np.ndarray, normals: np.ndarray,
                  radii_mm: np.ndarray) -> HoleGeometry:
    """``HoleGeometry`` of holes (N, 3), (N, 3), (N,) (part frame, mm) at poses (L, 4, 4)."""
    T = np.asarray(T_cam_part, dtype=float)
    Rm, t = T[:, :3, :3], T[:, :3, 3]
    Rt = np.swapaxes(Rm, 1, 2)  # holes (N, 3) or one set per pose (L, N, 3): R x as x Rᵀ, broadcast over L
    c = np.asarray(centres, dtype=float) @ Rt + t[:, None, :]
    nrm = np.linalg.norm(normals, axis=-1, keepdims=True)
    n = (normals / np.where(nrm > 0, nrm, 1.0)) @ Rt
    r = np.broadcast_to(np.asarray(radii_mm, dtype=float), c.shape[:-1])
    e = hole_ellipse(camera, c, n, r)
    valid = np.asarray(e.valid, dtype=bool)
    major, minor = e.axes_px[..., 0], e.axes_px[..., 1]
    a, b = 0.5 * major, 0.5 * minor
    h = ((a - b) / np.maximum(a + b, 1e-12)) ** 2
    rim = np.pi * (a + b) * (1.0 + 3.0 * h / (10.0 + np.sqrt(np.maximum(4.0 - 3.0 * h, 0.0))))
    Z = c[..., 2]
    in_front = Z > 1.0
    step = np.maximum(r, 0.1)[..., None] * 0.1
    deeper = c - step * n
    z0 = np.where(in_front[..., None], c, np.array([0.0, 0.0, 1.0]))
    z1 = np.where(in_front[..., None] & (deeper[..., 2:] > 1.0), deeper, z0)
    d = camera.project(z1) - camera.project(z0)
    dn = np.linalg.norm(d, axis=-1, keepdims=True)
    axis_dir = np.where(dn > 1e-12, d / np.where(dn > 1e-12, dn, 1.0), 0.0)
    point = r <= 0  # point features (radius 0): no rim, no facing; the projected point must be in the image
    valid = np.where(point, in_front, valid)
    facing = np.where(point, 1.0, facing_margin(c, n))
    pp = camera.project(np.where(in_front[..., None], c, np.array([0.0, 0.0, 1.0])))
    point_margin = np.minimum(np.minimum(pp[..., 0], camera.width - pp[..., 0]),
                              np.minimum(pp[..., 1], camera.height - pp[..., 1]))
    margin = np.where(point, point_margin, image_margin_from_ellipse(camera, e))
    rims = (np.asarray(e.centre_px), np.asarray(e.axes_px), np.asarray(e.angle_rad),
            valid & in_front & (facing > 0) & ~point)
    # the headlight shines along the optical axis (ℓ = −ẑ towards the camera): the face and floor get n · ℓ; the
    # wall seen inside the rim is the one across the bore from the camera, its inward normal the line of sight's
    # part across the axis
    view = -c / np.maximum(np.linalg.norm(c, axis=-1, keepdims=True), 1e-12)
    across = view - np.sum(view * n, axis=-1, keepdims=True) * n
    an = np.linalg.norm(across, axis=-1)
    light_face = np.clip(-n[..., 2], 0.0, 1.0)
    light_wall = np.clip(-across[..., 2] / np.maximum(an, 1e-12), 0.0, 1.0)
    shift_t, shift_r = placement_shift_px(camera, c, c - t[:, None, :])
    return HoleGeometry(minor, major, margin, facing,
                        defocus_diameter_px(camera, np.maximum(Z, 1.0)), rim, axis_dir, valid, in_front, rims,
                        light_face, light_wall, half_spacing_px(np.asarray(e.centre_px), valid & in_front),
                        shift_t, shift_r)


def half_spacing_px(centre_px: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """(L, N) half the image distance (px) from each predicted rim centre (L, N, 2) to the nearest other valid
    one (``valid`` (L, N); inf where there is none): the distance term of ``associate``'s gate."""
    cp = np.asarray(centre_px, dtype=float)
    ok = np.asarray(valid, dtype=bool) & np.all(np.isfinite(cp), axis=-1)
    N = cp.shape[-2]
    diff = cp[..., :, None, :] - cp[..., None, :, :]
    d = np.sqrt(np.einsum("...ijk,...ijk->...ij", diff, diff))
    d = np.where(np.eye(N, dtype=bool) | ~ok[..., None, :] | ~np.isfinite(d), np.inf, d)
    return 0.5 * d.min(axis=-1) if N > 1 else np.full(cp.shape[:-1], np.inf)


def placement_shift_px(camera: Camera, centre_cam: np.ndarray, lever_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis RMS image shift (px) of points ``centre_cam`` (L, N, 3) (camera frame, mm) per mm of an isotropic
    translation and per rad of an isotropic rotation about the part's origin, ``lever_mm`` (L, N, 3) the points'
    positions from it (camera axes): √(tr(P Pᵀ)/2) and √(tr(P (|a|² I − a aᵀ) Pᵀ)/2), P the pinhole projection's
    2×3 Jacobian (fx/Z, fy/Z; −x/Z² terms) at the point."""
    x = np.asarray(centre_cam, dtype=float)
    Z = np.maximum(x[..., 2], 1e-9)
    P = np.zeros(x.shape[:-1] + (2, 3))
    P[..., 0, 0] = camera.fx / Z
    P[..., 1, 1] = camera.fy / Z
    P[..., 0, 2] = -camera.fx * x[..., 0] / Z ** 2
    P[..., 1, 2] = -camera.fy * x[..., 1] / Z ** 2
    a = np.asarray(lever_mm, dtype=float)
    PPt = np.einsum("...ik,...jk->...ij", P, P)
    Pa = np.einsum("...ik,...k->...i", P, a)
    tr_t = np.trace(PPt, axis1=-2, axis2=-1)
    tr_r = np.sum(a * a, axis=-1) * tr_t - np.sum(Pa * Pa, axis=-1)
    return np.sqrt(0.5 * tr_t), np.sqrt(np.maximum(0.5 * tr_r, 0.0))


#: A rim that comes closer than this (px) to another hole's rim in the image is not detected: the detector's
#: surround ring (``vision.detection``, 2.5 px outside the fitted rim) cannot tell a neighbouring edge from the
#: rim's own, and the closed loop drops such holes at association (``vision.closed_loop.RIM_GAP_MIN_PX``).
RIM_GAP_MIN_PX = 3.0
#: The renderer's shading (``render.camera_views``: ambient 0.3, diffuse 0.75 under a 0.75 headlight): a face at
#: cos γ to the line of sight has the grey level ∝ A + (1 − A) cos γ with A = 0.3 / (0.3 + 0.75 · 0.75).
SHADE_AMBIENT = 0.3 / (0.3 + 0.75 * 0.75)
#: Hole faces' albedo over the part's: luma (BT.601) of ``render.scene.HOLE_DARK`` over ``PART_GREY``.
HOLE_ALBEDO = (0.299 * 0.06 + 0.587 * 0.06 + 0.114 * 0.07) / (0.299 * 0.82 + 0.587 * 0.82 + 0.114 * 0.84)
#: A neighbouring rim counts as an edge in the image while less than this fraction of it is hidden by the part.
EDGE_HIDDEN_MAX = 0.5


def _radius_along(axes_px: np.ndarray, major_dir: np.ndarray, unit: np.ndarray) -> np.ndarray:
    """Distance (px) from an ellipse's centre to its boundary along the image direction ``unit`` (..., 2):
    ab / √((b cos ψ)² + (a sin ψ)²), ψ the angle from the major axis ``major_dir`` (..., 2); a, b the semi-axes."""
    a, b = 0.5 * axes_px[..., 0], 0.5 * axes_px[..., 1]
    cos_p = unit[..., 0] * major_dir[..., 0] + unit[..., 1] * major_dir[..., 1]
    sin_p = unit[..., 0] * major_dir[..., 1] - unit[..., 1] * major_dir[..., 0]
    return a * b / np.maximum(np.sqrt((b * cos_p) ** 2 + (a * sin_p) ** 2), 1e-12)


def rim_gap_px(centre_px: np.ndarray, axes_px: np.ndarray, angle_rad: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """(L, N) image gap (px) between each hole's rim ellipse and the nearest other seen hole's rim (inf when
    there is none), along the line joining their centres: d − ρ_i − ρ_j for disjoint rims, ρ_out − d − ρ_in for a
    rim nested in another (a counterbore's), with ρ the ellipse's radius towards the other centre
    (``_radius_along``). Exact for circles seen fronto-parallel; for oblique, nearby rims it is the gap on the
    centre line (≥ the true smallest gap by at most the ellipses' curvature there). O(L N²), no rim sampling.
    ``centre_px`` (L, N, 2), ``axes_px`` (L, N, 2) full (major, minor), ``angle_rad`` (L, N), ``seen`` (L, N)."""
    cp = np.asarray(centre_px, dtype=float)
    L, N = cp.shape[:2]
    if N < 2:
        return np.full((L, N), np.inf)
    d_vec = cp[:, None, :, :] - cp[:, :, None, :]                                  # (L, i, j, 2): i → j
    d: np.ndarray = np.sqrt(np.einsum("lijk,lijk->lij", d_vec, d_vec))
    unit = d_vec / np.maximum(d, 1e-12)[..., None]
    ax = np.asarray(axes_px, dtype=float)
    ang = np.asarray(angle_rad, dtype=float)
    major = np.stack([np.cos(ang), np.sin(ang)], axis=-1)                       # (L, N, 2)
    rho_i = _radius_along(ax[:, :, None], major[:, :, None], unit)
    rho_j = np.swapaxes(rho_i, 1, 2)  # ρ_j towards i = ρ_j towards −unit: the same numbers (ψ's cos and sin negate)
    apart = d - rho_i - rho_j
    nested = np.maximum(rho_i, rho_j) - d - np.minimum(rho_i, rho_j)
    gap: np.ndarray = np.where(d >= np.maximum(rho_i, rho_j), apart, np.maximum(apart, nested))
    ok = seen[:, :, None] & seen[:, None, :] & ~np.eye(N, dtype=bool)[None] & np.isfinite(gap)
    return np.where(ok, gap, np.inf).min(axis=-1)


def interior_contrast(facing: ArrayLike, depth_ratio: ArrayLike, through: ArrayLike, minor_px: ArrayLike,
                      light_face: ArrayLike | None = None, light_wall: ArrayLike | None = None) -> np.ndarray:
    """g · ΔI (module docstring, dimensionless): the grey-level difference just inside an oblique rim between the
    wall's side and the d̂ side, over the face's level, faded in with the wall's band. ``facing`` cos θ (θ from
    the line of sight), ``depth_ratio`` depth/diameter, ``through`` bool, ``minor_px`` the rim's minor axis,
    ``light_face`` / ``light_wall`` the face's and the wall's cosines to the headlight (``HoleGeometry``; None:
    cos θ and sin θ, a hole on the optical axis); broadcast together. Smooth in θ and the depth (the optimiser
    differentiates it)."""
    cos_t = np.clip(np.asarray(facing, dtype=float), 1e-3, 1.0)
    sin_t = np.sqrt(1.0 - cos_t ** 2)
    tan_t = sin_t / cos_t
    ratio = np.maximum(np.asarray(depth_ratio, dtype=float), 0.0)
    lf = cos_t if light_face is None else np.asarray(light_face, dtype=float)
    lw = sin_t if light_wall is None else np.asarray(light_wall, dtype=float)

    def level(c: np.ndarray) -> np.ndarray:
        return SHADE_AMBIENT + (1.0 - SHADE_AMBIENT) * c

    wall = level(lw)
    far = np.where(np.asarray(through, dtype=bool), 0.0, level(lf))
    v = _sigmoid((1.0 - ratio * tan_t) / 0.1)                 # the floor / background shows past the d̂ rim
    delta = HOLE_ALBEDO * v * (wall - far) / level(lf)
    band = ratio * np.maximum(np.asarray(minor_px, dtype=float), 0.0) * tan_t
    return np.tanh(band) * delta


def _kind_is(kinds: ArrayLike | None, n: int, test: Callable[[str, str], bool]) -> np.ndarray:
    """(N,) or (L, N) bool: ``test(base, rim)`` of each hole's kind (``Hole.kind``, "<base>[, <rim>]");
    None = plain holes with sharp rims."""
    if kinds is None:
        return np.zeros(n, dtype=bool)

    def one(k: object) -> bool:
        base, _, rim = str(k).partition(",")
        return test(base.strip(), rim.strip())
    return np.vectorize(one, otypes=[bool])(np.asarray(kinds, dtype=object))


def _counterbore(base: str, rim: str) -> bool:
    return base == "counterbore"


def _chamfered(base: str, rim: str) -> bool:
    return "chamfer" in rim


#: The calibration tables' blind depths/diameters (``tools/calibrate_detection.py``): the unexplained offset of
#: a blind rim is measured at these two (``PoseModels.unexplained_px``).
SHALLOW_RATIO = 0.3
DEEP_RATIO = 1.0


@dataclass(frozen=True)
class PoseModels:
    """Parameters of the detection and measurement models (module docstring; px unless stated)."""

    m0_px: float = 5.0
    w_m_px: float = 1.0
    kappa_blur: float = 0.3
    w_f_px: float = 1.0
    c0: float = 0.2
    w_c: float = 0.05
    o0: float = 0.03
    w_o: float = 0.01
    sigma0_px: float = 0.01
    k_sigma: float = 1.0
    w0_px: float = 1.0
    k_b: float = 0.0
    k_d: float = 0.0
    k_w_px: float = 0.0
    k_i: float = 0.0
    k_alias_px: float = 0.0
    alias_floor_px: float = 0.0
    gap0_px: float = RIM_GAP_MIN_PX
    w_g_px: float = 0.3
    #: the flat-floor term (module docstring "Flat floors"): a blind hole is found once its wall shows,
    #: q = depth/diameter · tan θ ≥ q₀ (width w_q); w_q = 0 turns it off (the raster world: painted floors)
    floor_q0: float = 0.0
    floor_w_q: float = 0.0
    #: per-axis RMS (px) of the systematic offset the offset model leaves unexplained on its table (module
    #: docstring "Per-world calibrations"): added to σ in quadrature, like the pixel-grid term; 0 = none.
    #: With ``offset_rms_shallow_px`` / ``offset_rms_chamfer_px`` (None: this one for every rim) it is that of the
    #: rims the model describes — through holes and blind holes of depth/diameter ≥ ``DEEP_RATIO`` with sharp
    #: rims —, the others that of blind holes of depth/diameter ≤ ``SHALLOW_RATIO`` (the variance interpolated
    #: in depth/diameter between the two) and of chamfered rims (``unexplained_px``)
    offset_rms_px: float = 0.0
    offset_rms_shallow_px: float | None = None
    offset_rms_chamfer_px: float | None = None
    #: association (module docstring): the closed loop's gate and the σ per axis of the part's placement error —
    #: the cell's (``for_cell``: ``[cell] gate_px`` and σ = 0.4 t of its placement tolerance; not fitted)
    gate_px: float = D.GATE_PX
    placement_mm: float = D.PLACEMENT_SIGMA_MM
    placement_deg: float = D.PLACEMENT_SIGMA_DEG
    source: str = "defaults (not calibrated)"

    def detection_probability(self, geo: HoleGeometry, occlusion: np.ndarray, *, depth_ratio: ArrayLike | None = None,
                              through: ArrayLike | None = None) -> np.ndarray:
        """p (L, N) in [0, 1] (module docstring); ``occlusion`` (L, N) hidden fraction of the rim (or bool);
        ``depth_ratio`` / ``through`` (N,) or (L, N) the holes' depth/diameter and through flags for the
        flat-floor term (None: plain through holes, no floor term)."""
        occ = np.asarray(occlusion, dtype=float)
        size = _sigmoid((geo.minor_px - self.kappa_blur * geo.blur_px - self.m0_px) / self.w_m_px)
        fov = _sigmoid(np.maximum(geo.margin_px, -50.0 * self.w_f_px) / self.w_f_px)
        facing = _sigmoid((geo.facing - self.c0) / self.w_c)
        occl = _sigmoid((self.o0 - occ) / self.w_o) / _sigmoid(self.o0 / self.w_o)
        gap = geo.rim_gap_px(occ)
        near = 1.0 if gap is None else _sigmoid((np.minimum(gap, 1e6) - self.gap0_px) / self.w_g_px)
        floor = self.floor_term(geo, depth_ratio, through)
        return np.where(geo.valid & geo.in_front & (geo.facing > 0),
                        size * fov * facing * occl * near * floor * self.association(geo), 0.0)

    def floor_term(self, geo: HoleGeometry, depth_ratio: ArrayLike | None, through: ArrayLike | None
                   ) -> np.ndarray | float:
        """s((q − q₀)/w_q) for blind holes, q = depth/diameter · tan θ (module docstring "Flat floors"), (L, N);
        1 for through holes, with no depth given, or when the term is off (w_q = 0)."""
        if self.floor_w_q <= 0 or depth_ratio is None:
            return 1.0
        shape = geo.facing.shape
        ratio = np.broadcast_to(np.asarray(depth_ratio, dtype=float), shape)
        thr = np.zeros(shape, bool) if through is None else np.broadcast_to(np.asarray(through, bool), shape)
        cos_t = np.clip(geo.facing, 1e-3, 1.0)
        q = np.maximum(ratio, 0.0) * np.sqrt(1.0 - cos_t ** 2) / cos_t
        return np.where(thr, 1.0, _sigmoid((q - self.floor_q0) / self.floor_w_q))

    def association(self, geo: HoleGeometry) -> np.ndarray | float:
        """a(G_j) = 1 − exp(−G_j²/(2σ̄²)) (module docstring): the chance that hole j's detection falls inside its
        association gate, (L, N); 1.0 when the geometry carries no spacing (e.g. the calibration's table)."""
        if geo.half_spacing_px is None or geo.shift_px_per_mm is None or geo.shift_px_per_rad is None:
            return 1.0
        gate = np.minimum(self.gate_px, geo.half_spacing_px)
        var = ((geo.shift_px_per_mm * self.placement_mm) ** 2
               + (geo.shift_px_per_rad * np.radians(self.placement_deg)) ** 2)
        return -np.expm1(-gate ** 2 / (2.0 * np.maximum(var, 1e-12)))

    def unexplained_px(self, ratio: np.ndarray, through: np.ndarray, kinds: ArrayLike | None) -> np.ndarray:
        """Per-axis RMS (px) of the unexplained systematic offset of each hole, shape of ``ratio`` (its
        depth/diameter; ``through`` bool, ``kinds`` as ``Hole.kind``): ``offset_rms_px`` for the rims the offset
        model describes; a blind hole's variance interpolated linearly in depth/diameter from
        ``offset_rms_shallow_px`` at ``SHALLOW_RATIO`` to ``offset_rms_px`` at ``DEEP_RATIO`` (the table's two
        depths); ``offset_rms_chamfer_px`` for a chamfered rim (the model sees it as its plain hole)."""
        base2 = self.offset_rms_px ** 2
        shallow2 = base2 if self.offset_rms_shallow_px is None else self.offset_rms_shallow_px ** 2
        w = np.where(through, 0.0, np.clip((DEEP_RATIO - ratio) / (DEEP_RATIO - SHALLOW_RATIO), 0.0, 1.0))
        var = base2 + w * (shallow2 - base2)
        if self.offset_rms_chamfer_px is not None:
            chamfered = np.broadcast_to(_kind_is(kinds, np.shape(ratio)[-1], _chamfered), np.shape(ratio))
            var = np.where(chamfered, self.offset_rms_chamfer_px ** 2, var)
        return np.sqrt(var)

    def measurement_model(self, geo: HoleGeometry, *, depth_ratio: ArrayLike | None = None,
                          kinds: ArrayLike | None = None, through: ArrayLike | None = None,
                          noise_grey: float = D.NOISE_SIGMA_GREY) -> tuple[np.ndarray, np.ndarray]:
        """Centre noise σ (L, N) px and systematic offset b (L, N, 2) px (module docstring)."""
        rho = np.maximum(geo.rim_px, 1.0)
        edge = self.k_sigma * (noise_grey / 2.0) * np.sqrt(self.w0_px ** 2 + geo.blur_px ** 2)
        shape = geo.minor_px.shape  # (L, N); per-hole (N,) or per-pose (L, N) inputs
        ratio = np.zeros(shape) if depth_ratio is None else np.broadcast_to(np.asarray(depth_ratio, float), shape)
        thr = np.zeros(shape, bool) if through is None else np.broadcast_to(np.asarray(through, bool), shape)
        sigma = np.sqrt(self.sigma0_px ** 2 + self.alias_floor_px ** 2 + self.unexplained_px(ratio, thr, kinds) ** 2
                        + (edge ** 2 + self.k_alias_px ** 2) / rho)
        # a counterbore's rim sees its step's floor past the d̂ side, like a blind hole (interior contrast)
        floor = ~thr | np.broadcast_to(_kind_is(kinds, shape[-1], _counterbore), shape)
        sin_t = np.sqrt(np.clip(1.0 - geo.facing ** 2, 0.0, 1.0))
        mag = (self.k_b * geo.blur_px + self.k_w_px
               + self.k_d * np.where(thr, 1.0, 0.5) * np.minimum(ratio, 2.0)) * sin_t
        mag = mag + self.k_i * np.sqrt(self.w0_px ** 2 + geo.blur_px ** 2) * interior_contrast(
            geo.facing, ratio, ~floor, geo.minor_px, geo.light_face, geo.light_wall)
        return sigma, mag[..., None] * geo.axis_dir_px

    def to_json(self) -> str:
        return json.dumps(asdict(self), indent=2)

    def for_cell(self, cell: Cell) -> PoseModels:
        """These models in ``cell`` (``cadfeat.cell.Cell``): the association term's gate is the cell's
        ``gate_px`` and its placement σ the cell's (``Cell.placement_sigma``: σ = 0.4 t per axis, as the closed loop
        draws it; a per-axis tolerance enters as the RMS of its three σ, since the term's image shift is the RMS
        over directions)."""
        mm, deg = cell.placement_sigma()
        return replace(self, gate_px=float(cell.gate_px), placement_mm=_rms_axis(mm), placement_deg=_rms_axis(deg))


def _rms_axis(value: float | tuple[float, ...]) -> float:
    """A per-axis σ as one number: itself, or the RMS of its three values."""
    v = np.atleast_1d(np.asarray(value, dtype=float))
    return float(np.sqrt(np.mean(v * v)))


@lru_cache(maxsize=1)
def default_models() -> PoseModels:
    """The committed calibration (``measures/data/detection_model.json``), or the defaults if it is absent."""
    try:
        text = resources.files("cadfeat.measures").joinpath(DATA, MODEL_FILE).read_text()
    except (FileNotFoundError, OSError):
        return PoseModels()
    return PoseModels(**json.loads(text))


# --------------------------------------------------------------------------------------- per-cell calibrations
#: The models calibrated per world (``tools/calibrate_detection.py --renderer … --detector …``): package data
#: ``detection_model_<key>.json`` and its table ``detection_calibration_<key>.csv``, ``key`` = ``model_key``.
MODEL_PREFIX = "detection_model_"
#: Materials of one family (same base material) and of one finish class: ``models_for``'s nearness.
MATERIAL_FAMILIES = {"machined_aluminium": "aluminium", "blasted_aluminium": "aluminium",
                     "machined_steel": "steel", "blasted_steel": "steel", "grey_plastic": "dielectric",
                     "black_anodised": "dielectric", "white_reference": "dielectric"}
MATERIAL_FINISHES = {"machined_aluminium": "machined", "blasted_aluminium": "blasted",
                     "machined_steel": "machined", "blasted_steel": "blasted", "grey_plastic": "dielectric",
                     "black_anodised": "dielectric", "white_reference": "dielectric"}


class ModelKey(NamedTuple):
    """What a calibration was made in: detector, renderer and (pbr) material, light kind and hole ends."""

    detector: str
    renderer: str
    material: str = "machined_aluminium"
    light: str = "ring"
    hole_ends: str = "as_modelled"

    def text(self) -> str:
        """The file key: ``<detector>-raster`` or ``<detector>-pbr-<material>-<light>-<hole_ends>``."""
        if self.renderer == "raster":
            return f"{self.detector}-raster"
        return "-".join(self)

    @classmethod
    def parse(cls, text: str) -> ModelKey:
        parts = text.split("-")
        return cls(parts[0], parts[1]) if len(parts) == 2 else cls(*parts[:5])


def model_key(detector: str, renderer: str, material: str = "machined_aluminium", light: str = "ring",
              hole_ends: str = "as_modelled") -> str:
    """The file key of a calibration (``ModelKey.text``)."""
    return ModelKey(detector, renderer, material, light, hole_ends).text()


def model_distance(want: ModelKey, have: ModelKey) -> float:
    """How far calibration ``have`` is from the world ``want`` (0: the same; inf: another detector or renderer):
    material 1 within its family (aluminium, steel, dielectric), 2 within its finish class (machined, blasted),
    4 otherwise; light 2 when another kind; hole ends 1 when another, 0.25 between ``as_modelled`` and
    ``milled`` (the calibration plate's blind holes have flat floors: as modelled is milled)."""
    if want.detector != have.detector or want.renderer != have.renderer:
        return float("inf")
    if want.renderer == "raster":
        return 0.0
    fam, fin = MATERIAL_FAMILIES, MATERIAL_FINISHES
    mat = 0.0 if want.material == have.material else 1.0 if fam.get(want.material) == fam.get(have.material) \
        else 2.0 if fin.get(want.material) == fin.get(have.material) else 4.0
    light = 0.0 if want.light == have.light else 2.0
    flat = {"as_modelled", "milled"}
    ends = 0.0 if want.hole_ends == have.hole_ends else 0.25 if {want.hole_ends, have.hole_ends} <= flat else 1.0
    return mat + light + ends


@lru_cache(maxsize=1)
def calibrated_keys() -> tuple[str, ...]:
    """The keys of the committed per-world calibrations (package data ``detection_model_<key>.json``)."""
    folder = resources.files("cadfeat.measures").joinpath(DATA)
    names = sorted(p.name for p in folder.iterdir() if p.name.startswith(MODEL_PREFIX) and p.name.endswith(".json"))
    return tuple(n[len(MODEL_PREFIX):-len(".json")] for n in names)


@lru_cache(maxsize=32)
def load_models(key: str) -> PoseModels:
    """The committed calibration ``key`` (``detection_model_<key>.json``)."""
    text = resources.files("cadfeat.measures").joinpath(DATA, f"{MODEL_PREFIX}{key}.json").read_text()
    return PoseModels(**json.loads(text))


def models_for(cell: Cell, renderer: str = "pbr") -> PoseModels:
    """The calibration of ``cell``'s world: its detector, and (``renderer`` "pbr", the physical world) its
    material, light kind and hole ends; where none matches exactly the nearest of the same detector
    (``model_distance``), the choice recorded in ``source``; none of the same detector and renderer:
    ``default_models()`` (the threshold detector's raster calibration), said so in ``source``. The cell's gate
    and placement σ are not applied here (``PoseModels.for_cell``)."""
    want = ModelKey(str(cell.detector), renderer, str(cell.material.name), str(cell.light.kind),
                    str(cell.hole_ends))
    keys = calibrated_keys()
    dist = [model_distance(want, ModelKey.parse(k)) for k in keys]
    if not keys or not np.isfinite(min(dist)):
        base = default_models()
        return replace(base, source=f"{base.source}; models_for: no {want.detector}/{renderer} calibration for "
                                    f"{want.text()}, the default models")
    best = keys[int(np.argmin(dist))]
    m = load_models(best)
    how = "exact" if best == want.text() else f"nearest to {want.text()} (distance {min(dist):g})"
    return replace(m, source=f"{m.source}; models_for: {best} ({how})")
