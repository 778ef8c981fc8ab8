"""The unseen-hole rule of the objectives (docs/design.md "Trust rules"; issue 17, issue 32 item 7).

``measures.evaluate`` reports the thesis's measures as the equations give them (FOV cone eq. 3.2–3.3, focus
eq. 3.6, the image margin and resolution §3.3.3) together with what the camera cannot see: ``hidden`` (the centre's
ray blocked by the part), ``folded`` (past the lens's fold radius), ``rim_hidden`` h (the hidden fraction of the
rim) and ``facing``. This module is where the objectives turn those into scores — a scoring rule, not a measure:
per feature-pose, for each of the FOV cone margin, the FOV image margin (px), the focus margin and the resolution
margin (px) — v the measure's value, f its floor (``unseen_floors``: the value of a feature behind the camera,
below any seen one, a constant of the camera):

- past the lens's fold radius (``folded``), or facing away from the camera with its centre hidden by the part:
  f;
- facing the camera: ``f + (1 − h)(v − f)``, h in [0, 1] the hidden fraction of the hole's rim. A rim seen whole
  (h = 0) scores v, bit for bit as without occlusion; a rim hidden whole scores f; a partly hidden one scores
  between, in proportion to the rim seen.

So a hidden hole never scores better than the same hole seen (f ≤ v); a wholly hidden hole scores f whatever its
size and position, so it gains nothing by shrinking, by moving while it stays hidden or by vanishing; and a
partly hidden one gains only by showing more of its rim — the slope that leads an optimiser out from behind
what hides it. A partly hidden hole whose centre is seen may gain by shrinking when the smaller rim comes wholly
into view: that is a hole coming into view, not a hidden one gaining. The scored ``visible`` flag also drops the
folded feature-poses (the measure's flag, the thesis's visibility, does not know the lens's fold).

``scored_measures`` applies the rule to a ``Measures`` and returns a ``ScoredMeasures`` (same fields, the four
margins and ``visible`` scored): ``Problem`` scores every design through it, the study's outputs and pre-flight
read it, and ``objectives.objective_values`` applies it to raw measures it is given (with the camera). The rule
was applied inside ``measures.evaluate`` until issue 32 item 7; the objective values are the same bit for bit.
Λ (g_DIR) is not scored here: its Jacobian rows are weighted by ``Measures.seen`` inside ``evaluate``, and g_POSE
gives a hidden rim no information in ``measures.pose_information``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar, Protocol

import numpy as np

from cadfeat.camera import Camera
from cadfeat.measures.evaluate import Measures
from cadfeat.measures.focus import focus_scale_mm
from cadfeat.measures.fov import behind_px

__all__ = ["UNSEEN_KEYS", "ScoredMeasures", "apply_unseen", "is_scored", "scored_arrays", "scored_measures",
           "unseen_floors"]

#: The ``Measures`` fields the rule applies to.
UNSEEN_KEYS = ("fov", "fov_px", "focus", "resolution_px")


@dataclass(frozen=True)
class ScoredMeasures(Measures):
    """``Measures`` with the unseen rule applied (module docstring): ``fov``, ``fov_px``, ``focus`` and
    ``resolution_px`` scored, ``visible`` false where folded; every other field as ``evaluate`` gave it."""

    scored: ClassVar[bool] = True


class UnseenFields(Protocol):
    """What the rule reads of a ``Measures`` (or of any object with its fields): the margins it scores, and what
    tells a hole unseen."""

    @property
    def fov(self) -> np.ndarray: ...
    @property
    def fov_px(self) -> np.ndarray: ...
    @property
    def focus(self) -> np.ndarray: ...
    @property
    def resolution_px(self) -> np.ndarray: ...
    @property
    def facing(self) -> np.ndarray: ...
    @property
    def folded(self) -> np.ndarray: ...
    @property
    def hidden(self) -> np.ndarray: ...
    @property
    def rim_hidden(self) -> np.ndarray: ...
    @property
    def visible(self) -> np.ndarray: ...


def is_scored(measures: object) -> bool:
    """True for measures the rule was applied to (a ``ScoredMeasures``, or a wrapper that forwards ``scored``)."""
    return bool(getattr(measures, "scored", False))


def unseen_floors(camera: Camera, min_axis_px: float) -> dict[str, float]:
    """The floor f of each measure (module docstring): cone −1 − cos(α/2), image ``behind_px``, focus
    −(near + far)/scale (below any seen hole up to a depth of 2·far + near), resolution −ω − max(W, H) px."""
    near, far = camera.depth_of_field_mm
    return {"fov": -1.0 - float(np.cos(0.5 * camera.fov_rad)), "fov_px": behind_px(camera),
            "focus": -(near + (far if np.isfinite(far) else 0.0)) / focus_scale_mm(camera),
            "resolution_px": -float(min_axis_px) - float(max(camera.width, camera.height))}


def apply_unseen(camera: Camera, out: dict[str, np.ndarray], hidden: np.ndarray, folded: np.ndarray,
                 rim_hidden: np.ndarray, min_axis_px: float) -> None:
    """Apply the rule (module docstring) to the measures ``out`` (``UNSEEN_KEYS`` arrays (L, N)) in place:
    ``hidden`` (L, N) the centre's ray blocked, ``folded`` past the fold radius, ``rim_hidden`` h (L, N);
    ``out["facing"]`` tells facing away."""
    floors = unseen_floors(camera, min_axis_px)
    hard = folded | (hidden & (out["facing"] <= 0.0))
    part = (rim_hidden > 0.0) & ~hard
    if part.any():
        seen = 1.0 - rim_hidden[part]
        for key in UNSEEN_KEYS:
            v = out[key][part]
            out[key][part] = floors[key] + seen * (v - floors[key])
    if hard.any():
        for key in UNSEEN_KEYS:
            out[key][hard] = floors[key]


def scored_arrays(measures: UnseenFields, camera: Camera, min_axis_px: float) -> dict[str, np.ndarray]:
    """The scored ``UNSEEN_KEYS`` margins and ``visible`` (L, N) of ``measures`` (a ``Measures``, or any object with
    its fields, computed with this ``camera`` and ``min_axis_px``): new arrays, ``measures`` is left as it is."""
    out = {key: np.array(getattr(measures, key), dtype=float) for key in UNSEEN_KEYS}
    out["facing"] = np.asarray(measures.facing, dtype=float)
    folded = np.asarray(measures.folded, dtype=bool)
    apply_unseen(camera, out, np.asarray(measures.hidden, dtype=bool), folded,
                 np.asarray(measures.rim_hidden, dtype=float), min_axis_px)
    del out["facing"]
    out["visible"] = np.asarray(measures.visible, dtype=bool) & ~folded
    return out


def scored_measures(measures: Measures, camera: Camera, min_axis_px: float) -> ScoredMeasures:
    """``measures`` (``measures.evaluate``'s, computed with this ``camera`` and ``min_axis_px``) as the objectives
    score them (module docstring; ``scored_arrays``); already scored measures are returned as they are."""
    if isinstance(measures, ScoredMeasures):
        return measures
    fields = {f.name: getattr(measures, f.name) for f in dataclasses.fields(Measures)}
    fields.update(scored_arrays(measures, camera, min_axis_px))
    return ScoredMeasures(**fields)
