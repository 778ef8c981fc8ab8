"""Design space and feature models: the map from design variables to hole features.

The optimiser never rebuilds CAD in its inner loop (docs/design.md, "CAD in the outer loop, features in the
inner loop"). It works on a *feature model* — a map ``x (P,) -> (centres (N,3) mm, axes (N,3), radii (N,)
mm)`` — obtained from the CAD model:

- ``LinearFeatureModel``: ``c(x) = c0 + dC (x - x0)``, ``r(x) = r0 + dR (x - x0)``, axes fixed. Built from
  the part's ``design_map`` (∂features/∂parameters by finite differences of real CAD rebuilds: the
  geometric level of the axiomatic design matrix, eq. 2.2) or from any ``rebuild(x) -> list[Hole]``
  (``from_rebuild``).
- ``HoleMoveModel``: holes of a STEP part; the variables are in-plane offsets (s, t) mm along the host
  face's (u, v) axes and optionally the diameter (mm). Holes of a pattern share variables; mirror pairs
  share them through a reflection (symmetry).

Both give ``features_batch(X (B,P))`` for batched finite differences.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, cast, runtime_checkable

import numpy as np

from cadfeat.cad.features import FaceOutline, Hole, holes_to_arrays, match_holes
from cadfeat.cad.features.identity import hole_name
from cadfeat.cad.step_parts import HoleMove
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import JsonDict

__all__ = [
    "VARIABLE_KINDS",
    "DesignSpace",
    "FeatureModel",
    "HoleMoveModel",
    "LinearFeatureModel",
    "Variable",
    "snap_to_sizes",
]

VARIABLE_KINDS = ("position", "diameter", "other")


@dataclass(frozen=True)
class Variable:
    """One design variable: ``lower ≤ x ≤ upper`` in ``unit``; ``kind`` groups variables for the design
    matrix (positions, diameters, other); ``standard_sizes`` (sorted) are the allowed discrete values."""

    name: str
    lower: float
    upper: float
    unit: str = "mm"
    kind: str = "position"
    standard_sizes: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.lower) and np.isfinite(self.upper) and self.lower < self.upper):
            raise CadfeatError(f"variable {self.name!r}: bounds must be finite with lower < upper, "
                               f"got ({self.lower!r}, {self.upper!r})")
        if self.kind not in VARIABLE_KINDS:
            raise CadfeatError(f"variable {self.name!r}: kind {self.kind!r} is not one of {', '.join(VARIABLE_KINDS)}")
        if self.standard_sizes is not None:
            sizes = tuple(sorted(float(s) for s in self.standard_sizes))
            inside = [s for s in sizes if self.lower - 1e-12 <= s <= self.upper + 1e-12]
            if not inside:
                raise CadfeatError(f"variable {self.name!r}: no standard size {list(sizes)} lies within the bounds "
                                   f"[{self.lower:g}, {self.upper:g}] {self.unit}")
            object.__setattr__(self, "standard_sizes", tuple(inside))

    @property
    def span(self) -> float:
        return float(self.upper - self.lower)

    def to_dict(self) -> JsonDict:
        return {"name": self.name, "unit": self.unit, "kind": self.kind, "lower": float(self.lower),
                "upper": float(self.upper),
                "standard_sizes": None if self.standard_sizes is None else list(self.standard_sizes)}


def snap_to_sizes(value: float, sizes: Sequence[float]) -> float:
    """The standard size nearest to ``value`` (ties: the smaller)."""
    table = np.asarray(sizes, dtype=float)
    return float(table[int(np.argmin(np.abs(table - value)))])


@dataclass
class DesignSpace:
    """The design variables and the initial design ``x0`` (P,)."""

    variables: list[Variable]
    x0: np.ndarray

    def __post_init__(self) -> None:
        self.variables = list(self.variables)
        self.x0 = np.asarray(self.x0, dtype=float).reshape(-1)
        if not self.variables:
            raise CadfeatError("design space: no design variables")
        names = self.names
        if len(set(names)) != len(names):
            raise CadfeatError(f"design space: duplicate variable names in {names}")
        if self.x0.shape != (len(self.variables),):
            raise CadfeatError(f"design space: x0 has {self.x0.size} values for {len(self.variables)} variables")
        bad = (self.x0 < self.lower - 1e-9 * self.span) | (self.x0 > self.upper + 1e-9 * self.span)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            v = self.variables[i]
            raise CadfeatError(f"design space: initial value {self.x0[i]:g} of {v.name!r} is outside its bounds "
                               f"[{v.lower:g}, {v.upper:g}] {v.unit}")
        self.x0 = self.clip(self.x0)

    @property
    def names(self) -> list[str]:
        return [v.name for v in self.variables]

    @property
    def size(self) -> int:
        return len(self.variables)

    @property
    def lower(self) -> np.ndarray:
        return np.array([v.lower for v in self.variables], dtype=float)

    @property
    def upper(self) -> np.ndarray:
        return np.array([v.upper for v in self.variables], dtype=float)

    @property
    def span(self) -> np.ndarray:
        return self.upper - self.lower

    def clip(self, x: np.ndarray) -> np.ndarray:
        return np.clip(np.asarray(x, dtype=float), self.lower, self.upper)

    def to_unit(self, x: np.ndarray) -> np.ndarray:
        """Design values (..., P) to unit coordinates in [0, 1] (the optimiser's variables)."""
        return (np.asarray(x, dtype=float) - self.lower) / self.span

    def from_unit(self, u: np.ndarray) -> np.ndarray:
        """Unit coordinates (..., P) to design values."""
        return self.lower + np.asarray(u, dtype=float) * self.span

    @property
    def discrete(self) -> np.ndarray:
        """(P,) bool: variables with standard sizes."""
        return np.array([v.standard_sizes is not None for v in self.variables])

    def snap(self, x: np.ndarray) -> np.ndarray:
        """``x`` with every variable that has standard sizes moved to the nearest size."""
        x = np.array(x, dtype=float)
        for i, v in enumerate(self.variables):
            if v.standard_sizes is not None:
                x[i] = snap_to_sizes(x[i], v.standard_sizes)
        return x

    def groups(self) -> dict[str, list[int]]:
        """Variable indices by kind ("position", "diameter", "other"), in that order, empty kinds omitted."""
        out = {k: [i for i, v in enumerate(self.variables) if v.kind == k] for k in VARIABLE_KINDS}
        return {k: idx for k, idx in out.items() if idx}

    def as_dict(self, x: np.ndarray) -> dict[str, float]:
        return {n: float(val) for n, val in zip(self.names, np.asarray(x, dtype=float), strict=True)}


@runtime_checkable
class FeatureModel(Protocol):
    """Design variables → hole features (part frame, mm)."""

    @property
    def holes(self) -> list[Hole]:
        """The holes at the reference design (their order is the features' order)."""
        ...

    def features(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """centres (N,3) mm, unit axes (N,3), radii (N,) mm at design ``x`` (P,)."""
        ...

    def features_batch(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """centres (B,N,3), axes (B,N,3), radii (B,N) for designs ``X`` (B,P)."""
        ...


@dataclass
class LinearFeatureModel:
    """Hole features linear in the design variables (exact for holes placed by parameters).

    ``c(x) = centres0 + dC @ (x - x0)`` with ``dC`` (N,3,P) mm per unit, ``r(x) = radii0 + dR @ (x - x0)``
    (N,P); axes ``a0 + dA @ (x - x0)`` normalised (``dA`` (N,3,P), default zero: constant axes).
    ``holes`` are the reference holes at ``x0`` (outlines for the constraints); ``outline_rates``: per hole, how
    its host face's outline moves with x (``cadfeat.cad.outline_motion.OutlineRates`` or None: fixed);
    ``dD``, ``dB`` (N,P): ∂depth/∂x and ∂bore radius/∂x (mm per unit; None: the holes' own depth and bore at
    every x) — ``depths_batch`` and ``bores_batch`` (issue 17: depth and rim chamfer as design variables).
    """

    holes: list[Hole]
    x0: np.ndarray
    dC: np.ndarray
    dR: np.ndarray
    names: list[str] = field(default_factory=list[str])
    dA: np.ndarray | None = None
    outline_rates: list[Any] | None = None
    dD: np.ndarray | None = None
    dB: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.holes = list(self.holes)
        self.x0 = np.asarray(self.x0, dtype=float).reshape(-1)
        n, p = len(self.holes), self.x0.size
        self.dC = np.asarray(self.dC, dtype=float).reshape(n, 3, p)
        self.dR = np.asarray(self.dR, dtype=float).reshape(n, p)
        self.dA = np.zeros((n, 3, p)) if self.dA is None else np.asarray(self.dA, dtype=float).reshape(n, 3, p)
        self.centres0, self.axes0, self.radii0 = holes_to_arrays(self.holes)
        self.dD = np.zeros((n, p)) if self.dD is None else np.asarray(self.dD, dtype=float).reshape(n, p)
        self.dB = self.dR.copy() if self.dB is None else np.asarray(self.dB, dtype=float).reshape(n, p)
        self.depths0 = np.array([float(h.depth_mm) for h in self.holes])
        self.bores0 = np.array([float(h.bore_radius_mm) for h in self.holes])

    @classmethod
    def from_design_map(cls, dm: Any, names: Sequence[str], x0: Sequence[float]) -> LinearFeatureModel:
        """From a ``cadfeat.cad.design_map.DesignMap`` built at parameters ``x0`` for ``names`` (columns in that
        order). ``dm.holes0``, ``dm.dC`` (N,3,P), ``dm.dR`` (N,P), ``dm.dA`` (N,3,P) if present."""
        x = np.asarray(x0, dtype=float)
        dC, dR = np.asarray(dm.dC, dtype=float), np.asarray(dm.dR, dtype=float)
        if dC.shape[-1] != len(names) or dR.shape[-1] != len(names) or x.size != len(names):
            raise CadfeatError(f"design map has {dC.shape[-1]} parameter columns, expected {len(names)} ({names})")
        dA = getattr(dm, "dA", None)
        return cls(list(dm.holes0), x, dC, dR, list(names), None if dA is None else np.asarray(dA, dtype=float),
                   getattr(dm, "outline_rates", None), getattr(dm, "dD", None), getattr(dm, "dB", None))

    @classmethod
    def from_rebuild(cls, rebuild: Callable[[np.ndarray], list[Hole]], x0: np.ndarray, steps: np.ndarray,
                     holes0: list[Hole] | None = None, names: Sequence[str] = (),
                     match_tol_mm: float | None = None) -> LinearFeatureModel:
        """Finite-difference map from CAD rebuilds: ``holes0 = rebuild(x0)`` (unless given) and one forward
        rebuild per variable with step ``steps`` (P,). Holes are matched by geometry (``match_holes``), never
        by index; ``match_tol_mm`` defaults to 2·max|step| + 1e-3."""
        x0 = np.asarray(x0, dtype=float)
        steps = np.asarray(steps, dtype=float) * np.ones_like(x0)
        holes0 = list(rebuild(x0)) if holes0 is None else list(holes0)
        c0, _, r0 = holes_to_arrays(holes0)
        tol = float(match_tol_mm if match_tol_mm is not None else 2 * np.max(np.abs(steps)) + 1e-3)
        dC = np.zeros((len(holes0), 3, x0.size))
        dR = np.zeros((len(holes0), x0.size))
        for k in range(x0.size):  # one CAD rebuild per variable
            x = x0.copy()
            x[k] += steps[k]
            moved = list(rebuild(x))
            if len(moved) != len(holes0):  # a step that adds or merges holes has no derivative
                raise CadfeatError(f"CAD rebuild for the map: {len(moved)} holes found, {len(holes0)} designed")
            idx = match_holes(holes0, moved, tol_mm=tol)
            c, _, r = holes_to_arrays([moved[int(i)] for i in idx])
            dC[:, :, k] = (c - c0) / steps[k]
            dR[:, k] = (r - r0) / steps[k]
        return cls(holes0, x0, dC, dR, list(names))

    def features(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        c, a, r = self.features_batch(np.asarray(x, dtype=float)[None])
        return c[0], a[0], r[0]

    def features_batch(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        dX = np.asarray(X, dtype=float) - self.x0
        centres = self.centres0 + np.einsum("nkp,bp->bnk", self.dC, dX)
        radii = self.radii0 + dX @ self.dR.T
        dA = cast(np.ndarray, self.dA)  # (arrays after __post_init__, as dD and dB)
        if np.any(dA):
            axes = self.axes0 + np.einsum("nkp,bp->bnk", dA, dX)
            axes = axes / np.linalg.norm(axes, axis=-1, keepdims=True)
        else:
            axes = np.broadcast_to(self.axes0, centres.shape)
        return centres, axes, radii

    def depths_batch(self, X: np.ndarray) -> np.ndarray:
        """(B, N) hole depths (mm) at designs ``X`` (B, P): ``depth0 + dD (x − x0)``."""
        return self.depths0 + (np.atleast_2d(np.asarray(X, dtype=float)) - self.x0) @ cast(np.ndarray, self.dD).T

    def bores_batch(self, X: np.ndarray) -> np.ndarray:
        """(B, N) bore radii (mm; the drill's, under a chamfered or counterbored rim) at designs ``X`` (B, P)."""
        return self.bores0 + (np.atleast_2d(np.asarray(X, dtype=float)) - self.x0) @ cast(np.ndarray, self.dB).T

    def holes_at(self, x: np.ndarray) -> list[Hole]:
        """The reference holes with the features (and depth, bore) at ``x`` and their host-face outlines moved to
        ``x`` (``outline_rates``; outlines without rates as at ``x0``)."""
        c, a, r = self.features(x)
        depth, bore = self.depths_batch(x)[0], self.bores_batch(x)[0]
        dx = np.asarray(x, dtype=float) - self.x0
        out: list[Hole] = []
        for i, h in enumerate(self.holes):
            o, rates = h.outline, (self.outline_rates or [None] * len(self.holes))[i]
            if o is not None and rates is not None:
                outer = o.outer + rates.outer @ dx if rates.outer is not None else o.outer
                kos = tuple(k + kr @ dx if kr is not None else k for k, kr in zip(o.keepouts, rates.keepouts,
                                                                                      strict=True))
                o = FaceOutline(o.origin, o.u, o.v, outer, kos)
            out.append(dataclasses.replace(h, centre=c[i], axis=a[i], radius_mm=float(r[i]), outline=o,
                                           depth_mm=float(depth[i]), bore_radius_mm=float(bore[i])))
        return out

    def moved_mask(self) -> np.ndarray:
        """(N,) bool: holes that any variable moves or resizes."""
        return (np.abs(self.dC).max(axis=(1, 2), initial=0) > 0) | (np.abs(self.dR).max(axis=1, initial=0) > 0)


def _in_plane_frame(hole: Hole) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) in-plane unit axes of a hole's host face: the outline's, else a frame ⟂ to the axis."""
    if hole.outline is not None:
        return np.asarray(hole.outline.u, float), np.asarray(hole.outline.v, float)
    a = np.asarray(hole.axis, float)
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    u = np.cross(helper, a)
    u /= np.linalg.norm(u)
    return u, np.cross(a, u)


class HoleMoveModel(LinearFeatureModel):
    """STEP-part holes moved in their host face plane (and optionally resized).

    Variables, per independent hole ``h`` (``movable``, minus followers): ``"<h>.s"``, ``"<h>.t"`` — offsets
    (mm) of the rim centre along the host face's ``u`` and ``v`` axes — and, if ``diameter``, ``"<h>.d"``
    — the entrance diameter (mm). ``patterns``: lists of hole indices that move together (the first is the
    leader; the others share its variables, same offset and diameter). ``mirrors``: ``(leader, follower,
    plane_normal)`` — the follower's offset is the leader's reflected in the plane with that normal (3,)
    (symmetric pair), same diameter. Fixed holes (not in ``movable``) have no variables.
    """

    def __init__(self, holes: Sequence[Hole], movable: Sequence[int], *, diameter: bool | Sequence[int] = False,
                 patterns: Sequence[Sequence[int]] = (), mirrors: Sequence[tuple[int, int, Sequence[float]]] = ()):
        holes = list(holes)
        n = len(holes)
        movable = sorted({int(i) for i in movable})
        if any(i < 0 or i >= n for i in movable):
            raise CadfeatError(f"HoleMoveModel: movable hole indices {movable} outside 0..{n - 1}")
        follow: dict[int, tuple[int, np.ndarray]] = {}
        for pattern in patterns:
            pattern = [int(i) for i in pattern]
            for i in pattern[1:]:
                follow[i] = (pattern[0], np.eye(3))
        for leader, follower, normal in mirrors:
            nvec = np.asarray(normal, dtype=float)
            nvec = nvec / np.linalg.norm(nvec)
            follow[int(follower)] = (int(leader), np.eye(3) - 2 * np.outer(nvec, nvec))
        for i, (leader, _) in follow.items():
            if i not in movable or leader not in movable:
                raise CadfeatError(f"HoleMoveModel: pattern/mirror holes {leader} and {i} must both be movable")
            if leader in follow:
                raise CadfeatError(f"HoleMoveModel: hole {leader} leads a pattern but follows another one")
        leaders = [i for i in movable if i not in follow]
        # diameter: True (every movable hole), False, or the hole indices whose entrance diameter varies
        resized = set(movable) if diameter is True else set[int]() if diameter is False else \
            {int(i) for i in diameter}
        width = sum(3 if i in resized else 2 for i in leaders)
        names: list[str] = []
        x0: list[float] = []
        kinds: list[str] = []
        dC = np.zeros((n, 3, width))
        dR = np.zeros((n, width))
        col = 0
        for i in leaders:
            label = hole_name(holes[i], i)
            u, v = _in_plane_frame(holes[i])
            names += [f"{label}.s", f"{label}.t"]
            x0 += [0.0, 0.0]
            kinds += ["position", "position"]
            dC[i, :, col:col + 2] = np.stack([u, v], axis=1)
            col += 2
            if i in resized:
                names.append(f"{label}.d")
                x0.append(2.0 * holes[i].radius_mm)
                kinds.append("diameter")
                dR[i, col] = 0.5
                col += 1
        for i, (leader, M) in follow.items():
            dC[i] = M @ dC[leader]
            dR[i] = dR[leader]
        self.movable = movable
        self.resized = resized & set(leaders)
        self.diameter = bool(self.resized)
        self.leaders = leaders
        self.kinds = kinds
        super().__init__(holes, np.array(x0), dC, dR, names)

    def design_space(self, offset_bounds_mm: tuple[float, float] | None = None,
                     diameter_bounds_mm: tuple[float, float] | None = None,
                     standard_sizes: Sequence[float] | None = None,
                     max_offsets_mm: Mapping[int, float] | None = None) -> DesignSpace:
        """A ``DesignSpace`` for these variables. Offsets default to the host outline's bounding box seen from
        the hole centre (the hole may go anywhere on its face, the constraints keep it inside), or to
        ±``max_offsets_mm[i]`` for hole index ``i`` whose host face is not planar; diameters default to
        [0.5, 2]× the current one."""
        variables: list[Variable] = []
        for i in self.leaders:
            hole = self.holes[i]
            label = hole_name(hole, i)
            if offset_bounds_mm is not None:
                lo_s = lo_t = float(offset_bounds_mm[0])
                hi_s = hi_t = float(offset_bounds_mm[1])
            elif hole.outline is None and max_offsets_mm and i in max_offsets_mm:
                lo_s = lo_t = -float(max_offsets_mm[i])
                hi_s = hi_t = float(max_offsets_mm[i])
            elif hole.outline is not None:
                st = hole.outline.to_face(hole.centre)
                lo_s, lo_t = hole.outline.outer.min(axis=0) - st
                hi_s, hi_t = hole.outline.outer.max(axis=0) - st
            else:
                raise CadfeatError(f"hole {label}: its host face is not planar; give offset bounds (mm)")
            variables += [Variable(f"{label}.s", float(lo_s), float(hi_s), "mm", "position"),
                          Variable(f"{label}.t", float(lo_t), float(hi_t), "mm", "position")]
            if i in self.resized:
                d0 = 2.0 * hole.radius_mm
                lo, hi = diameter_bounds_mm if diameter_bounds_mm is not None else (0.5 * d0, 2.0 * d0)
                variables.append(Variable(f"{label}.d", float(lo), float(hi), "mm", "diameter",
                                          None if standard_sizes is None else tuple(standard_sizes)))
        return DesignSpace(variables, self.x0)

    def hole_moves(self, x: np.ndarray) -> list[Any]:
        """``step_parts.HoleMove`` for every movable hole at design ``x`` (for ``redrill``)."""
        c, _, r = self.features(x)
        return [HoleMove(self.holes[i], c[i], float(r[i])) for i in self.movable]
