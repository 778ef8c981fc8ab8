"""The uncertainty of the cell that will be built, and a fixed, seeded set of draws of it (common random numbers).

``Uncertainty`` holds the study's tolerances: the cell's (``[cell]``, ``cadfeat.cell.Cell``: the camera mount, the
part placement, the sensor noise) and the path's and shop's (``[robustness]``, ``study.settings.RobustnessSettings``):

- camera mounting error: translation (mm) and rotation (deg) per camera axis, the same at every pose;
- part placement error in the cell: translation (mm) and rotation (deg) per part axis;
- trajectory variation: a path offset (mm per task axis, the whole path displaced) and a time scaling (± percent
  of the speed, the same path run faster or slower);
- pixel noise: ± grey levels around the cell's nominal sensor noise σ (``nominal_noise_grey``; g_POSE's centre noise
  grows with it);
- the shop's tolerances: each hole the study designs displaced across its axis (± mm per direction) and its
  diameter changed (± mm).

Each value is the tolerance t: ``distribution = "uniform"`` draws uniformly in [−t, t]; ``"normal"`` draws a
normal of σ = t/2 truncated at ±t (a tolerance read as 2σ). ``draws(uncertainty, S, N, seed, sampling)`` maps
S points of a scrambled Sobol sequence (``scipy.stats.qmc``, the default) or a Latin hypercube in [0, 1)^d to
these errors: the same seed gives the same draws (the optimiser sees a deterministic, piecewise-smooth function
of the design: common random numbers). ``Draws.only(kind)`` keeps one source of uncertainty (the others
nominal) for the one-at-a-time analysis. Units: mm, degrees (rad inside ``Draws``), grey levels, percent.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from cadfeat.cell import Cell, triple
from cadfeat.cell import defaults as D
from cadfeat.errors import CadfeatError
from cadfeat.poses import rotvec_matrix

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import JsonDict

__all__ = ["CELL_KINDS", "KINDS", "NOMINAL_NOISE_GREY", "SAMPLINGS", "Draws", "Uncertainty", "draws", "rigid"]

NOMINAL_NOISE_GREY = D.NOISE_SIGMA_GREY
"""The default cell's sensor noise σ (grey levels; ``cadfeat.cell.Cell.noise_sigma_grey``)."""
SAMPLINGS = ("sobol", "lhs")
KINDS = ("camera", "placement", "path", "pixel_noise", "manufacturing")
"""The sources of uncertainty, each a perturbation of results.json ``robustness.designs``."""
CELL_KINDS = ("camera", "placement", "path", "pixel_noise")
"""The sources that change the cell (poses, screws, noise), not the holes: evaluated together (``cell``)."""

Triple = tuple[float, float, float]


@dataclass(frozen=True)
class Uncertainty:
    """Tolerances of the cell and the shop (module docstring; defaults: the study's ``[robustness]``)."""

    camera_position_mm: Triple = (D.CAMERA_POSITION_MM,) * 3  # pyright: ignore[reportAssignmentType] (3 floats)
    camera_angle_deg: Triple = (D.CAMERA_ANGLE_DEG,) * 3  # pyright: ignore[reportAssignmentType]
    placement_position_mm: Triple = (D.PLACEMENT_POSITION_MM,) * 3  # pyright: ignore[reportAssignmentType]
    placement_angle_deg: Triple = (D.PLACEMENT_ANGLE_DEG,) * 3  # pyright: ignore[reportAssignmentType]
    path_offset_mm: Triple = (0.5, 0.5, 0.5)
    time_scale_percent: float = 10.0
    pixel_noise_grey: float = D.NOISE_SPREAD_GREY
    position_tol_mm: float = 0.1
    diameter_tol_mm: float = 0.1
    distribution: str = "uniform"
    nominal_noise_grey: float = NOMINAL_NOISE_GREY

    @staticmethod
    def from_settings(spec: Any, cell: Cell | None = None) -> Uncertainty:
        """The uncertainty of a ``[robustness]`` settings object in the cell ``cell`` (``[cell]``; the default
        cell if None): numbers become one value per axis."""
        cell = cell or Cell()
        return Uncertainty(triple(cell.camera_position_mm), triple(cell.camera_angle_deg),
                           triple(cell.placement_position_mm), triple(cell.placement_angle_deg),
                           triple(spec.path_offset_mm), float(spec.time_scale_percent), float(cell.noise_spread_grey),
                           float(spec.position_tol_mm), float(spec.diameter_tol_mm), str(spec.distribution),
                           float(cell.noise_sigma_grey))

    def to_dict(self) -> JsonDict:
        return {k: list(cast("tuple[float, ...]", v)) if isinstance(v, tuple) else v
                for k, v in dataclasses.asdict(self).items()}


def rigid(rotvec_rad: np.ndarray, translation_mm: np.ndarray) -> np.ndarray:
    """(S, 4, 4) rigid transforms of rotation vectors (S, 3) rad and translations (S, 3) mm (scipy Rotation:
    exact for small angles, docs/design.md "Known pitfalls")."""
    S = len(rotvec_rad)
    T = np.tile(np.eye(4), (S, 1, 1))
    if S:
        T[:, :3, :3] = rotvec_matrix(rotvec_rad)
    T[:, :3, 3] = translation_mm
    return T


@dataclass(frozen=True)
class Draws:
    """S drawn cells: camera mount ``dC`` (S, 4, 4) (camera frame), part placement ``dP`` (S, 4, 4) (part frame),
    path offset ``offset_mm`` (S, 3) (task frame), ``time_scale`` (S,) (speed factor), ``noise_grey`` (S,) or
    None (the σ model's default), the shop's ``hole_shift_mm`` (S, N, 2) across each hole's axis and
    ``diameter_mm`` (S, N) diameter change."""

    dC: np.ndarray
    dP: np.ndarray
    offset_mm: np.ndarray
    time_scale: np.ndarray
    noise_grey: np.ndarray | None
    hole_shift_mm: np.ndarray
    diameter_mm: np.ndarray

    @property
    def size(self) -> int:
        return len(self.time_scale)

    @staticmethod
    def nominal(S: int, N: int) -> Draws:
        """S copies of the nominal cell and shop (no error)."""
        eye = np.tile(np.eye(4), (S, 1, 1))
        return Draws(eye, eye.copy(), np.zeros((S, 3)), np.ones(S), None, np.zeros((S, N, 2)), np.zeros((S, N)))

    def take(self, sl: slice | np.ndarray) -> Draws:
        """The draws ``sl`` (a slice or indices)."""
        return Draws(self.dC[sl], self.dP[sl], self.offset_mm[sl], self.time_scale[sl],
                     None if self.noise_grey is None else self.noise_grey[sl], self.hole_shift_mm[sl],
                     self.diameter_mm[sl])

    def only(self, kind: str) -> Draws:
        """The same draws with every source but ``kind`` (``KINDS``, or "cell": all but the shop) nominal."""
        if kind not in (*KINDS, "cell"):
            raise CadfeatError(f"robustness: unknown source of uncertainty {kind!r}; allowed: {', '.join(KINDS)}, cell")
        keep = set(CELL_KINDS) if kind == "cell" else {kind}
        nom = Draws.nominal(self.size, self.hole_shift_mm.shape[1])
        return Draws(self.dC if "camera" in keep else nom.dC, self.dP if "placement" in keep else nom.dP,
                     self.offset_mm if "path" in keep else nom.offset_mm,
                     self.time_scale if "path" in keep else nom.time_scale,
                     self.noise_grey if "pixel_noise" in keep else None,
                     self.hole_shift_mm if "manufacturing" in keep else nom.hole_shift_mm,
                     self.diameter_mm if "manufacturing" in keep else nom.diameter_mm)


def _unit(S: int, d: int, seed: int, sampling: str) -> np.ndarray:
    """S points in [0, 1)^d: scrambled Sobol (the first S of 2^m) or a Latin hypercube, seeded."""
    from scipy.stats import qmc  # pyright: ignore[reportMissingTypeStubs]

    if sampling not in SAMPLINGS:
        raise CadfeatError(f"robustness.sampling: {sampling!r} is not allowed; allowed: {', '.join(SAMPLINGS)}")
    if S <= 0:
        return np.zeros((0, d))
    if sampling == "lhs":
        return qmc.LatinHypercube(d=d, seed=seed).random(S)  # pyright: ignore[reportCallIssue] (scipy: no stubs)
    m = int(np.ceil(np.log2(max(S, 2))))
    return qmc.Sobol(d=d, scramble=True, seed=seed).random_base2(m)[:S]  # pyright: ignore[reportCallIssue]


def _signed(U: np.ndarray, distribution: str) -> np.ndarray:
    """Unit points U → errors in [−1, 1]: uniform, or a normal of σ = 1/2 truncated at ±1 (inverse CDF)."""
    if distribution == "uniform":
        return 2.0 * U - 1.0
    if distribution == "normal":
        from scipy.stats import norm  # pyright: ignore[reportMissingTypeStubs]

        lo, hi = norm.cdf(-2.0), norm.cdf(2.0)  # pyright: ignore[reportUnknownMemberType] (scipy: no stubs)
        return 0.5 * norm.ppf(  # pyright: ignore[reportUnknownMemberType]
            lo + np.clip(U, 1e-12, 1 - 1e-12) * (hi - lo))
    raise CadfeatError(f"robustness.distribution: {distribution!r} is not allowed; allowed: uniform, normal")


def draws(uncertainty: Uncertainty, S: int, N: int, seed: int, sampling: str = "sobol") -> Draws:
    """S draws (``Draws``) of ``uncertainty`` for designs of N holes, from one seeded low-discrepancy design of
    dimension 17 + 3N (module docstring)."""
    u = uncertainty
    E = _signed(_unit(S, 17 + 3 * N, seed, sampling), u.distribution)
    cam = rigid(np.radians(E[:, 0:3] * u.camera_angle_deg), E[:, 3:6] * u.camera_position_mm)
    place = rigid(np.radians(E[:, 6:9] * u.placement_angle_deg), E[:, 9:12] * u.placement_position_mm)
    offset = E[:, 12:15] * np.asarray(u.path_offset_mm)
    scale = 1.0 + E[:, 15] * u.time_scale_percent / 100.0
    noise = np.maximum(u.nominal_noise_grey + E[:, 16] * u.pixel_noise_grey, 0.0) if u.pixel_noise_grey > 0 else None
    shift = E[:, 17:17 + 2 * N].reshape(S, N, 2) * u.position_tol_mm
    diam = E[:, 17 + 2 * N:17 + 3 * N] * u.diameter_tol_mm
    return Draws(cam, place, offset, scale, noise, shift, diam)
