"""Objectives: the measures aggregated over the trajectory, normalised and combined (thesis §3.4, §4.2.3, §5.4).

Per pose k, each measure is first reduced over the N features (``feature_reduce``; default ``"min"``, the
worst feature, because the thesis's visual constraints — FOV eq. 3.3, focus eq. 3.6, resolution eq. 3.22 —
must hold for *every* feature; the thesis does not state its per-pose reduction). Only the features the
design can change count (``feature_mask``: the moving holes; all features when none moves) — a fixed hole's
FOV/focus/resolution cannot be improved, and as the worst feature it would flatten the objective.
Resolvability Λ_k
(eq. 4.27–4.32) is already one number per pose. Then over the L poses (``aggregate``):

- ``"sum"``: g = Σ_k Λ_k — the thesis (eq. 3.24 for FOV/FOC/RES, eq. 4.33 for Λ);
- ``"mean"``: the sum / L;
- ``"min"``: the worst pose;
- ``"smoothmin"``: g = m − (s/β) log( (1/L) Σ_k exp(−β (Λ_k − m)/s) ), m = min_k Λ_k, s = the measure's
  natural unit (``natural_units``), β = ``smoothmin_beta`` (dimensionless, default 20). It lies between
  the min (β → ∞; within s·log(L)/β of it) and the mean (β → 0), and is smooth.

Objective names: g_FOV (cone margin eq. 3.3, or the image margin in px with ``fov_measure="image"``),
g_FOC (focus margin eq. 3.4–3.6), g_RES (minor axis − ω in px, §3.3.3), g_DIR (Λ, px/mm, eq. 4.33),
g_POSE (the predicted pose error, ``pose_objective``: minus the error in mm, so larger is better; measure key
"pose", needs ``measures.pose`` = a ``cadfeat.measures.PoseInformation`` of the same poses). All are "larger
is better". Hidden, partly hidden and folded holes: the measures (``measures.evaluate``) are the thesis's equations
wherever a hole is; the objectives score what the camera cannot see by the rule of ``design.unseen`` — with h the
hidden fraction of a rim at a pose, FOV/focus/resolution score floor + (1 − h)(margin − floor) (each measure's
constant floor, ``unseen_floors``, when hidden whole, facing away with the centre hidden, or folded) —, Λ weighs
the hole's rows by 1 − h, g_POSE gives a hidden rim no information — so no objective improves when a hole the
camera cannot see shrinks, moves (staying unseen) or vanishes, and a partly hidden hole scores between seen and
hidden. ``per_pose_values`` and ``objective_values`` apply the rule to ``evaluate``'s measures (given the camera)
and take measures already scored (``unseen.scored_measures``, as ``Problem`` makes them) as they are.
Combination of the normalised objectives ĝ_i = (g_i − offset_i) / scale_i
(``Normaliser``; default ``"payoff"``: offset = nadir, scale = ideal − nadir, from each objective's own optimum
over the design space — independent of the starting design):

- ``"weighted"``: maximise Σ w_i ĝ_i (eq. 2.6, weights default 1);
- ``"maxmin"``: maximise min_i ĝ_i (eq. 3.26, 5.2); ties broken by leximin (then the next-worst ĝ, ...);
  an objective that does not depend on the design (constant over the design space) is left out and reported;
- ``"constraint"``: the measures with a ``thresholds`` entry become hard constraints g_i ≥ threshold_i (raw
  units of the aggregated objective); the others are maximised as a weighted sum (if none is left: the
  smallest normalised slack is maximised);
- ``"pareto"``: the vector ĝ (NSGA-II), the max-min point of the front is the chosen design.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar, Protocol, cast, overload

import numpy as np
from pydantic import ValidationInfo, field_validator, model_validator

from cadfeat.errors import CadfeatError
from cadfeat.settings import Settings, Tuple, boolean, choice, context_of, number, reject

if TYPE_CHECKING:  # pragma: no cover

    from cadfeat.camera import Camera
    from cadfeat.design.unseen import UnseenFields

__all__ = [
    "AGGREGATES",
    "COMBINES",
    "FEATURE_REDUCTIONS",
    "FOV_MEASURES",
    "MEASURES",
    "NORMALISATIONS",
    "Normaliser",
    "ObjectiveConfig",
    "POSE_ROTATION_LENGTH_MM",
    "SCORES",
    "STUDY_MEASURES",
    "aggregate",
    "combine",
    "combined_indices",
    "leximin_better",
    "leximin_key",
    "natural_units",
    "objective_values",
    "per_pose_values",
    "pose_objective",
]

#: measure key → objective name
MEASURES = {"fov": "g_FOV", "focus": "g_FOC", "resolution": "g_RES", "resolvability": "g_DIR", "pose": "g_POSE"}
#: g_POSE's aggregation over the trajectory (``pose_objective``)
POSE_AGGREGATES = ("rms", "worst", "logdet")
#: predicted error (mm) standing for an unobservable pose (singular information) in g_POSE
POSE_UNOBSERVABLE_MM = 1e3
AGGREGATES = ("sum", "mean", "min", "smoothmin")
COMBINES = ("weighted", "maxmin", "constraint", "pareto")
FEATURE_REDUCTIONS = ("min", "mean", "sum")
NORMALISATIONS = ("payoff", "initial", "natural", "none")
TINY_REL = 1e-3  # |g(x0)| below TINY_REL × natural unit → the natural unit is the scale


FOV_MEASURES = ("cone", "image")
SCORES = ("movable", "all")
_KEY = {v: k for k, v in MEASURES.items()}


class PosePrediction(Protocol):
    """What g_POSE reads of the predicted pose error along the trajectory (``measures.PoseInformation``; the
    optimiser's batches give ``error_mm`` alone)."""

    @property
    def information(self) -> np.ndarray: ...

    def error_mm(self, rotation_length_mm: float | None = None) -> np.ndarray: ...


def _choice(key: str, value: object, allowed: Sequence[str]) -> None:
    """A function argument's enumeration check (the config's fields are checked by the model)."""
    if value not in allowed:
        raise CadfeatError(f"objective.{key}: {value!r} is not one of {', '.join(map(repr, allowed))}")


def _one_of(value: str, names: Sequence[str]) -> str:
    if value not in names:
        raise ValueError("not one of the names")
    return value


#: g_POSE's default rotation-to-length scale ℓ (mm per rad): a rotation error δθ counts as ℓ·δθ mm of error —
#: the displacement it causes at ℓ from the part's origin; 50 mm is about the half-size of the parts cadfeat targets.
POSE_ROTATION_LENGTH_MM = 50.0

#: the measures of a study file that lists none (issue 17: new studies optimise the predicted pose error; the
#: thesis studies list the thesis measures). A configuration built in code keeps the thesis measures.
STUDY_MEASURES = ("pose",)


class ObjectiveConfig(Settings):
    """How the measures become objectives (see the module docstring) — and the study file's ``[objective]``
    (one declaration: ``cadfeat.study.settings.ObjectiveSettings`` is this class). ``weights``/``thresholds``
    are keyed by measure ("fov", ...) or objective name ("g_FOV", ...; stored by measure). ``occlusion``: holes
    hidden by the part count as unseen (a ray test against the part's mesh, default on); ``score``: which
    holes' FOV/focus/resolution count — "movable" (the holes the design moves; all when none moves), "all", or
    hole names. ``feature_reduce`` (per pose, over the features) is not a study key.
    ``rotation_length_mm`` ℓ scales rotation in the resolvability g_DIR (thesis: 1); ``pose_rotation_length_mm``
    is g_POSE's own ℓ (a rotation error of 1 rad counts as ℓ mm; default ``POSE_ROTATION_LENGTH_MM`` = 50 mm, about
    a small part's half-size, so that rotation counts: with ℓ = 1 mm g_POSE would ignore it). A study file that
    lists no ``measures`` optimises ``STUDY_MEASURES`` (g_POSE)."""

    section: ClassVar[str] = "objective"

    measures: Tuple[str] = choice(("fov", "focus", "resolution", "resolvability"),
                                  f"a non-empty list of distinct names from {', '.join(MEASURES)}",
                                  description='a study file without it: ["pose"] (g_POSE); the thesis studies list '
                                  'the thesis measures')
    aggregate: str = choice("sum", AGGREGATES)
    combine: str = choice("maxmin", COMBINES)
    weights: dict[str, float] = choice(dict[str, float], "a table measure = number ≥ 0, measures from "
                                       "objective.measures", factory=True)
    thresholds: dict[str, float] = choice(dict[str, float], "a table measure = minimum value, measures from "
                                          "objective.measures", factory=True)
    min_axis_px: float = number(5.0, 0.0, lo_open=True)
    rotation_length_mm: float = number(1.0, 0.0, lo_open=True)
    smoothmin_beta: float = number(20.0, 0.0, lo_open=True)
    normalisation: str = choice("payoff", NORMALISATIONS)
    fov_measure: str = choice("cone", FOV_MEASURES)
    occlusion: bool = boolean(True)
    score: str | Tuple[str] = choice(
        "movable", '"movable", "all" or a non-empty list of distinct hole names (e.g. ["H1", "H3"])')
    pose_aggregate: str = choice("rms", POSE_AGGREGATES,
                                 description='g_POSE over the trajectory ("pose" in measures): rms, worst or logdet')
    pose_rotation_length_mm: float = number(POSE_ROTATION_LENGTH_MM, 0.0, lo_open=True)
    feature_reduce: str = choice("min", FEATURE_REDUCTIONS, internal=True)

    @model_validator(mode="before")
    @classmethod
    def _study_measures(cls, data: object, info: ValidationInfo) -> object:
        """A study file (validation context ``study``) without ``measures`` optimises ``STUDY_MEASURES``."""
        if context_of(info).get("study") and isinstance(data, Mapping) and "measures" not in data:
            return {**cast("Mapping[str, object]", data), "measures": list(STUDY_MEASURES)}
        return cast(object, data)

    @field_validator("measures")
    @classmethod
    def _measures(cls, value: tuple[str, ...]) -> tuple[str, ...]:
        if not value or len(set(value)) != len(value):
            raise ValueError("not a non-empty list of distinct names")
        return tuple(_one_of(v, list(MEASURES)) for v in value)

    @field_validator("weights", "thresholds", mode="before")
    @classmethod
    def _by_measure(cls, value: object) -> object:
        """Objective names ("g_FOV") as measure keys ("fov")."""
        if isinstance(value, Mapping):
            table = cast("Mapping[object, object]", value)
            return {_KEY.get(k, k) if isinstance(k, str) else k: v for k, v in table.items()}
        return value

    @field_validator("weights", "thresholds")
    @classmethod
    def _finite(cls, value: dict[str, float]) -> dict[str, float]:
        if not all(math.isfinite(v) for v in value.values()):
            raise ValueError("not finite")
        return dict(sorted(value.items()))

    @field_validator("score")
    @classmethod
    def _score(cls, value: str | tuple[str, ...]) -> str | tuple[str, ...]:
        if isinstance(value, str):
            return _one_of(value, SCORES)
        if not value or not all(value) or len(set(value)) != len(value):
            raise ValueError("not a non-empty list of distinct names")
        return value

    @model_validator(mode="after")
    def _rules(self, info: ValidationInfo) -> ObjectiveConfig:
        """Weights and thresholds name chosen measures; combine = "constraint" needs thresholds. A study file
        (validation context ``study``) also gives thresholds only with "constraint", and not for every measure."""
        allowed = ", ".join(self.measures)
        for name in ("weights", "thresholds"):
            table = cast("dict[str, float]", getattr(self, name))
            for m, v in table.items():
                if m not in self.measures:
                    raise reject(f"{name}.{m}", "not one of objective.measures", allowed)
                if name == "weights" and v < 0:
                    raise reject(f"weights.{m}", f"{v} is not allowed", "a number ≥ 0")
        if self.combine == "weighted" and self.weights and not any(w > 0 for w in self.weights.values()):
            raise reject("weights", "all weights are zero", "non-negative weights, at least one positive")
        if self.combine == "constraint" and not self.thresholds:
            raise reject("thresholds", "missing (combine = \"constraint\" makes these measures hard constraints)",
                         f"a table measure = minimum value, measures from {allowed}")
        if not context_of(info).get("study"):
            return self
        if self.combine == "constraint" and set(self.thresholds) == set(self.measures):
            raise reject("thresholds", "every measure is a constraint, none is left to optimise",
                         "thresholds for some of the measures, not all")
        if self.combine != "constraint" and self.thresholds:
            raise reject("thresholds", f"only used with combine = \"constraint\" (combine is {self.combine!r})",
                         "remove it, or combine = \"constraint\"")
        return self

    @staticmethod
    def key(name: str) -> str:
        """Measure key of a measure or objective name ("g_FOV" → "fov")."""
        return _KEY.get(name, name)

    @property
    def names(self) -> list[str]:
        """Objective names in order (g_FOV, ...)."""
        return [MEASURES[m] for m in self.measures]

    @property
    def objective_measures(self) -> list[str]:
        """The measures that are objectives (not thresholded constraints)."""
        if self.combine != "constraint":
            return list(self.measures)
        return [m for m in self.measures if m not in self.thresholds]


# ------------------------------------------------------------------------------------- aggregation
def _reduce_features(values: np.ndarray, how: str) -> np.ndarray:
    if values.shape[-1] == 0:
        return np.zeros(values.shape[:-1])
    return {"min": np.min, "mean": np.mean, "sum": np.sum}[how](values, axis=-1)


def _scored(measures: object, config: ObjectiveConfig, camera: Camera | None) -> dict[str, np.ndarray] | None:
    """The scored margins (``unseen.scored_arrays``) of ``evaluate``'s measures, or None when ``measures`` are scored
    already, carry no unseen flags (arrays of another origin) or no chosen measure is ruled (module docstring)."""
    if getattr(measures, "scored", False) or getattr(measures, "rim_hidden", None) is None \
            or not set(config.measures) & {"fov", "focus", "resolution"}:  # ``unseen.is_scored``
        return None
    from cadfeat.design.unseen import scored_arrays  # lazy: the measures package stays out of the settings' import

    if camera is None:
        raise CadfeatError("objective values of measures.evaluate's measures need the camera, for the unseen-hole "
                           "rule (design.unseen): pass camera=..., or score them first with "
                           "cadfeat.design.unseen.scored_measures(measures, camera, min_axis_px)")
    return scored_arrays(cast("UnseenFields", measures), camera, config.min_axis_px)  # (measures.evaluate's)


def per_pose_values(measures: object, config: ObjectiveConfig, feature_mask: np.ndarray | None = None,
                    camera: Camera | None = None) -> dict[str, np.ndarray]:
    """Per-pose value (..., L) of each chosen measure: the features selected by ``feature_mask`` (N,) bool
    (default all) reduced by ``config.feature_reduce``; resolvability uses every feature (the Jacobian).
    ``measures`` of ``measures.evaluate`` are scored by the unseen rule first (``camera``: the camera they were
    computed with, module docstring); scored ones (``unseen.ScoredMeasures``) are read as they are."""
    out: dict[str, np.ndarray] = {}
    mask = None if feature_mask is None or not np.any(feature_mask) else np.asarray(feature_mask, dtype=bool)
    scored = _scored(measures, config, camera)
    for m in config.measures:
        if m == "pose":
            out[m] = -_pose_errors(_pose_of(measures), config.pose_rotation_length_mm)
            continue
        if m == "resolvability":
            out[m] = np.asarray(getattr(measures, "resolvability"), dtype=float)  # noqa: B009 (any measures)
            continue
        attr = {"fov": "fov" if config.fov_measure == "cone" else "fov_px", "focus": "focus",
                "resolution": "resolution_px"}[m]
        values = np.asarray(getattr(measures, attr) if scored is None else scored[attr], dtype=float)
        out[m] = _reduce_features(values if mask is None else values[..., mask], config.feature_reduce)
    return out


def aggregate(values: np.ndarray, how: str, beta: float = 20.0, unit: float = 1.0) -> np.ndarray:
    """Aggregate per-pose values (..., L) over the trajectory (module docstring): (...)."""
    v = np.asarray(values, dtype=float)
    if how == "sum":
        return v.sum(axis=-1)
    if how == "mean":
        return v.mean(axis=-1)
    if how == "min":
        return v.min(axis=-1)
    if how == "smoothmin":
        m = v.min(axis=-1)
        z = np.exp(-beta * (v - m[..., None]) / unit)
        return m - (unit / beta) * np.log(z.mean(axis=-1))
    raise CadfeatError(f"objective.aggregate: {how!r} is not one of {', '.join(AGGREGATES)}")


def objective_values(measures: object, config: ObjectiveConfig, units: Mapping[str, float] | None = None,
                     feature_mask: np.ndarray | None = None, camera: Camera | None = None) -> dict[str, float]:
    """The aggregated objectives {g_FOV, g_FOC, g_RES, g_DIR} (those chosen) of one ``Measures``; ``units``
    (measure → natural unit, ``natural_units``) sets the smooth-min scale (1 if not given);
    ``feature_mask`` and ``camera`` (the unseen rule of ``evaluate``'s measures) as in ``per_pose_values``."""
    units = units or {}
    out: dict[str, float] = {}
    for m, v in per_pose_values(measures, config, feature_mask, camera).items():
        if m == "pose":
            out[MEASURES[m]] = pose_objective(_pose_of(measures), config.pose_aggregate,
                                               config.pose_rotation_length_mm)
            continue
        out[MEASURES[m]] = float(aggregate(v, config.aggregate, config.smoothmin_beta, units.get(m, 1.0)))
    return out


def _pose_of(measures: object) -> PosePrediction:
    pose: PosePrediction | None = getattr(measures, "pose", None)
    if pose is None:
        raise CadfeatError("objective.measures: 'pose' (g_POSE) needs the pose information of the same poses "
                           "(measures.pose = cadfeat.measures.pose_information(...)); none was computed")
    return pose


def _pose_errors(pose: PosePrediction, rotation_length_mm: float) -> np.ndarray:
    """(..., L) predicted error per pose, mm: √(e_t² + (ℓ e_r)²) with bias and noise (``PoseInformation``),
    unobservable poses at ``POSE_UNOBSERVABLE_MM``."""
    e = np.asarray(pose.error_mm(rotation_length_mm), dtype=float)
    return np.where(np.isfinite(e), np.minimum(e, POSE_UNOBSERVABLE_MM), POSE_UNOBSERVABLE_MM)


def pose_objective(pose: PosePrediction, how: str = "rms", rotation_length_mm: float = 50.0) -> float:
    """g_POSE (mm, larger is better) of a ``PoseInformation`` along the trajectory.

    Per pose the predicted error e_k = √(‖δ_b,p‖² + σ_t² + ℓ² (‖δ_b,θ‖² + σ_θ²)) (bias and noise; δθ in rad,
    ℓ = ``rotation_length_mm``: a rotation error of 1 rad counts as ℓ mm, as in the resolvability's scaling),
    then over the L poses (``how``):

    - ``"rms"``: g = −√(mean_k e_k²);
    - ``"worst"``: g = −max_k e_k;
    - ``"logdet"`` (D-optimal, noise only): g = −exp(−mean_k log det(S I_k S) / 12), S = diag(1,1,1,1/ℓ,1/ℓ,1/ℓ):
      minus the geometric-mean standard deviation over the six directions and the poses, mm.

    An unobservable pose (fewer than three holes seen) counts as ``POSE_UNOBSERVABLE_MM``. As a constraint,
    ``thresholds = {"pose": -0.05}`` means "predicted error ≤ 0.05 mm".
    """
    _choice("pose_aggregate", how, POSE_AGGREGATES)
    if how == "logdet":
        s = np.array([1.0, 1.0, 1.0] + [1.0 / rotation_length_mm] * 3)
        info = np.asarray(pose.information, dtype=float) * s[:, None] * s[None, :]
        sign, raw = np.linalg.slogdet(info)
        floor = -12.0 * np.log(POSE_UNOBSERVABLE_MM)
        logdet = cast(np.ndarray, np.where((sign > 0) & np.isfinite(raw), np.maximum(raw, floor), floor))
        return float(-np.exp(-np.mean(logdet) / 12.0))
    e = _pose_errors(pose, rotation_length_mm)
    return float(-np.sqrt(np.mean(e * e, axis=-1))) if how == "rms" else float(-np.max(e, axis=-1))


def natural_units(config: ObjectiveConfig, camera: Camera, n_poses: int, n_features: int,
                  median_depth_mm: float) -> dict[str, float]:
    """A natural unit of each aggregated objective (measure key → value), used when the initial value is tiny
    and for the smooth min: per pose —

    - fov (cone): 1 − cos(α/2), the margin of a feature on the optical axis (the measure's range);
      (image): half the smaller image side, px;
    - focus: 1 (the margin is normalised by the half depth of field);
    - resolution: ω = min_axis_px (px; 1 px if ω = 0);
    - resolvability: √N · f_x / Z̃ px/mm — Λ of N points at the median depth Z̃ (at the reference design)
      translating parallel to the image plane (each moves f_x/Z̃ px per mm);
    - pose: Z̃ / f_x mm, one pixel's footprint at the median depth (g_POSE is in mm, never summed over poses);

    times L for ``aggregate="sum"``."""
    per_pose = {
        "fov": (1.0 - np.cos(0.5 * camera.fov_rad)) if config.fov_measure == "cone"
        else 0.5 * min(camera.width, camera.height),
        "focus": 1.0,
        "resolution": config.min_axis_px if config.min_axis_px > 0 else 1.0,
        "resolvability": np.sqrt(max(n_features, 1)) * camera.fx / max(median_depth_mm, 1e-9),
        "pose": max(median_depth_mm, 1e-9) / camera.fx,
    }
    factor = n_poses if config.aggregate == "sum" else 1
    return {m: float(per_pose[m] * (1 if m == "pose" else factor)) for m in config.measures}


@dataclass(frozen=True)
class Normaliser:
    """Scales that make the objectives comparable: ĝ_i = (g_i − offset_i) / scale_i.

    ``method``:

    - ``"payoff"`` (default): the ideal/nadir normalisation of the payoff table — each objective maximised
      alone over the design space (on features), ideal_i = its own optimum, nadir_i = its worst value at the
      other objectives' optima; ĝ_i = (g_i − nadir_i)/(ideal_i − nadir_i), so 1 = the best this objective can
      reach, 0 = what it falls to when another objective is favoured. Fixed by the design space, camera and
      trajectory: the same whatever the starting design. An objective whose range is below ``TINY_REL`` of
      its natural unit does not depend on the design (``constant``): it keeps its natural unit and is left
      out of the combination. A single objective has nothing to trade off: its row is the best of a fixed
      Sobol sample of the design space (``Problem.payoff_normaliser``), so ĝ ≥ 1 at its optimum;
    - ``"initial"`` — scale_i = |g_i(x0)| (the initial design), or the natural unit when |g_i(x0)| < 1e-3 ×
      natural unit. START-DEPENDENT: a max-min optimum then moves with the starting design;
    - ``"natural"`` — the natural unit; ``"none"`` — 1 (raw units).

    ``reference``: objective name → scale; ``offset``: objective name → offset (0 unless payoff);
    ``sources``: objective name → "payoff", "initial", "natural" or "none"; ``constant``: objective names that
    do not depend on the design variables; ``payoff``: the payoff table (rows: the objective maximised)."""

    method: str
    reference: dict[str, float]
    sources: dict[str, str]
    note: str = ""
    offset: dict[str, float] = field(default_factory=dict[str, float])
    constant: tuple[str, ...] = ()
    payoff: dict[str, object] | None = None

    @classmethod
    def build(cls, method: str, initial: Mapping[str, float], natural: Mapping[str, float]) -> Normaliser:
        """From the initial objective values and the natural units (both keyed by objective name); for
        ``"payoff"`` use ``from_payoff``."""
        _choice("normalisation", method, NORMALISATIONS)
        ref: dict[str, float] = {}
        src: dict[str, str] = {}
        for name, g0 in initial.items():
            unit = float(natural[name])
            if method == "none":
                ref[name], src[name] = 1.0, "none"
            elif method == "initial" and abs(g0) >= TINY_REL * unit:
                ref[name], src[name] = abs(float(g0)), "initial"
            else:
                ref[name], src[name] = unit, "natural"
        notes = {"initial": "each objective divided by |its value at the initial design| (start-dependent: the "
                            "optimum moves with the starting design), or by its natural unit when that value is "
                            "below 1e-3 of the unit",
                 "natural": "each objective divided by its natural unit",
                 "none": "raw units (max-min compares unlike quantities)",
                 "payoff": "natural units (payoff table not computed)"}
        note = notes[method] + _UNITS_NOTE
        return cls(method, ref, src, note)

    @classmethod
    def from_payoff(cls, names: Sequence[str], table: np.ndarray, natural: Mapping[str, float],
                    sampled_range: np.ndarray | None = None, sampled_min: np.ndarray | None = None) -> Normaliser:
        """The ideal/nadir normaliser of a payoff table ``table`` (K, K): row i = the raw objectives at the
        design that maximises objective i alone. ``sampled_range``/``sampled_min`` (K,): the range and minimum
        of each objective over a fixed sample of the design space (decide ``constant``, and the nadir when the
        table gives no spread: objectives that do not conflict)."""
        table = np.asarray(table, dtype=float)
        ideal = np.diag(table).copy()
        ideal = np.maximum(ideal, table.max(axis=0))
        nadir = table.min(axis=0)
        ref: dict[str, float] = {}
        off: dict[str, float] = {}
        src: dict[str, str] = {}
        constant: list[str] = []
        for i, name in enumerate(names):
            unit = float(natural[name])
            spread = ideal[i] - nadir[i]
            varies = sampled_range is None or sampled_range[i] > TINY_REL * unit
            if spread <= TINY_REL * unit and varies and sampled_min is not None:
                nadir[i] = min(nadir[i], float(sampled_min[i]))  # no conflict: worst sampled design as nadir
                spread = ideal[i] - nadir[i]
            if spread <= TINY_REL * unit and not varies:
                ref[name], off[name], src[name] = unit, float(ideal[i]), "natural"
                constant.append(name)
            elif spread <= TINY_REL * unit:
                ref[name], off[name], src[name] = unit, float(nadir[i]), "natural"
            else:
                ref[name], off[name], src[name] = float(spread), float(nadir[i]), "payoff"
        note = ("ideal/nadir from the payoff table: each objective maximised alone over the design space (on "
                "features); ĝ = (g − nadir)/(ideal − nadir), 1 = the objective's own optimum, 0 = its worst at the "
                "other objectives' optima — independent of the starting design")
        if constant:
            note += f"; constant over the design space (left out of the combination): {', '.join(constant)}"
        payoff: dict[str, object] = {"names": list(names), "table": table.tolist(), "ideal": ideal.tolist(),
                                     "nadir": nadir.tolist()}
        return cls("payoff", ref, src, note + _UNITS_NOTE, off, tuple(constant), payoff)

    @overload
    def normalise(self, values: Mapping[str, float]) -> dict[str, float]: ...
    @overload
    def normalise(self, values: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]: ...
    def normalise(self, values: Mapping[str, float] | Mapping[str, np.ndarray]
                  ) -> dict[str, float] | dict[str, np.ndarray]:
        """ĝ = (g − offset) / reference per objective (a value gives a numpy float, an array an array)."""
        return {k: (np.asarray(v) - self.offset.get(k, 0.0)) / self.reference[k] for k, v in values.items()}

    def to_dict(self) -> dict[str, object]:
        out: dict[str, object] = {"method": self.method, "reference": dict(self.reference),
                                  "sources": dict(self.sources), "note": self.note}
        if self.offset:
            out["offset"] = dict(self.offset)
        if self.constant:
            out["constant"] = list(self.constant)
        if self.payoff is not None:
            out["payoff"] = self.payoff
        return out


_UNITS_NOTE = ("; natural units: FOV 1−cos(α/2), focus 1, resolution ω px, resolvability √N·fx/Z̃ px/mm (per pose; "
               "×L for sums), pose Z̃/fx mm")


def combined_indices(config: ObjectiveConfig, names: Sequence[str], constant: Sequence[str] = ()) -> list[int]:
    """Indices (in ``names`` order) of the objectives that enter the combination: not thresholded (for
    "constraint") and not ``constant`` (unless every one is)."""
    keys = [ObjectiveConfig.key(n) for n in names]
    use = [i for i, k in enumerate(keys) if k in config.objective_measures]
    varying = [i for i in use if names[i] not in set(constant)]
    return varying or use


def combine(G: np.ndarray, config: ObjectiveConfig, names: Sequence[str], constant: Sequence[str] = ()) -> np.ndarray:
    """The scalar to MAXIMISE from normalised objectives ``G`` (..., K) in ``names`` order (module docstring).
    For "constraint" the thresholded objectives are excluded (they are constraints), and so are the
    ``constant`` ones (they do not depend on the design); for "pareto" the max-min value is returned (the
    chosen point's criterion)."""
    G = np.asarray(G, dtype=float)
    keys = [ObjectiveConfig.key(n) for n in names]
    use = combined_indices(config, names, constant)
    if config.combine in ("maxmin", "pareto"):
        return G[..., use].min(axis=-1)
    if not use:  # constraint with every measure thresholded: no objective left
        return np.zeros(G.shape[:-1])
    w = np.array([config.weights.get(keys[i], 1.0) for i in use])
    return G[..., use] @ w


def leximin_key(G_normalised: np.ndarray) -> np.ndarray:
    """The normalised objectives (..., K) sorted ascending: max-min compares the first entry, leximin the
    next ones on ties (the worst objective, then the next-worst, ...)."""
    return np.sort(np.asarray(G_normalised, dtype=float), axis=-1)


def leximin_better(a: np.ndarray, b: np.ndarray, tol: float = 1e-7) -> bool:
    """Whether sorted vector ``a`` beats ``b`` lexicographically, entries within ``tol`` counted equal."""
    for x, y in zip(np.asarray(a).ravel(), np.asarray(b).ravel(), strict=True):
        if x > y + tol:
            return True
        if x < y - tol:
            return False
    return False
