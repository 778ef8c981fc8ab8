"""Any design of a study, scored and tracked (issue 17: one closed loop, a public API for any design).

A design is a parameter dict ``{design variable: value}`` — the names of the study's design space
(``cadfeat run`` prints them: a part script's parameters, a STEP part's ``H1.s``/``H1.t``/``H1.d``, …) and, for a
part script, its integer parameters; a variable not given keeps the study's start (``StudySetup.space.x0``).

- ``score_design(study, values)``: the part rebuilt in CAD at that design (the real model, never the surrogate),
  its holes extracted in the design's order and named as ``cadfeat run`` names them, then scored exactly as
  ``cadfeat run`` scores its delivered design: the objectives and their combined value (``pipeline.score``),
  every kept requirement measured on the B-rep (``verify.requirement_checks``) and the predicted pose error
  before (the study's original) and at this design (``study.pose_accuracy``).
- ``track_design(study, values)``: the closed loop on that design and, paired with it, the study's original
  (``against="original"``; None tracks the design alone), with the settings of ``cadfeat run``'s check (``mode``
  fast or full) and any ``[tracking]`` key overridden (``runs=16``, ``seed=11``, …): the results.json
  ``tracking`` section, ``cadfeat track``'s numbers for the same design.

Bad input (an unknown variable, a value outside its bounds, an unknown ``[tracking]`` key) is one
``StudyError`` naming the key and the allowed values, before any CAD work (a STEP part's variables, its holes',
once its set-up has read them). A design at which the part's holes change in number (a moved hole broke into an
edge or into another hole) is one ``CadfeatError`` line naming the design and both hole counts.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.errors import CadfeatError
from cadfeat.study.schema import StudyConfig, StudyError, TrackingSpec

if TYPE_CHECKING:  # pragma: no cover
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.results import JsonDict
    from cadfeat.study.settings.design import ParameterSpec
    from cadfeat.study.setup import StudySetup

__all__ = ["score_design", "track_design"]

StudySource = str | Path | Mapping[str, object] | StudyConfig


def score_design(study: StudySource, values: Mapping[str, float] | None = None, *,
                 seed: int | None = None) -> JsonDict:
    """The design ``values`` of ``study`` (module docstring) rebuilt in CAD and scored as ``cadfeat run`` scores
    its delivered design. Returns {"values", "holes", "objectives", "combined" (None for pareto),
    "requirements" (each kept requirement's check), "requirements_hold", "rebuild_deviation_mm" (largest
    centre/radius deviation of the CAD holes from the feature model's prediction), "pose_accuracy" (results.json's
    block: "before" the original, "after" this design)}, as results.json writes them (``outputs.plain``)."""
    from cadfeat.study.outputs import hole_dict, plain
    from cadfeat.study.pipeline import score
    from cadfeat.study.pose_accuracy import part_mesh, pose_accuracy
    from cadfeat.study.verify import requirement_checks

    config, setup, x, (shape, holes, deviation) = _design(study, values, seed)
    objectives, combined = score(setup, holes)
    checks = requirement_checks(setup, shape, holes, "brep")
    pose = pose_accuracy(config, setup, setup.holes0, part_mesh(config, setup.shape0), setup, holes,
                         part_mesh(config, shape))
    fixed, movable = np.asarray(setup.fixed_mask, bool), np.asarray(setup.movable_mask, bool)
    return plain({"values": {**setup.space.as_dict(x), **dict(setup.int_values)},
                  "holes": [hole_dict(h, i, bool(fixed[i]), bool(movable[i])) for i, h in enumerate(holes)],
                  "objectives": objectives, "combined": combined, "requirements": checks,
                  "requirements_hold": all(bool(c["ok"]) for c in checks),
                  "rebuild_deviation_mm": float(deviation), "pose_accuracy": pose})


def track_design(study: StudySource, values: Mapping[str, float] | None = None, *, against: str | None = "original",
                 mode: str = "fast", seed: int | None = None, out_dir: str | Path | None = None,
                 **tracking: object) -> JsonDict:
    """The closed loop on the design ``values`` of ``study`` ("after") and, with ``against="original"``, on the
    study's original ("before", paired run by run: the verdict per estimator). ``mode``: "fast" (``cadfeat
    run``'s default check: PnP + IEKF, 8 runs, ≤ 20 frames) or "full" (the study's ``[tracking]`` settings);
    ``tracking``: ``[tracking]`` keys overriding either (e.g. ``runs=16, seed=11``); ``out_dir``: a folder the drawn
    frames go into, under ``tracking/`` (None: none written; a non-empty folder cadfeat did not create is refused,
    as by ``cadfeat run``). Returns the results.json ``tracking`` section (as results.json writes it)."""
    from cadfeat.output_folder import check_output_folder, staged_output
    from cadfeat.study.closed_loop_check import fast_spec
    from cadfeat.study.outputs import plain
    from cadfeat.study.tracking import run_tracking

    if against not in ("original", None):
        raise StudyError(f"track_design: against={against!r} is not allowed; allowed: 'original' or None")
    if mode not in ("fast", "full"):
        raise StudyError(f"track_design: mode={mode!r} is not allowed; allowed: 'fast', 'full'")
    from cadfeat.study.run import _resolve  # pyright: ignore[reportPrivateUsage] (the run's own resolution)

    config = _resolve(study, seed)
    spec = _with_keys(config.tracking_settings(), tracking, config.label)
    if out_dir is not None:
        check_output_folder(out_dir, names=("tracking",))  # before any work
    _, setup, _, (shape, holes, _) = _design(config, values, None)
    if mode == "fast":  # the check's fast settings on the study's (and the given keys over them)
        spec = _with_keys(fast_spec(dataclasses.replace(config, tracking=spec), len(setup.trajectory.times_s)),
                          tracking, config.label)
    designs = {"after": (shape, holes)}
    if against == "original":
        designs = {"before": (setup.shape0, setup.holes0), **designs}
    if out_dir is None:
        return plain(run_tracking(config, designs, None, spec))
    with staged_output(out_dir, merge=True, names=("tracking",)) as stage:  # never over what cadfeat did not write
        return plain(run_tracking(config, designs, stage, spec))


def _with_keys(spec: TrackingSpec, keys: Mapping[str, object], label: str) -> TrackingSpec:
    """``spec`` with the ``[tracking]`` ``keys`` replaced; an unknown key is one error listing the allowed ones."""
    unknown = sorted(set(keys) - set(TrackingSpec.study_keys()))
    if unknown:
        raise StudyError(f"{label}: track_design: unknown [tracking] key(s) {', '.join(unknown)}; allowed: "
                         f"{', '.join(sorted(TrackingSpec.study_keys()))}")
    return spec.replace(**keys) if keys else spec


def _design(study: StudySource, values: Mapping[str, float] | None, seed: int | None
            ) -> tuple[StudyConfig, StudySetup, np.ndarray, tuple[Shape, list[Hole], float]]:
    """(config, the set-up of the design's integer parameters, the design vector, ``verify.rebuild`` at it). A part
    script's values are checked against the study's parameters before any CAD work; a STEP part's variables (its
    holes') are known once its set-up has read them."""
    from cadfeat.study.run import _resolve  # pyright: ignore[reportPrivateUsage] (the run's own resolution)
    from cadfeat.study.setup import setup_study
    from cadfeat.study.verify import HoleCountError, rebuild

    config = _resolve(study, seed)
    values = dict(values or {})
    params = {p.name: p for p in config.design.parameters} if config.study.part_kind == "script" else {}
    ints = sorted(k for k, p in params.items() if p.is_int)
    int_values = {k: _int_value(config, params[k], values.pop(k)) for k in list(values) if k in ints}
    if params:
        _check(config, values, {k: (p.lower, p.upper, p.unit) for k, p in params.items() if not p.is_int}, ints)
    setup = setup_study(config, int_values or None, time_limit_s=config.study.build_timeout_s)
    space = setup.space
    if not params:
        _check(config, values, {v.name: (v.lower, v.upper, v.unit) for v in space.variables}, [])
    x = np.array(space.x0, dtype=float)
    for k, v in values.items():
        x[list(space.names).index(k)] = float(v)
    try:
        return config, setup, x, rebuild(setup, x)
    except HoleCountError as exc:
        design = ", ".join(f"{k}={v:g}" for k, v in {**space.as_dict(x), **int_values}.items())
        raise CadfeatError(f"{config.label}: the design {design} has {exc.found} holes, the study's design "
                           f"{exc.designed}: a moved hole broke into an edge or into another hole; allowed: a "
                           "design at which every hole of the part stays a hole of its own") from None


def _int_value(config: StudyConfig, parameter: ParameterSpec, value: object) -> int:
    lo, hi = parameter.lower, parameter.upper
    if isinstance(value, bool) or not isinstance(value, int | float) or not float(value).is_integer() \
            or not lo <= int(value) <= hi:
        raise StudyError(f"{config.label}: design value {parameter.name}={value!r} is not allowed; allowed: an "
                         f"integer in [{lo:g}, {hi:g}]")
    return int(value)


def _check(config: StudyConfig, values: Mapping[str, float], bounds: Mapping[str, tuple[float, float, str]],
           ints: list[str]) -> None:
    """One error for the first unknown name or value outside its bounds (lower, upper, unit) of ``values``."""
    unknown = sorted(set(values) - set(bounds))
    if unknown:
        raise StudyError(f"{config.label}: design variable(s) {', '.join(unknown)} not in the study; allowed: "
                         f"{', '.join(list(bounds) + ints)}")
    for k, v in values.items():
        lower, upper, unit = bounds[k]
        try:
            value = float(v)
        except (TypeError, ValueError):
            value = float("nan")
        if not (np.isfinite(value) and lower <= value <= upper):
            raise StudyError(f"{config.label}: design value {k}={v!r} is not allowed; allowed: a number in "
                             f"[{lower:g}, {upper:g}] {unit}".rstrip())
