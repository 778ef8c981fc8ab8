"""Hole identity: a hole's name, the pairing of two sets of holes, and the holes of a design at ``x``.

One home for "which hole is which" across rebuilds, re-extractions and STEP round trips:

- ``hole_name`` / ``hole_names`` / ``named``: a hole's name is its own (``Hole.name``) or, unnamed, ``H<i+1>``
  by its place in the list (``DEFAULT_NAME``) — the only place that default is written;
- ``pair_holes``: the one pairing function. Cost of pairing reference hole i with candidate j (mm)::

      cost_ij = ‖c_i − c_j‖ + |r_i − r_j| + tol_mm · angle(a_i, a_j) / axis_tol_rad

  admissible when each term is within its tolerance; an optimal one-to-one assignment (Hungarian,
  ``scipy.optimize.linear_sum_assignment``) minimises the summed cost. ``along_axis=True`` pairs holes by
  their axis lines and radii, whichever end extraction called a through hole's entrance: the axes may point
  either way (parallel within ``axis_tol_rad``), the distance of c_j from the reference's axis line and the
  radius difference are each admissible within ``tol_mm``, and the cost is
  ``‖c_i − c_j‖ + |r_i − r_j| + line distance`` (nearest on the line first);
  ``bounded=False`` pairs holes of two designs of a part (a parameter may move a hole any distance; this is
  how ``Part.name_holes`` ties names to the default build): every pair is admissible, the axis term is
  sign-free, and holes left over on either side stay unpaired::

      cost_ij = ‖c_i − c_j‖ + |r_i − r_j| + 100 mm · (1 − |a_i · a_j|)

- ``take_names``: paired holes take their reference's names (a hole keeps one name in every output);
- ``holes_at``: the holes of a feature model at design ``x`` (centre, axis, radius predicted; the rest of each
  hole as the model's own).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Protocol

import numpy as np
from scipy.optimize import linear_sum_assignment

from cadfeat.cad.features import Hole, holes_to_arrays
from cadfeat.errors import CadfeatError

__all__ = ["DEFAULT_NAME", "FeatureModel", "hole_name", "hole_names", "holes_at", "named", "pair_holes", "take_names"]

DEFAULT_NAME = "H{number}"
"""The name of an unnamed hole: ``H1``, ``H2``, … by its 1-based place in its list."""


class FeatureModel(Protocol):
    """What a feature model offers (``cadfeat.cad.design_map``'s models, ``study.verify.AnchoredModel``): its
    holes at the reference design and, at a design ``x``, centres (N, 3) mm, unit axes (N, 3), radii (N,) mm."""

    @property
    def holes(self) -> Sequence[Hole]: ...

    def features(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


def hole_name(hole: Hole, index: int) -> str:
    """``hole``'s name, or ``H<index+1>`` when it has none."""
    return hole.name or DEFAULT_NAME.format(number=index + 1)


def hole_names(holes: Sequence[Hole]) -> list[str]:
    """The names of ``holes`` (``hole_name`` of each)."""
    return [hole_name(h, i) for i, h in enumerate(holes)]


def named(holes: Sequence[Hole]) -> list[Hole]:
    """``holes`` with every unnamed one named ``H<i+1>``."""
    return [h if h.name else dataclasses.replace(h, name=hole_name(h, i)) for i, h in enumerate(holes)]


def _costs(reference: Sequence[Hole], candidates: Sequence[Hole], tol_mm: float, axis_tol_rad: float,
           along_axis: bool) -> tuple[np.ndarray, np.ndarray]:
    """(cost (N, M) mm, admissible (N, M) bool) of the module docstring's pairing."""
    c_ref, a_ref, r_ref = holes_to_arrays(reference)
    c_can, a_can, r_can = holes_to_arrays(candidates)
    d = c_can[None, :, :] - c_ref[:, None, :]
    d_centre = np.linalg.norm(d, axis=-1)
    cos = np.clip(np.einsum("ik,jk->ij", a_ref, a_can), -1.0, 1.0)
    d_radius = np.abs(r_ref[:, None] - r_can[None, :])
    if along_axis:
        off_line = np.linalg.norm(d - np.einsum("ijk,ik->ij", d, a_ref)[..., None] * a_ref[:, None, :], axis=-1)
        admissible = (np.arccos(np.abs(cos)) <= axis_tol_rad) & (off_line <= tol_mm) & (d_radius <= tol_mm)
        return d_centre + d_radius + off_line, admissible
    d_angle = np.arccos(cos)
    admissible = (d_centre <= tol_mm) & (d_radius <= tol_mm) & (d_angle <= axis_tol_rad)
    return d_centre + d_radius + tol_mm * d_angle / axis_tol_rad, admissible


def pair_holes(reference: Sequence[Hole], candidates: Sequence[Hole], tol_mm: float = 0.5,
               axis_tol_rad: float = 1e-3, *, along_axis: bool = False, bounded: bool = True,
               what: str = "match_holes") -> np.ndarray:
    """``idx`` with ``candidates[idx[i]]`` the hole paired with ``reference[i]`` (module docstring: the cost).

    Raises ``CadfeatError`` starting with ``what`` when a reference hole has no admissible candidate or there
    are fewer candidates than reference holes; extra candidates are left unpaired. ``bounded=False``: no
    tolerances, never raises; ``idx[i] = -1`` for a reference hole left unpaired (fewer candidates)."""
    if len(reference) == 0:
        return np.zeros(0, dtype=int)
    if not bounded:
        return _pair_unbounded(reference, candidates)
    if len(candidates) < len(reference):
        raise CadfeatError(f"{what}: {len(reference)} reference holes but only {len(candidates)} candidates")
    cost, admissible = _costs(reference, candidates, tol_mm, axis_tol_rad, along_axis)
    big = 1e6 * (1.0 + cost.max())
    rows, cols = linear_sum_assignment(np.where(admissible, cost, big))
    idx = np.empty(len(reference), dtype=int)
    idx[rows] = cols
    bad = ~admissible[np.arange(len(reference)), idx]
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        label = reference[i].name or f"#{i}"
        within = f"tol_mm={tol_mm} mm of its axis line and radius" if along_axis else \
            f"tol_mm={tol_mm} mm and axis_tol_rad={axis_tol_rad}"
        raise CadfeatError(f"{what}: reference hole {label} at {np.round(reference[i].centre, 6).tolist()} "
                           f"has no candidate within {within}")
    return idx


def _pair_unbounded(reference: Sequence[Hole], candidates: Sequence[Hole]) -> np.ndarray:
    idx = np.full(len(reference), -1, dtype=int)
    if len(candidates) == 0:
        return idx
    c_ref, a_ref, r_ref = (np.asarray(v, float) for v in holes_to_arrays(reference))
    c_can, a_can, r_can = (np.asarray(v, float) for v in holes_to_arrays(candidates))
    cost = (np.linalg.norm(c_ref[:, None] - c_can[None], axis=-1) + np.abs(r_ref[:, None] - r_can[None])
            + 100.0 * (1.0 - np.abs(a_ref @ a_can.T)))
    rows, cols = linear_sum_assignment(cost)
    idx[rows] = cols
    return idx


def take_names(reference: Sequence[Hole], holes: Sequence[Hole], idx: np.ndarray) -> list[Hole]:
    """``holes[idx[i]]`` in reference order, each taking ``reference[i]``'s name when it has one."""
    return [dataclasses.replace(holes[int(k)], name=r.name) if r.name else holes[int(k)]
            for r, k in zip(reference, idx, strict=True)]


def holes_at(model: FeatureModel, x: np.ndarray) -> list[Hole]:
    """The holes of the feature model ``model`` (``features(x)`` → centres, axes, radii; ``holes``) at ``x``."""
    c, a, r = model.features(x)
    return [dataclasses.replace(h, centre=np.asarray(c[i]), axis=np.asarray(a[i]), radius_mm=float(r[i]))
            for i, h in enumerate(model.holes)]
