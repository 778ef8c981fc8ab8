"""The geometric design matrix ∂F/∂P of a part script: how each parameter moves and resizes the holes.

docs/design.md ("CAD in the outer loop, features in the inner loop"): the map parameters → hole features is
read from the CAD model itself — build at the design point, extract the holes, and take central finite
differences of the extracted features per parameter (one-sided where a step would leave the bounds).
This is the geometric level of the axiomatic design matrix of eq. 2.2 (thesis §2.2.4). Holes are matched
across rebuilds by geometry (``match_holes``), never by face index.

Linearity: the finite-difference map is checked against a second build at a larger step (``check_factor``
× ``step_mm``): the map is *linear* in a parameter when the extracted centres, radii and axes at that step
equal the linear prediction within ``LINEAR_TOL_MM`` (1e-6 mm; axes 1e-9 rad).

Hole depth and bore: the map also carries ∂depth/∂P and ∂bore radius/∂P (``dD``, ``dB``), read from the same
builds (issue 17: a part script's hole depth and rim chamfer are design variables: a chamfer widens the rim, the
radius the camera sees, and leaves the bore, the drill). Their linearity is checked with the rest.

Costs: 1 + 3P builds + extractions for P parameters.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from cadfeat.cad.features import holes_to_arrays, match_holes
from cadfeat.cad.outline_motion import outline_rates
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cad.features import Hole
    from cadfeat.cad.parts import Part
    from cadfeat.results import JsonDict

__all__ = ["LINEAR_TOL_MM", "MOVE_TOL", "DesignMap", "design_map", "reference_design_map", "reference_designs"]

LINEAR_TOL_MM = 1e-6
"""Largest deviation (mm) from the linear prediction at the check step for a parameter to count as linear."""
LINEAR_TOL_RAD = 1e-9
"""Largest axis deviation (rad) from the linear prediction at the check step."""
MOVE_TOL = 1e-7
"""A parameter moves a hole when |∂centre|, |∂radius|, a blind hole's |∂depth| (mm per unit) or |∂axis| (per unit)
exceeds this."""


@dataclass(frozen=True)
class DesignMap:
    """Linearised parameters → holes map of a part at the point ``at``.

    ``holes0``: the N holes at ``at`` (extraction order); ``dC`` (N, 3, P) ∂centre/∂parameter (mm per unit
    of the parameter), ``dA`` (N, 3, P) ∂axis/∂parameter, ``dR`` (N, P) ∂radius/∂parameter; ``moved_by``:
    parameter → indices of the holes it moves or resizes; ``unused``: parameters that change no hole;
    ``linear_by``: parameter → whether the map is linear in it (checked at ``check_steps``), ``linear``:
    all of them; ``deviation_mm``: parameter → the largest deviation from the linear prediction at the
    check step; ``n_builds``: CAD builds spent; ``outline_rates``: per hole, how its host face's outline moves
    with the parameters (``cadfeat.cad.outline_motion.OutlineRates``, None where it cannot be paired);
    ``dD`` (N, P) ∂depth/∂parameter and ``dB`` (N, P) ∂bore radius/∂parameter (mm per unit; None: not read).
    """

    part_name: str
    names: tuple[str, ...]
    at: dict[str, float]
    holes0: list[Hole]
    dC: np.ndarray
    dA: np.ndarray
    dR: np.ndarray
    steps: np.ndarray
    check_steps: np.ndarray
    moved_by: dict[str, list[int]]
    linear_by: dict[str, bool]
    deviation_mm: dict[str, float]
    n_builds: int
    unused: list[str] = field(default_factory=list)
    outline_rates: list[Any] | None = None
    dD: np.ndarray | None = None
    dB: np.ndarray | None = None

    @property
    def linear(self) -> bool:
        """Whether the map is linear in every parameter (within ``LINEAR_TOL_MM``)."""
        return all(self.linear_by.values())

    def feature_matrix(self) -> tuple[list[str], np.ndarray]:
        """The geometric design matrix ∂F/∂P (eq. 2.2) as rows × parameters: row labels (``"H3.x"``,
        ``"H3.y"``, ``"H3.z"``, ``"H3.r"``; holes numbered from 1 in ``holes0`` order) and the (4N, P) array."""
        rows = [f"H{i + 1}.{k}" for i in range(len(self.holes0)) for k in ("x", "y", "z", "r")]
        block = np.concatenate([self.dC, self.dR[:, None, :]], axis=1)  # (N, 4, P)
        return rows, block.reshape(-1, len(self.names))

    def delta(self, params: Mapping[str, float]) -> np.ndarray:
        """(P,) parameter change from ``at`` (names not given keep their value at ``at``)."""
        unknown = sorted(set(params) - set(self.names))
        if unknown:
            raise CadfeatError(f"design map of {self.part_name}: unknown parameter(s) {', '.join(unknown)}; "
                               f"allowed: {', '.join(self.names)}")
        return np.array([float(params.get(n, self.at[n])) - self.at[n] for n in self.names])

    def predict(self, params: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Linear prediction at ``params``: centres (N, 3) mm, unit axes (N, 3), radii (N,) mm."""
        dx = self.delta(params)
        c0, a0, r0 = holes_to_arrays(self.holes0)
        axes = a0 + self.dA @ dx
        axes = axes / np.linalg.norm(axes, axis=-1, keepdims=True)
        return c0 + self.dC @ dx, axes, r0 + self.dR @ dx

    def predict_batch(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Batched prediction for parameter vectors X (B, P) in ``names`` order: (B,N,3), (B,N,3), (B,N)."""
        dX = np.atleast_2d(np.asarray(X, dtype=float)) - np.array([self.at[n] for n in self.names])
        c0, a0, r0 = holes_to_arrays(self.holes0)
        axes = a0 + np.einsum("nkp,bp->bnk", self.dA, dX)
        axes = axes / np.linalg.norm(axes, axis=-1, keepdims=True)
        return c0 + np.einsum("nkp,bp->bnk", self.dC, dX), axes, r0 + dX @ self.dR.T


def _arrays(holes: Sequence[Hole]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return holes_to_arrays(holes)


def _form(holes: Sequence[Hole]) -> tuple[np.ndarray, np.ndarray]:
    """(depth (N,) mm, bore radius (N,) mm) of ``holes``."""
    return (np.array([float(h.depth_mm) for h in holes]), np.array([float(h.bore_radius_mm) for h in holes]))


def _matched(part: Part, params: JsonDict, reference: Sequence[Hole], what: str,
             tol_mm: float, timeout_s: float | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[Hole]]:
    """Centres, axes, radii and the holes of a build at ``params`` in ``reference`` order (matched by geometry)."""
    holes = part.holes_timed(params, timeout_s)
    if len(holes) != len(reference):
        raise CadfeatError(f"{part.path}: {what} changes the number of holes ({len(reference)} -> {len(holes)}); "
                           "a design-map parameter must move or resize holes, not add or remove them")
    try:
        idx = match_holes(reference, holes, tol_mm=tol_mm, axis_tol_rad=0.05)
    except CadfeatError as exc:
        raise CadfeatError(f"{part.path}: {what}: holes cannot be matched to the design point ({exc})") from None
    c, a, r = _arrays(holes)
    return c[idx], a[idx], r[idx], [holes[i] for i in idx]


def _steps(part: Part, name: str, x0: float, h: float) -> tuple[float, float]:
    """Lower and upper step (≥ 0) of a central difference of size h, clipped into the bounds."""
    p = part.parameters[name]
    return min(h, x0 - p.lower), min(h, p.upper - x0)


def design_map(part: Part, names: Sequence[str], at: Mapping[str, Any] | None = None, step_mm: float = 1e-3,
               check_factor: float = 100.0, match_tol_mm: float = 0.5, timeout_s: float | None = None) -> DesignMap:
    """Finite-difference design map of ``part`` in the parameters ``names`` at ``at`` (default: defaults).

    Central differences with step ``step_mm`` (in the parameter's unit), one-sided where the step would
    leave the bounds; integer parameters are rejected (they add/remove holes, no derivative). The linearity
    check builds once more per parameter at ``check_factor × step_mm`` (clipped into the bounds, on the side
    with more room) and compares with the linear prediction (``LINEAR_TOL_MM``). Raises ``CadfeatError`` for
    unknown/integer names, a parameter with no room in its bounds, or a step that changes the hole count.
    With ``timeout_s`` every build runs in a worker process with that time limit (``build_shape``; a hung
    or failing build raises ``PartBuildError``); by default builds run in this process (fast).
    """
    names = tuple(names)
    unknown = [n for n in names if n not in part.parameters]
    if unknown or len(set(names)) != len(names):
        raise CadfeatError(f"{part.path}: design map parameters {list(names)}: unknown or repeated names; "
                           f"allowed: {', '.join(part.parameters)}")
    ints = [n for n in names if part.parameters[n].is_int]
    if ints:
        raise CadfeatError(f"{part.path}: integer parameter(s) {', '.join(ints)} cannot be in a design map "
                           "(they add or remove holes); fix them with `at`")
    x = part.resolve(**dict(at or {}))
    holes0 = part.holes_timed(x, timeout_s)
    c0, a0, r0 = _arrays(holes0)
    n, p = len(holes0), len(names)
    dC, dA, dR = np.zeros((n, 3, p)), np.zeros((n, 3, p)), np.zeros((n, p))
    dD, dB = np.zeros((n, p)), np.zeros((n, p))
    form0 = _form(holes0)
    through0 = np.array([bool(h.through) for h in holes0], dtype=bool)  # a through hole's depth is its wall's
    steps, checks = np.zeros(p), np.zeros(p)
    moved_by: dict[str, list[int]] = {}
    linear_by: dict[str, bool] = {}
    deviation: dict[str, float] = {}
    builds = 1
    sides: list[list[Any]] = [[], []]  # matched holes at +step / −step of each parameter (outline rates)
    spans = np.zeros(p)
    for j, name in enumerate(names):
        lo, hi = _steps(part, name, x[name], step_mm)
        if lo + hi <= 0:
            raise CadfeatError(f"{part.path}: parameter {name!r} has no room between its bounds")
        *plus, holes_plus = _matched(part, {**x, name: x[name] + hi}, holes0, f"{name} + {hi:g}", match_tol_mm,
                                     timeout_s) if hi else (c0, a0, r0, None)
        *minus, holes_minus = _matched(part, {**x, name: x[name] - lo}, holes0, f"{name} - {lo:g}", match_tol_mm,
                                       timeout_s) if lo else (c0, a0, r0, None)
        sides[0].append(holes_plus)
        sides[1].append(holes_minus)
        builds += (hi > 0) + (lo > 0)
        span = lo + hi
        spans[j] = span
        dC[..., j], dA[..., j], dR[:, j] = ((u - v) / span for u, v in zip(plus, minus, strict=True))
        dD[:, j], dB[:, j] = ((u - v) / span for u, v in zip(_form(holes_plus) if holes_plus else form0,
                                                             _form(holes_minus) if holes_minus else form0,
                                                             strict=True))
        steps[j] = span / 2 if lo and hi else span
        moved = (np.abs(dC[..., j]).max(axis=-1) > MOVE_TOL) | (np.abs(dA[..., j]).max(axis=-1) > MOVE_TOL) \
            | (np.abs(dR[:, j]) > MOVE_TOL) | ((np.abs(dD[:, j]) > MOVE_TOL) & ~through0)
        moved_by[name] = np.flatnonzero(moved).tolist()
        linear_by[name], deviation[name], checks[j] = _check_linear(
            part, x, name, holes0, (dC[..., j], dA[..., j], dR[:, j], dD[:, j], dB[:, j]), check_factor * step_mm,
            match_tol_mm, timeout_s)
        builds += 1
    unused = [nm for nm in names if not moved_by[nm]]

    return DesignMap(part.name, names, {nm: float(x[nm]) for nm in names}, holes0, dC, dA, dR, steps, checks,
                     moved_by, linear_by, deviation, builds, unused,
                     outline_rates(holes0, sides[0], sides[1], spans), dD, dB)


def _check_linear(part: Part, x: JsonDict, name: str, holes0: Sequence[Hole],
                  grads: tuple[np.ndarray, ...], big_step: float,
                  match_tol_mm: float, timeout_s: float | None) -> tuple[bool, float, float]:
    """Build at a larger step; (linear?, max deviation mm of centres, radii, depths and bores, the signed step)."""
    lo, hi = _steps(part, name, x[name], big_step)
    h = hi if hi >= lo else -lo
    gc, ga, gr, gd, gb = grads
    c0, a0, r0 = _arrays(holes0)
    pc, pa, pr = c0 + gc * h, a0 + ga * h, r0 + gr * h
    pa = pa / np.linalg.norm(pa, axis=-1, keepdims=True)
    predicted = [dataclasses.replace(hole, centre=pc[i], axis=pa[i], radius_mm=float(pr[i]))
                 for i, hole in enumerate(holes0)]
    c, a, r, holes = _matched(part, {**x, name: x[name] + h}, predicted, f"{name} {h:+g} (linearity check)",
                              match_tol_mm, timeout_s)
    (d0, b0), (d, b) = _form(holes0), _form(holes)
    dev_mm = max(float(np.linalg.norm(c - pc, axis=-1).max(initial=0.0)), float(np.abs(r - pr).max(initial=0.0)),
                 float(np.abs(d - (d0 + gd * h)).max(initial=0.0)), float(np.abs(b - (b0 + gb * h)).max(initial=0.0)))
    dev_rad = float(np.linalg.norm(a - pa, axis=-1).max(initial=0.0))  # chord = angle to first order
    return dev_mm <= LINEAR_TOL_MM and dev_rad <= LINEAR_TOL_RAD, dev_mm, h


#: Sobol points of the design box tried (after its centre) as the reference design of ``reference_design_map``.
REFERENCE_CANDIDATES = 8


def reference_designs(lower: Sequence[float], upper: Sequence[float], n: int = REFERENCE_CANDIDATES) -> np.ndarray:
    """(1 + n, P) candidate reference designs of a design box: its centre, then ``n`` points of a fixed
    scrambled Sobol sequence of the box (seed 0). They depend on the bounds only, never on the part's values."""
    from scipy.stats import qmc

    lo, hi = np.asarray(lower, float), np.asarray(upper, float)
    u = qmc.Sobol(d=lo.size, scramble=True, seed=0).random_base2(int(np.ceil(np.log2(max(n, 1)))))[:n]
    return np.vstack([0.5 * (lo + hi), lo + u * (hi - lo)])


def reference_design_map(part: Part, names: Sequence[str], start: Mapping[str, Any], lower: Sequence[float],
                         upper: Sequence[float], **kwargs: Any) -> tuple[DesignMap, list[Hole]]:
    """The design map of ``part`` linearised at a reference design that does not depend on the starting design
    (issue 16: a map built at the part's current values is exact only near them, so the optimum moved with
    them): the centre of the box [``lower``, ``upper``] of the variables ``names``, else the first of the
    ``reference_designs`` whose build has the same holes (by name) as the build at ``start``. Parameters that
    are not design variables keep their ``start`` values (integers, fixed dimensions).

    Returns the map (rows in the order of the holes at ``start``) and the holes at ``start`` (the part as it
    is: the "before" design). Falls back to the map at ``start`` when no reference design builds the same
    holes (then the answer may depend on the start: the part's hole set changes across its design box).
    ``kwargs`` go to ``design_map``."""
    names = tuple(names)
    start = dict(start)
    holes_start = part.holes_timed(part.resolve(**start), kwargs.get("timeout_s"))
    labels = [h.name for h in holes_start]
    if len(set(labels)) != len(labels) or None in labels:
        return design_map(part, names, at=start, **kwargs), holes_start
    for x in reference_designs(lower, upper):
        at = {**start, **{n: float(v) for n, v in zip(names, x, strict=True)}}
        try:
            dm = design_map(part, names, at=at, **kwargs)
        except CadfeatError:
            continue
        order = {h.name: i for i, h in enumerate(dm.holes0)}
        if sorted(order) != sorted(labels):
            continue
        return _reordered(dm, [order[name] for name in labels]), holes_start
    return design_map(part, names, at=start, **kwargs), holes_start


def _reordered(dm: DesignMap, idx: Sequence[int]) -> DesignMap:
    """``dm`` with its hole rows in the order ``idx`` (new row k = old row idx[k])."""
    idx = list(idx)
    new_of_old = {old: new for new, old in enumerate(idx)}
    moved_by = {n: sorted(new_of_old[i] for i in rows) for n, rows in dm.moved_by.items()}
    rates = None if dm.outline_rates is None else [dm.outline_rates[i] for i in idx]
    return dataclasses.replace(dm, holes0=[dm.holes0[i] for i in idx], dC=dm.dC[idx], dA=dm.dA[idx],
                               dR=dm.dR[idx], moved_by=moved_by, outline_rates=rates,
                               dD=None if dm.dD is None else dm.dD[idx], dB=None if dm.dB is None else dm.dB[idx])
