"""Verification of a study's answer on real CAD: rebuild, pair, check, export.

The answer of a study is the CAD model rebuilt at the optimum, never the surrogate: ``rebuild`` builds it and
pairs its holes with the design (``order_like``: by axis line and radius, one to one, each taking the design
hole's name); ``requirement_checks`` measures every kept requirement on a solid (``verify_on_brep``), pairing the
re-extracted holes by their axis lines (``pair_by_axis``); ``export_and_verify`` writes original.step,
optimised.step and optimised.stl into the staging folder, re-imports the STEP, matches its holes to the design
to ``ROUNDTRIP_TOL_MM`` and checks every requirement again on the re-imported solid.

Every extraction here enters a through hole on the study's side (``StudySetup.view_direction``, the end the
camera sees), as the set-up did: a through hole's identity never depends on which end extraction calls its
entrance, and its entrance is the same in set-up, rebuild, checks and the re-imported STEP.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.cad.export import (
    check_solid,
    check_stl,
    expected_step_volume,
    export_step,
    export_stl,
    import_step,
    stl_watertight,
)
from cadfeat.cad.features import extract_holes, holes_to_arrays
from cadfeat.cad.features.identity import holes_at, pair_holes, take_names
from cadfeat.design.constraints import verify_on_brep
from cadfeat.design.optimize.cad import MATCH_TOL_MM
from cadfeat.errors import CadfeatError
from cadfeat.study.outputs import normalise_step_header

if TYPE_CHECKING:  # pragma: no cover
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.design.design_space import FeatureModel
    from cadfeat.results import RequirementData, VerificationData
    from cadfeat.study.delivery import Delivery
    from cadfeat.study.schema import StudyConfig
    from cadfeat.study.setup import StudySetup

__all__ = ["PREDICTION_TOL_MM", "ROUNDTRIP_TOL_MM", "AnchoredModel", "HoleCountError", "export_and_verify",
           "extract_plain", "extract_viewed", "fail_on", "order_like", "outlines_differ", "pair_by_axis",
           "predicted_holes", "rebuild", "requirement_checks"]

ROUNDTRIP_TOL_MM = 1e-6
PREDICTION_TOL_MM = 1e-6


class HoleCountError(CadfeatError):
    """A rebuilt design has another number of holes than the design (a moved hole broke into an edge or into
    another hole): ``found`` and ``designed`` holes. An infeasible point for the optimiser."""

    def __init__(self, message: str, found: int, designed: int) -> None:
        super().__init__(message)
        self.found, self.designed = found, designed


def outlines_differ(a: Sequence[Hole], b: Sequence[Hole], tol_mm: float = 1e-6) -> bool:
    """Whether the host-face outlines of paired holes differ (outer polygon or keep-outs, mm)."""
    for h, g in zip(a, b, strict=True):
        oa, ob = h.outline, g.outline
        if (oa is None) != (ob is None):
            return True
        if oa is None or ob is None:  # (both None: the same)
            continue
        pa, pb = np.asarray(oa.outer, float), np.asarray(ob.outer, float)
        if pa.shape != pb.shape or np.abs(pa - pb).max(initial=0.0) > tol_mm:
            return True
        ka, kb = list(oa.keepouts), list(ob.keepouts)
        if len(ka) != len(kb) or any(np.asarray(x).shape != np.asarray(y).shape or
                                     np.abs(np.asarray(x) - np.asarray(y)).max(initial=0.0) > tol_mm
                                     for x, y in zip(ka, kb, strict=True)):
            return True
    return False


def order_like(reference: Sequence[Hole], holes: Sequence[Hole], tol_mm: float, what: str) -> list[Hole]:
    """``holes`` reordered to pair with ``reference`` by axis line and radius (``identity.pair_holes`` with
    ``along_axis``: parallel axes of either sign, within ``tol_mm`` of the reference's axis line, radii within
    ``tol_mm``, nearest centre first), each taking its reference's name. Raises ``HoleCountError`` when the counts
    differ, ``CadfeatError`` when a hole has no partner."""
    if len(holes) != len(reference):
        raise HoleCountError(f"{what}: {len(holes)} holes found, {len(reference)} designed", len(holes),
                             len(reference))
    try:
        idx = pair_holes(list(reference), list(holes), tol_mm=tol_mm, along_axis=True)
    except CadfeatError as exc:
        raise CadfeatError(f"{what}: holes do not match the design: {exc}") from exc
    return take_names(reference, holes, idx)


def predicted_holes(setup: StudySetup, x: np.ndarray) -> list[Hole]:
    """The feature model's holes at ``x`` (``identity.holes_at``)."""
    return holes_at(setup.model, x)


def rebuild(setup: StudySetup, x: np.ndarray, verified: Sequence[Hole] | None = None
            ) -> tuple[Shape, list[Hole], float]:
    """The CAD rebuild at ``x``: solid, its holes in the design's order, and the largest centre/radius
    deviation from the prediction (mm): the feature model's, or ``verified`` (the holes the CAD trust-region
    loop extracted at ``x``, in model order) when given. The rebuilt holes pair with the prediction within
    0.5 mm of its axis lines and radii; with the feature model of a part whose map is not linear (``setup.linear``
    false: a bolt circle turned by its phase, predicted by the map linearised at the middle of the design box),
    within the CAD trust-region loop's ``MATCH_TOL_MM``, as that loop pairs them."""
    shape = setup.rebuild_shape(x)
    predicted = predicted_holes(setup, x)
    tol_mm = 0.5 if setup.linear else MATCH_TOL_MM
    if verified is not None and len(verified) == len(predicted):
        predicted = [dataclasses.replace(v, name=p.name) for v, p in zip(verified, predicted, strict=True)]
        tol_mm = 0.5
    holes = order_like(predicted, setup.rebuild_holes(shape), tol_mm, "CAD rebuild of the optimum")
    c0, _, r0 = holes_to_arrays(predicted)
    c1, _, r1 = holes_to_arrays(holes)
    err = float(max(np.linalg.norm(c1 - c0, axis=1).max(initial=0.0), np.abs(r1 - r0).max(initial=0.0)))
    return shape, holes, err


def requirement_checks(setup: StudySetup, shape: Shape, holes: Sequence[Hole], where: str) -> list[RequirementData]:
    """Every kept requirement measured on the solid ``shape`` whose holes are ``holes`` (design order).

    ``verify_on_brep`` re-extracts the holes with the study's view (``StudySetup.view_direction``: a through
    hole enters on the camera's side, as in the set-up); the design and reference holes are extracted the same
    way and paired with the design order by their axis lines."""
    view = setup.view_direction
    design = pair_by_axis(holes, extract_viewed(shape, view), f"{where} holes")
    reference = pair_by_axis(setup.holes0, extract_viewed(setup.shape0, view), "original holes")
    checks = verify_on_brep(shape, design, setup.constraints, setup.fixed_mask, reference=reference,
                            reference_shape=setup.shape0, prefer_direction=view)
    return [{**c.to_dict(), "checked_on": where} for c in checks]


def pair_by_axis(reference: Sequence[Hole], holes: Sequence[Hole], what: str, tol_mm: float = 1e-3) -> list[Hole]:
    """``holes`` reordered to pair with ``reference`` hole by hole on their axis lines (``identity.pair_holes``
    with ``along_axis``: parallel axes of either sign, centre within ``tol_mm`` of the reference's axis line,
    nearest first); each paired hole takes its reference's name."""
    if len(holes) != len(reference):
        raise HoleCountError(f"{what}: {len(holes)} holes found, {len(reference)} designed", len(holes),
                             len(reference))
    return take_names(reference, holes, pair_holes(list(reference), list(holes), tol_mm, along_axis=True,
                                                   what=what))


def fail_on(checks: Sequence[RequirementData], label: str) -> None:
    bad = [c for c in checks if not c["ok"]]
    if bad:
        text = "; ".join(f"{c['name']} {'/'.join(c['holes'])}: {c['value']:.6g} {c['unit']} (required "
                         f"{c['required']:.6g}, checked on {c.get('checked_on')})" for c in bad[:6])
        raise CadfeatError(f"{label}: the optimised design violates kept requirement(s): {text}")


def extract_plain(shape: Shape) -> list[Hole]:
    """The holes of ``shape`` by extraction's own entrance rule (no view)."""
    return extract_holes(shape)


def extract_viewed(shape: Shape, view: Sequence[float] | np.ndarray | None) -> list[Hole]:
    """The holes of ``shape``, each through hole entering on the side of ``view`` (towards the camera, part
    frame; None: extraction's own rule)."""
    return extract_holes(shape, prefer_direction=view)


class AnchoredModel:
    """The feature model anchored on the CAD-verified holes at ``x0`` (when the trust-region loop gave them):
    ``features(x) = verified(x0) + model(x) − model(x0)``, so a nonlinear part's small shop rounding is
    predicted around the real optimum, not around the linearisation point."""

    def __init__(self, model: FeatureModel, x0: np.ndarray, verified: Sequence[Hole] | None) -> None:
        self.model, self.holes = model, model.holes
        c0, _, r0 = model.features(x0)
        self.dc, self.dr = np.zeros_like(c0), np.zeros_like(r0)
        if verified is not None and len(verified) == len(r0):
            cv, _, rv = holes_to_arrays(list(verified))
            self.dc, self.dr = cv - c0, rv - r0

    def features(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        c, a, r = self.model.features(x)
        return c + self.dc, a, r + self.dr

    def features_batch(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        c, a, r = self.model.features_batch(X)
        return c + self.dc, a, r + self.dr

    def holes_at(self, x: np.ndarray) -> list[Hole]:
        return holes_at(self, x)


def export_and_verify(config: StudyConfig, stage: Path, delivery: Delivery, constraints: list[RequirementData],
                      step_checks: Callable[[Shape], list[RequirementData]] | None = None
                      ) -> tuple[list[RequirementData], VerificationData]:
    """Write original.step, optimised.step and optimised.stl into ``stage`` and verify them: a valid solid, the
    re-imported STEP's holes equal to the design's within ``ROUNDTRIP_TOL_MM`` (and its volume), every kept
    requirement again on the re-imported solid (raises ``CadfeatError`` naming a violated one), a watertight
    STL. ``step_checks``: what is measured on the re-imported solid instead of the design's requirements (a
    delivered design with added target holes: ``study.added_design.step_checks``). Returns (the B-rep and STEP
    requirement checks, the results.json ``verification`` block)."""
    setup = delivery.setup
    problems = check_solid(delivery.shape1)
    if problems:
        raise CadfeatError(f"{config.label}: the rebuilt optimum is not a valid solid: {'; '.join(problems[:3])}")
    for name, shape in (("original.step", delivery.shape0), ("optimised.step", delivery.shape1)):
        export_step(shape, stage / name)
        normalise_step_header(stage / name, f"{config.study.name} {name[:-5]}")
    from cadfeat.cad.export import verify_step_roundtrip  # lazy: looked up per call (tests replace it)

    view = setup.view_direction  # (the rebuild's holes extracted as verify_step_roundtrip extracts them)
    # the volume expected of the re-read file: the re-read original's plus the design's change (an imported
    # part's own volume is off by up to 1.5e-5 relative before any change: export.expected_step_volume)
    volume, uncertainty = expected_step_volume(delivery.shape1, delivery.shape0, stage / "original.step")
    trip = verify_step_roundtrip(stage / "optimised.step", extract_viewed(delivery.shape1, view),
                                 tol_mm=ROUNDTRIP_TOL_MM, expected_volume_mm3=volume, volume_rtol=1e-7,
                                 prefer_direction=view, volume_uncertainty_mm3=uncertainty)
    reimported = import_step(stage / "optimised.step")
    if step_checks is not None:
        checks = constraints + step_checks(reimported)
    else:
        step_holes = order_like(delivery.holes1, setup.rebuild_holes(reimported), 1e-3, "re-imported STEP")
        checks = constraints + requirement_checks(setup, reimported, step_holes, "step")
    fail_on(checks, config.label)
    export_stl(delivery.shape1, stage / "optimised.stl")
    stl_problems = check_stl(stage / "optimised.stl", delivery.shape1,
                             original=delivery.shape0 if config.study.part_kind == "step" else None)
    if stl_problems:
        raise CadfeatError(f"{config.label}: optimised.stl: {'; '.join(stl_problems[:3])}")
    verification: VerificationData = {
        "step_roundtrip_max_error_mm": max(trip.max_centre_error_mm, trip.max_radius_error_mm,
                                           trip.max_depth_error_mm),
        "step_roundtrip_max_axis_error_rad": trip.max_axis_error_rad, "brep_valid": True,
        "stl_watertight": stl_watertight(stage / "optimised.stl"), "tolerance_mm": ROUNDTRIP_TOL_MM}
    return checks, verification
