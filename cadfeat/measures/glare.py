"""Where a part's own light takes a rim's edge away: the glare of a specular part under the cell's light.

Under a light at the lens (a ring light), a machined metal part mirrors the light — directly, and through its
other faces (an L-bracket's base lights its upright) — so regions of its faces come close to full scale at the
metered exposure. A blind bore in a conductor returns the light to the lens: its interior clips (docs/results.md,
"Under physical light": the crops of the flagship's targets). Between a clipped interior and a bright face there
is little edge left: the detector's edge threshold and its surround test (``vision.edge_detector``) fail. The
detection model (``measures.pose_models``), calibrated on a plate whose face is lit the same everywhere, cannot
know where on a given part the bright regions fall: the flagship's move-only optimum put a target in one and the
target was missed in 8 of 20 frames that the model called certain.

``GlareMaps`` holds the part's noiseless, metered grey image at each of the study's L poses (made once at set-up
by ``render.glare.glare_maps``: the physically based renderer in the study's cell). For any blind hole — moved or
not — ``contrast_rate`` reads the face's grey level on the circle of ``SURROUND`` × the rim radius around it (in
the hole's face plane, ``SAMPLES`` points; points inside one of the part's original holes, whose interiors the
maps show, do not count), takes the rim's contrast as c = full scale − their median (the bore clips), and gives
the share of frames in which the detector finds such a rim:

    p_c = 1 / (1 + exp(−(c − C50 σ) / (CS σ)))        σ: the sensor's grey-level noise

C50 = 21.5 and CS = 4 were read off the flagship's renders (machined aluminium, ring light, σ = 2 grey; its two
targets over 2 designs × 20 frames × 16 runs: no target found below c = 25, 50 % at c ≈ 43, all above c ≈ 70;
``tests/measures/test_glare.py`` keeps that table). g_POSE multiplies the detection model's rate by p_c for blind
holes in a conductor (``cell.material.bores_return_light``); through holes show the dark background, and a
plastic's bores are darker than its face, so neither is limited this way.

Like the optimiser's depth maps (``measures.depth``), the maps are per nominal pose; ``tile`` stacks them for the
robustness draws, looking each point up where the nominal camera sees it (``to_nominal``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from cadfeat.camera import Camera
from cadfeat.measures.rim_occlusion import rim_points

__all__ = ["C50", "CS", "FULL_SCALE", "SAMPLES", "SURROUND", "GlareMaps", "contrast_rate", "rim_contrast"]

#: full scale of the grey images (a conductor's bore interior clips there)
FULL_SCALE = 255.0
#: contrast (in units of the sensor noise σ) at which half of the rims are found, and the logistic's scale
C50, CS = 21.5, 4.0
#: the surround circle's radius over the rim radius (outside the rim and its blur at the study's scales)
SURROUND = 1.5
#: points on the surround circle
SAMPLES = 16
#: a surround point within this factor of an original hole's radius from its centre lies in that hole
INSIDE_HOLE = 1.25


@dataclass(frozen=True)
class GlareMaps:
    """The part's noiseless metered grey (L, H, W) float32, 0 … 255, at the nominal poses ``T_cam_part`` (L, 4, 4)
    of ``camera``; ``holes_centre`` (K, 3) / ``holes_radius`` (K,) mm the original holes (part frame), whose
    interiors the maps show; ``rows`` the map of each stacked pose and ``to_nominal`` (S·L, 4, 4) a displaced
    camera's frame → its nominal one (``tile``; None: identity)."""

    grey: np.ndarray
    camera: Camera
    holes_centre: np.ndarray
    holes_radius: np.ndarray
    rows: np.ndarray | None = None
    to_nominal: np.ndarray | None = None

    @property
    def n_poses(self) -> int:
        return len(self.grey) if self.rows is None else len(self.rows)

    def tile(self, copies: int, to_nominal: np.ndarray | None = None) -> GlareMaps:
        """The maps for ``copies`` stacked copies of the poses (pose k uses map k mod L), as ``DepthMaps.tile``."""
        rows = np.tile(np.arange(len(self.grey)) if self.rows is None else self.rows, copies)
        return replace(self, rows=rows, to_nominal=None if to_nominal is None else np.asarray(to_nominal, float))


def _surround_points(centres: np.ndarray, axes: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(M, SAMPLES, 3) part-frame points on the circle of ``SURROUND`` × radius around each hole's centre, in the
    plane normal to its axis (the hole's face): ``rim_occlusion.rim_points`` of the grown circle."""
    return rim_points(centres, axes, SURROUND * np.asarray(radii, float), SAMPLES, phase=0.0)


def rim_contrast(glare: GlareMaps, T_cam_part: np.ndarray, centres: np.ndarray, axes: np.ndarray,
                 radii: np.ndarray) -> np.ndarray:
    """(L, M) grey levels between a clipped bore and the face around each hole at each pose: full scale − the
    median of the surround (module docstring); NaN where fewer than half of the surround's points count (off the
    image, behind the camera, inside an original hole). ``T_cam_part`` (L, 4, 4) the poses (pose l looks up map
    ``rows[l]``), holes ``centres`` / ``axes`` (M, 3), ``radii`` (M,) mm in the part frame."""
    T = np.asarray(T_cam_part, float)
    P = _surround_points(np.asarray(centres, float), np.asarray(axes, float), np.asarray(radii, float))
    d = np.linalg.norm(P[:, :, None, :] - glare.holes_centre[None, None], axis=-1)          # (M, S, K)
    outside = ~np.any(d < INSIDE_HOLE * glare.holes_radius, axis=-1)                        # (M, S)
    X = np.einsum("lij,msj->lmsi", T[:, :3, :3], P) + T[:, None, None, :3, 3]               # (L, M, S, 3)
    if glare.to_nominal is not None:
        N = glare.to_nominal[: len(T)]
        X = np.einsum("lij,lmsj->lmsi", N[:, :3, :3], X) + N[:, None, None, :3, 3]
    cam = glare.camera
    uv = cam.project(X)
    ok = (X[..., 2] > 0) & cam.in_image(uv, 1.0) & outside[None]
    rows = np.arange(len(T)) % len(glare.grey) if glare.rows is None else glare.rows[: len(T)]
    iu = np.clip(np.rint(uv[..., 0]).astype(np.int64), 0, cam.width - 1)
    iv = np.clip(np.rint(uv[..., 1]).astype(np.int64), 0, cam.height - 1)
    grey = np.where(ok, glare.grey[np.broadcast_to(rows[:, None, None], iu.shape), iv, iu], np.nan)
    enough = ok.sum(axis=-1) >= SAMPLES // 2
    with np.errstate(all="ignore"):
        median = np.nanmedian(np.where(enough[..., None], grey, 0.0), axis=-1)
    return np.where(enough, FULL_SCALE - median, np.nan)


def contrast_rate(glare: GlareMaps, T_cam_part: np.ndarray, centres: np.ndarray, axes: np.ndarray,
                  radii: np.ndarray, noise_grey: float | np.ndarray) -> np.ndarray:
    """(L, M) p_c, the share of frames in which a blind rim of that contrast is found (module docstring); 1 where
    the contrast is unknown (``rim_contrast`` NaN). ``noise_grey``: σ, a number or (L, 1)."""
    c = rim_contrast(glare, T_cam_part, centres, axes, radii)
    sigma = np.asarray(noise_grey, float)
    return np.where(np.isfinite(c), 1.0 / (1.0 + np.exp(-(np.nan_to_num(c) - C50 * sigma) / (CS * sigma))), 1.0)
