"""Parts given as STEP files: import, hole selection, and re-drilling holes at new places and sizes.

A STEP part has no parameters, so a redesign changes it directly on the B-rep (docs/design.md, "Data flow"):
each chosen hole is FILLED with the solid of revolution of its own profile (read from the hole's faces:
plain bore, counterbore steps, countersink cones, drill points), the filled faces are merged back into
their neighbours (``ShapeUpgrade_UnifySameDomain``), and the hole is CUT again at its new centre on the
same host face plane with its new radius. Everything else of the solid is left as it was.

Tolerances are the model's own (``cadfeat.cad.tolerance.ModelTolerance``: its size, B-rep tolerances and
the STEP file's uncertainty). A re-drill is judged by what matters: the holes re-extracted at the intended
place and size, a valid B-rep, and a volume change equal to the analytic one within the accuracy of the
volume computation on the changed region — measured as the volume of the Boolean difference between the
solids before and after (a small solid bounded by the hole's own cylinders, cones and planes, which OCCT
integrates exactly), with the B-rep tolerance over the changed surface as the allowance. Not by a 1e-6
relative difference of two whole-solid volumes: on parts with B-spline faces those are off by 1e-6..1e-4
(and OCCT's adaptive integration by more), so putting a hole back unchanged used to fail.

The input file is only read. CadQuery/OCP are imported inside the functions.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.cad.export import check_solid, import_step, mesh_from_shape, shape_volume_mm3
from cadfeat.cad.features import extract_holes
from cadfeat.cad.hole_profiles import HoleProfile, hole_label, hole_profile, revolved
from cadfeat.cad.tolerance import ModelTolerance, step_uncertainty_mm
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    import os

    import cadquery as cq

    from cadfeat.cad.features import Hole, ShapeLike
    from cadfeat.cad.features.extraction import SkippedHole

__all__ = [
    "HoleMove",
    "HoleProfile",
    "StepPart",
    "dry_run",
    "fill_holes",
    "hole_profile",
    "load_step",
    "redrill",
]

STL_TOLERANCE_MM = 0.01
"""Chord tolerance of the exported STL (``export.export_stl``'s default), which the dry run meshes at."""
VOLUME_RTOL_FLOOR = 1e-9
"""Least relative tolerance of a volume change (round-off)."""


# ------------------------------------------------------------------------------------------ STEP parts
@dataclass(frozen=True)
class StepPart:
    """A part read from a STEP file: one solid (mm) and its holes, named ``H1``, ``H2``... in order."""

    name: str
    path: Path
    shape: cq.Solid
    holes: tuple[Hole, ...] = field(repr=False)
    tolerance: ModelTolerance = field(default_factory=ModelTolerance, repr=False)
    skipped: tuple[SkippedHole, ...] = field(default=(), repr=False)

    def select(self, spec: int | str | Sequence[float], tol_mm: float = 0.01) -> Hole:
        """One hole by 1-based index (``2``), name (``"H2"``, ``"2"``) or position.

        A position is a point (3,) in mm (or the string ``"x,y,z"``): the hole whose entrance-rim centre
        is nearest, if it is within ``tol_mm``. Raises ``CadfeatError`` listing the available holes
        otherwise.
        """
        if isinstance(spec, str) and "," in spec:
            try:
                spec = [float(x) for x in spec.split(",")]
            except ValueError:
                raise CadfeatError(f"{self.path}: hole position {spec!r} is not 'x,y,z' in mm; "
                                   f"available holes: {self.describe_holes()}") from None
        if isinstance(spec, int | np.integer | str):
            return self._by_name(spec)
        return self._by_position(np.asarray(spec, dtype=float), tol_mm)

    def describe_holes(self) -> str:
        """``"H1 (x, y, z) r=R mm, H2 ..."``: the holes, for error messages and listings."""
        if not self.holes:
            return "none (the part has no holes)"
        return ", ".join(f"{h.name} ({', '.join(f'{x:.6g}' for x in h.centre)}) r={h.radius_mm:.6g} mm"
                         for h in self.holes)

    def _by_name(self, spec: int | str) -> Hole:
        key = str(spec).strip()
        key = key[1:] if key[:1] in ("H", "h") else key
        if key.isdigit() and 1 <= int(key) <= len(self.holes):
            return self.holes[int(key) - 1]
        raise CadfeatError(f"{self.path}: no hole {spec!r}; available holes: {self.describe_holes()}")

    def _by_position(self, point: np.ndarray, tol_mm: float) -> Hole:
        if point.shape != (3,) or not np.all(np.isfinite(point)):
            raise CadfeatError(f"{self.path}: a hole position must be 3 finite numbers (mm), got {point.tolist()}")
        if not self.holes:
            raise CadfeatError(f"{self.path}: no hole near {point.tolist()}: the part has no holes")
        centres = np.array([h.centre for h in self.holes], dtype=float)
        dist = np.linalg.norm(centres - point, axis=-1)
        best = int(np.argmin(dist))
        if dist[best] > tol_mm:
            raise CadfeatError(f"{self.path}: no hole within {tol_mm:g} mm of {point.tolist()} (nearest "
                               f"{self.holes[best].name} at {dist[best]:.6g} mm); available holes: "
                               f"{self.describe_holes()}")
        return self.holes[best]


    def listing(self) -> list[str]:
        """One line per hole (name, kind, entrance, host face) and per skipped near-round opening (reason),
        for ``cadfeat parts PART.step --holes``."""
        lines = []
        for h in self.holes:
            c = ", ".join(f"{v:.4g}" for v in h.centre)
            a = ", ".join(f"{v:.3g}" for v in h.axis)
            host = "planar" if h.outline is not None else "not planar"
            depth = "through" if h.through else f"blind {h.depth_mm:.4g} mm"
            lines.append(f"{h.name}: {h.kind}, entrance Ø{2 * h.radius_mm:.4g} mm (bore Ø{2 * h.bore_radius_mm:.4g} "
                         f"mm) at ({c}) mm facing ({a}), {depth}, host face {h.host_face} ({host})")
        for s in self.skipped:
            c = ", ".join(f"{v:.4g}" for v in s.centre)
            lines.append(f"skipped: Ø{2 * s.radius_mm:.4g} mm opening on the axis through ({c}) mm: {s.reason}")
        return lines


def load_step(path: str | os.PathLike[str], prefer_direction: Sequence[float] | np.ndarray | None = None) -> StepPart:
    """Read a STEP part: exactly one solid, its holes extracted and named ``H1``, ``H2``... in the
    deterministic order of ``features.extract_holes``, with tolerances scaled to the model (its size, its
    B-rep tolerances and the file's STEP uncertainty). ``prefer_direction`` (the side the camera looks
    from, in the part frame) picks the entrance end of through holes of equal end radii.

    Raises ``CadfeatError`` naming the file if it is missing, not STEP, holds no solid or several solids.
    The file is only read.
    """
    import cadquery as cq

    # lazy: would import OCP, scipy.optimize at module load
    from cadfeat.cad.features.extraction import extract_holes_and_skipped

    path = Path(path)
    shape = import_step(path)
    solids = shape.Solids()
    if len(solids) != 1:
        what = "no solid" if not solids else f"{len(solids)} solids"
        raise CadfeatError(f"{path}: holds {what}; a STEP part must hold exactly one solid")
    solid = cq.Solid(solids[0].wrapped)
    tol = ModelTolerance.of_shape(solid, step_uncertainty_mm(path))
    found, skipped = extract_holes_and_skipped(solid, prefer_direction, tol)
    holes = tuple(dataclasses.replace(h, name=f"H{i + 1}") for i, h in enumerate(found))
    return StepPart(name=path.stem, path=path, shape=solid, holes=holes, tolerance=tol, skipped=tuple(skipped))


# ----------------------------------------------------------------------------------------- re-drilling
@dataclass(frozen=True)
class HoleMove:
    """Re-drill ``hole`` with its entrance-rim centre at ``centre`` (mm, on the same host face plane) and
    visible entrance radius ``radius_mm`` (``HoleProfile.resized``: a counterbore or countersink widens or
    narrows, its screw bore stays; a plain hole scales)."""

    hole: Hole
    centre: np.ndarray
    radius_mm: float

    def __post_init__(self) -> None:
        centre = np.asarray(self.centre, dtype=float)
        if centre.shape != (3,) or not np.all(np.isfinite(centre)):
            raise CadfeatError(f"{hole_label(self.hole)}: new centre must be 3 finite numbers (mm), "
                               f"got {self.centre!r}")
        if not (math.isfinite(self.radius_mm) and self.radius_mm > 0):
            raise CadfeatError(f"{hole_label(self.hole)}: new radius_mm must be > 0, got {self.radius_mm!r}")
        object.__setattr__(self, "centre", centre)
        object.__setattr__(self, "radius_mm", float(self.radius_mm))


def _host_normal(hole: Hole) -> np.ndarray:
    """Outward normal of the hole's host face plane (from its outline, else the hole axis)."""
    outline = getattr(hole, "outline", None)
    if outline is not None:
        n = np.cross(np.asarray(outline.u, float), np.asarray(outline.v, float))
        return n / np.linalg.norm(n)
    return np.asarray(hole.axis, dtype=float)


def _check_on_host_plane(move: HoleMove, tol: ModelTolerance, path: str | os.PathLike[str] | None) -> None:
    offset = float(np.dot(move.centre - np.asarray(move.hole.centre, float), _host_normal(move.hole)))
    if abs(offset) > tol.linear_mm:
        raise CadfeatError(f"{hole_label(move.hole, path)}: new centre {move.centre.tolist()} is {offset:.3g} mm off "
                           f"its host face plane (allowed {tol.linear_mm:.3g} mm)")


def _unify(shape: ShapeLike) -> cq.Shape:
    """Merge same-domain faces and edges (``ShapeUpgrade_UnifySameDomain``), within the model tolerance."""
    import cadquery as cq
    from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain

    unify = ShapeUpgrade_UnifySameDomain(shape.wrapped, True, True, False)
    unify.AllowInternalEdges(False)
    unify.Build()
    return cq.Shape.cast(unify.Shape())


def _single_solid(shape: ShapeLike, what: str) -> cq.Solid:
    import cadquery as cq

    solids = shape.Solids()
    if len(solids) != 1:
        raise CadfeatError(f"{what} gave {len(solids)} solids instead of one")
    return cq.Solid(solids[0].wrapped)


def volume_change_mm3(before: ShapeLike, after: ShapeLike) -> float:
    """Volume ``after`` minus ``before`` (mm³), measured on the changed region only: the volumes of the two
    Boolean differences (material added, material removed), small solids bounded by the changed faces.

    Not used by the re-drilling checks: OCCT's Boolean of two solids that share almost all their faces can
    fail silently (a blind hole whose drill point touches a pocket wall: ``filled.cut(result)`` returned most
    of the part, pinned in tests/test_occt_behaviour.py); those measure against the small hole solids
    (``_material_in``)."""
    return shape_volume_mm3(after.cut(before)) - shape_volume_mm3(before.cut(after))


def _material_in(shape: ShapeLike, tools: Sequence[cq.Solid], tol: ModelTolerance) -> tuple[float, float]:
    """(volume of the union of ``tools``, volume of ``shape``'s material inside it), mm³: Booleans of the
    part with small solids bounded by a hole's own surfaces, which OCCT integrates exactly."""
    union = tools[0].fuse(*tools[1:]) if len(tools) > 1 else tools[0]
    fuzzy = tol.linear_mm if tol.linear_mm > 1e-5 else None
    return shape_volume_mm3(union), shape_volume_mm3(shape.intersect(union, tol=fuzzy))


def _volume_tolerance(profiles: Sequence[HoleProfile], expected: float, tol: ModelTolerance) -> float:
    """What a volume change can be off by on this solid: the B-rep tolerance over the changed surface
    (walls and entrance discs, both sides), plus round-off."""
    surface = sum(p.lateral_area_mm2 + np.pi * float(p.segments[0, 2]) ** 2 for p in profiles)
    return 2.0 * tol.linear_mm * surface + VOLUME_RTOL_FLOOR * abs(expected)


def fill_holes(shape: ShapeLike, holes: Sequence[Hole], tol: ModelTolerance | None = None,
               path: str | os.PathLike[str] | None = None) -> cq.Solid:
    """``shape`` with ``holes`` filled: fused with the solid of revolution of each hole's own profile,
    then same-domain faces unified so the filled host faces merge back into one face.

    Checks that the volume grew by the filled profiles' volume within the accuracy of the volume
    computation on that solid (``_volume_tolerance``).
    """
    tol = tol or ModelTolerance.of_shape(shape)
    return _fill(shape, holes, [hole_profile(shape, h, tol, path) for h in holes], tol, path)


def _fill(shape: ShapeLike, holes: Sequence[Hole], profiles: Sequence[HoleProfile], tol: ModelTolerance,
          path: str | os.PathLike[str] | None) -> cq.Solid:
    """``fill_holes`` with the holes' profiles already read."""
    if not holes:
        return _single_solid(shape, "the part")
    plugs = [revolved(p, np.asarray(h.centre, float), np.asarray(h.axis, float))
             for p, h in zip(profiles, holes, strict=True)]
    filled = _single_solid(_unify(shape.fuse(*plugs, tol=tol.linear_mm if tol.linear_mm > 1e-5 else None)),
                           "filling the holes")
    union, material = _material_in(shape, plugs, tol)
    added = union - material  # the void the plugs filled: they overlap neither each other nor material
    expected = sum(p.volume_mm3 for p in profiles)
    allowed = _volume_tolerance(profiles, expected, tol)
    if abs(added - expected) > allowed:
        raise CadfeatError(f"filling {', '.join(hole_label(h, path) for h in holes)} added {added:.9g} mm^3 instead "
                           f"of the holes' {expected:.9g} mm^3 (allowed ±{allowed:.3g} mm^3 on this solid): the holes "
                           "overlap each other or another feature")
    return filled


def redrill(shape: ShapeLike, moves: Sequence[HoleMove], tol: ModelTolerance | None = None,
            path: str | os.PathLike[str] | None = None, verify: bool = True) -> cq.Solid:
    """Re-drill holes of ``shape``: fill each ``move.hole`` (``fill_holes``), then cut it again at
    ``move.centre`` with entrance radius ``move.radius_mm`` (``HoleProfile.resized``, same axis direction),
    then unify same-domain faces. The rest of the solid is untouched.

    Validates before any CAD work that each new centre lies on its hole's host face plane (within the model
    tolerance ``tol``, default scaled to ``shape``). Afterwards checks that the cut removed the new holes'
    analytic volume within the accuracy of the volume computation on that solid, that through holes still
    come out (the part is as thick at the new centre), that the B-rep is valid (if the input was), and — with
    ``verify`` — that re-extracting the holes finds each new hole at its centre, axis and entrance radius.
    Raises ``CadfeatError`` naming the file (``path``) and the hole otherwise.
    """
    tol = tol or ModelTolerance.of_shape(shape)
    moves = list(moves)
    if not moves:
        return _single_solid(shape, "the part")
    for move in moves:
        _check_on_host_plane(move, tol, path)
    old_profiles = [hole_profile(shape, m.hole, tol, path) for m in moves]
    profiles = []
    for p, m in zip(old_profiles, moves, strict=True):
        try:
            profiles.append(p if abs(m.radius_mm - m.hole.radius_mm) <= 1e-12 else p.resized(m.radius_mm, m.hole.kind))
        except CadfeatError as exc:
            raise CadfeatError(f"{hole_label(m.hole, path)}: {exc}") from None
    filled = _fill(shape, [m.hole for m in moves], old_profiles, tol, path)
    tools = [revolved(p, m.centre, np.asarray(m.hole.axis, float)) for p, m in zip(profiles, moves, strict=True)]
    result = _single_solid(_unify(filled.cut(*tools)), "re-drilling the holes")
    _, removed = _material_in(filled, tools, tol)  # less than the holes' volume if they overlap or break out
    _, left = _material_in(result, tools, tol)  # what the cut left inside the new holes
    expected = sum(p.volume_mm3 for p in profiles)
    allowed = _volume_tolerance(profiles, expected, tol)
    if abs(removed - expected) > allowed or left > allowed:
        raise CadfeatError(f"re-drilling {', '.join(hole_label(m.hole, path) for m in moves)} removed {removed:.9g} "
                           f"mm^3 instead of {expected:.9g} mm^3 (allowed ±{allowed:.3g} mm^3 on this solid): a new "
                           "hole breaks out of the part or overlaps another hole")
    for profile, move in zip(profiles, moves, strict=True):
        if move.hole.through:
            _check_through(filled, move, profile.depth_mm, tol, path)
    if (problems := check_solid(result)) and not check_solid(shape):
        raise CadfeatError(f"re-drilling {', '.join(hole_label(m.hole, path) for m in moves)} gave an invalid solid: "
                           f"{'; '.join(problems[:5])}")
    if verify:
        _verify(result, moves, profiles, tol, path)
    return result


def _verify(result: cq.Solid, moves: Sequence[HoleMove], profiles: Sequence[HoleProfile], tol: ModelTolerance,
            path: str | os.PathLike[str] | None) -> None:
    """Each new hole is found again by extraction at its centre, axis and entrance radius (a through hole may
    be found from its other end: on the same axis line, with its exit radius)."""
    found = extract_holes(result, tol=tol)
    centres = np.array([h.centre for h in found]).reshape(-1, 3)
    axes = np.array([h.axis for h in found]).reshape(-1, 3)
    radii = np.array([h.radius_mm for h in found])
    near = max(1e-3, 10 * tol.linear_mm)
    for move, profile in zip(moves, profiles, strict=True):
        axis = np.asarray(move.hole.axis, float)
        radius, exit_radius = float(profile.segments[0, 2]), float(profile.segments[-1, 3])
        parallel = np.linalg.norm(np.cross(axes, axis), axis=-1) <= 10 * tol.angular_rad
        same = parallel & (np.linalg.norm(centres - move.centre, axis=-1) <= near) & (np.abs(radii - radius) <= near)
        if move.hole.through:
            off_line = np.linalg.norm(np.cross(centres - move.centre, axis), axis=-1)
            same |= parallel & (off_line <= near) & (axes @ axis < 0) & (np.abs(radii - exit_radius) <= near)
        if not same.any():
            raise CadfeatError(f"{hole_label(move.hole, path)}: after re-drilling, extraction finds no hole of "
                               f"entrance radius {radius:.6g} mm at {move.centre.tolist()} (it merged with another "
                               "feature or lost its rim)")


def _check_through(filled: cq.Solid, move: HoleMove, depth_mm: float, tol: ModelTolerance,
                   path: str | os.PathLike[str] | None) -> None:
    """A through hole must still exit at ``depth_mm``: material just above the exit, none just below."""
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.gp import gp_Pnt
    from OCP.TopAbs import TopAbs_IN, TopAbs_OUT

    axis = np.asarray(move.hole.axis, float)
    eps = min(max(1e-3, 10 * tol.linear_mm), 0.25 * depth_mm)
    states = []
    for depth in (depth_mm - eps, depth_mm + eps):
        p = move.centre - depth * axis
        classifier = BRepClass3d_SolidClassifier(filled.wrapped, gp_Pnt(*p), min(1e-7, 0.1 * tol.linear_mm))
        states.append(classifier.State())
    if states != [TopAbs_IN, TopAbs_OUT]:
        raise CadfeatError(f"{hole_label(move.hole, path)}: the part is not {depth_mm:.6g} mm thick at the new centre "
                           f"{move.centre.tolist()}, so the through hole would not come out there")


# ------------------------------------------------------------------------------------------- dry run
def dry_run(part: StepPart, holes: Sequence[Hole], resize: Sequence[bool] | None = None) -> None:
    """Before optimising: re-drill each of ``holes`` of ``part`` (filled, then cut again) moved by a small
    step in its host plane (1 % of its radius, at least 10× the model tolerance) — and, where ``resize``,
    with its entrance 2 % wider — so that a part that cannot be re-drilled is refused at once.

    Each re-drilled solid is also meshed as the run's STL export will mesh it, and written to STEP and checked
    as the run's export is (``_step_round_trip``). Raises ``CadfeatError`` naming the file, the hole and why (e.g.
    its wall is cut by another feature, a face cannot be triangulated, the re-read STEP differs).
    """
    resize = list(resize) if resize is not None else [False] * len(holes)
    originals: dict[str, float] = {}  # the original's STEP written and re-read once for all the holes
    for hole, grow in zip(holes, resize, strict=True):
        step = max(0.01 * hole.radius_mm, 10 * part.tolerance.linear_mm)
        if hole.outline is not None:
            u = np.asarray(hole.outline.u, float)
        else:
            helper = np.eye(3)[int(np.argmin(np.abs(hole.axis)))]
            u = np.cross(hole.axis, helper)
            u /= np.linalg.norm(u)
        move = HoleMove(hole, np.asarray(hole.centre, float) + step * u, hole.radius_mm * (1.02 if grow else 1.0))
        try:
            result = redrill(part.shape, [move], part.tolerance, part.path)
            mesh_from_shape(result, tolerance=STL_TOLERANCE_MM)  # the run exports the re-drilled part as STL
            _step_round_trip(part, result, originals)  # and as STEP, re-read and checked
        except CadfeatError as exc:
            text = str(exc)
            where = f"{part.path}: "
            raise CadfeatError(f"{where}hole {hole.name} cannot be re-drilled (dry run: moved {step:.3g} mm"
                               f"{', entrance 2 % wider' if grow else ''}): "
                               f"{text[len(where):] if text.startswith(where) else text}") from None


def _step_round_trip(part: StepPart, result: cq.Solid, originals: dict[str, float]) -> None:
    """Write the re-drilled ``result`` as STEP and check the re-read file as a run's export does
    (``export.verify_step_roundtrip``: holes to 1e-6 mm, the volume against the re-read original's plus the change,
    ``export.expected_step_volume``), so that a part whose export cannot be verified is refused now. ``originals``
    caches the re-read original's volume (``"volume"``) between the holes of one dry run."""
    import tempfile

    from cadfeat.cad.export import export_step, import_step, verify_step_roundtrip

    with tempfile.TemporaryDirectory(prefix="cadfeat-dry-run-") as tmp:
        if "volume" not in originals:
            export_step(part.shape, Path(tmp) / "original.step")
            originals["volume"] = shape_volume_mm3(import_step(Path(tmp) / "original.step"))
        reread, v0 = originals["volume"], shape_volume_mm3(part.shape)
        redrilled = Path(tmp) / "optimised.step"
        export_step(result, redrilled)
        # as export.expected_step_volume, with the re-read original's volume kept
        verify_step_roundtrip(redrilled, extract_holes(result), tol_mm=1e-6,  # study.verify.ROUNDTRIP_TOL_MM
                              expected_volume_mm3=reread + shape_volume_mm3(result) - v0, volume_rtol=1e-7,
                              volume_uncertainty_mm3=abs(reread - v0))
