"""Hole depth and rim form as design variables (issue 17): what a design's depth and bore are, and what a shop drills.

A part script may expose a hole's depth and a rim chamfer as parameters (``parts/nema17_mount.py``: its two
target holes). The design map (``cad.design_map``) reads ∂depth/∂P and ∂bore radius/∂P from the same CAD builds as
the centres and rim radii, and the linear feature model carries them (``LinearFeatureModel.depths_batch``,
``bores_batch``). This module is the one place the rest asks:

- ``design_depths(model, X)``: (B, N) depths (mm) of designs X, for g_POSE's offset model (depth/diameter) and the
  rim test of a blind hole — None where the model has no depth rates (the holes' own depths then hold);
- ``hole_depths(holes)``: the same for CAD holes (rebuilt, re-extracted): the reported values;
- ``variable_kind``: a parameter that changes a bore (the drill) is a "diameter"; one that changes only a depth
  or a rim (a chamfer: the rim widens, the bore stays) is "other" — a shop rounds it to its step, never to a
  drill size; one that moves holes is a "position";
- ``drill_mask`` / ``drill_radii_batch``: the radius a shop drills — the bore of a plain hole (with or without a
  chamfered rim), the entrance of a counterbore or countersink (its tool size, as before).

Depth bounds: a blind hole must leave a floor under it. cadfeat enforces it where it is exact and cheap: the part
script's bounds on the depth parameter (the flagship: 1–4 mm in a 5 mm plate, ≥ 1 mm floor), checked on the B-rep
in the tests (``tests/design/test_hole_form.py``: the floor at the upper bound, measured on the solid).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, cast

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cad.features import Hole
    from cadfeat.design.design_space import FeatureModel

__all__ = ["FORM_TOL", "design_bores", "design_depths", "drill_mask", "drill_radii_batch", "hole_depths",
           "variable_kind"]

FORM_TOL = 1e-7
"""A rate (mm per unit) above this counts as changing the depth, the bore or the rim."""


def _linear(model: FeatureModel) -> Any:
    """The linear model under ``model`` (``study.verify.AnchoredModel`` wraps one as ``.model``), or None."""
    for m in (model, getattr(model, "model", None)):
        if m is not None and hasattr(m, "depths_batch") and hasattr(m, "bores_batch"):
            return m
    return None


def design_depths(model: FeatureModel, X: np.ndarray) -> np.ndarray | None:
    """(B, N) hole depths (mm) of designs ``X`` (B, P) by the feature model's depth rates; None without them."""
    lin = _linear(model)
    return None if lin is None else lin.depths_batch(np.atleast_2d(np.asarray(X, dtype=float)))


def design_bores(model: FeatureModel, X: np.ndarray) -> np.ndarray | None:
    """(B, N) bore radii (mm) of designs ``X``: the model's rims minus its rim-to-bore width (an anchored model
    keeps its anchor's offset on the bore too); None without bore rates."""
    lin = _linear(model)
    if lin is None:
        return None
    X = np.atleast_2d(np.asarray(X, dtype=float))
    rim = np.asarray(model.features_batch(X)[2], dtype=float)
    return rim - (np.asarray(lin.features_batch(X)[2], dtype=float) - lin.bores_batch(X))


def hole_depths(holes: Sequence[Hole]) -> np.ndarray:
    """(N,) depths (mm) of CAD holes (``Hole.depth_mm``)."""
    return np.array([float(h.depth_mm) for h in holes])


def variable_kind(dR: np.ndarray, dB: np.ndarray | None, dD: np.ndarray | None,
                  through: Sequence[bool] | np.ndarray | None = None, plain: Sequence[bool] | np.ndarray | None = None
                  ) -> str:
    """The ``Variable.kind`` of a parameter with per-hole rates (N,) of rim radius ``dR``, bore radius ``dB`` and
    depth ``dD`` (mm per unit; None: not known): "diameter" when it changes a bore (or, bore unknown, a rim);
    "other" when it changes only blind holes' depths or rims over unchanged bores (a chamfer); else "position".
    ``through`` (N,) bool: holes whose depth is their wall's (a wall thickness is no hole depth); ``plain`` (N,)
    bool: holes drilled at their bore (``drill_mask``; the others — counterbores, countersinks — are sized at the
    entrance, so a rim rate counts as a diameter there)."""
    drilled = np.asarray(dR if dB is None else dB, dtype=float)
    bore = drilled if plain is None else np.where(np.asarray(plain, bool), drilled, np.asarray(dR, dtype=float))
    if np.abs(bore).max(initial=0.0) > FORM_TOL:
        return "diameter"
    rim = np.abs(np.asarray(dR, dtype=float)).max(initial=0.0) > FORM_TOL
    blind = np.ones(np.shape(dR), bool) if through is None else ~np.asarray(through, bool)
    depth = dD is not None and np.abs(np.asarray(dD, dtype=float)[blind]).max(initial=0.0) > FORM_TOL
    return "other" if rim or depth else "position"


def drill_mask(model: FeatureModel) -> np.ndarray:
    """(N,) bool: holes whose drilled size is the bore (plain holes, chamfered rim or not, of a model with bore
    rates); the others (counterbores, countersinks, models without bore rates) are sized at their entrance."""
    holes = list(model.holes)
    if _linear(model) is None:
        return np.zeros(len(holes), dtype=bool)
    return np.array([h.kind.partition(", ")[0] == "plain" for h in holes], dtype=bool)


def drill_radii_batch(model: FeatureModel, X: np.ndarray) -> np.ndarray:
    """(B, N) the radius a shop drills (``drill_mask``: the bore, else the entrance rim) at designs ``X``."""
    X = np.atleast_2d(np.asarray(X, dtype=float))
    rim = np.asarray(model.features_batch(X)[2], dtype=float)
    mask = drill_mask(model)
    if not mask.any():
        return rim
    return np.where(mask, cast(np.ndarray, design_bores(model, X)), rim)
