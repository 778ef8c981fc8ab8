"""Study files: the TOML format, its validation, and the frozen ``StudyConfig`` it becomes.

A study says which part to redesign, with which camera moving along which trajectory, what may change,
what must be kept, what to optimise and how (README, "Study files", has a full annotated example)::

    [study]        name, part (script .py or .step/.stp, relative to the study file), seed, description
    [camera]       preset = "dalsa-cad1-128a" | explicit fx fy cx cy width height dist + optics |
                   calibration = "file.yaml" (OpenCV FileStorage) — plus optional overrides
    [part_pose]    position_mm = [x, y, z], rotvec_deg = [rx, ry, rz] | quaternion = [x, y, z, w]
                   (the part frame in the task frame: T_task_part)
    [trajectory]   kind = "orbit_arc" + its arguments, or csv = "poses.csv"  (``cadfeat trajectories``)
    [design]       script parts: parameters = ["d", ...] or [design.parameters] d = {lower, upper}
                   STEP parts: holes = [{select = 2 | "H2" | [x, y, z], move, resize, max_offset_mm}]
                               (move/resize per hole), view_direction = [x, y, z] (towards the camera)
                   both: standard_diameters_mm, fixed = [selectors], patterns = [[selectors], ...]
    [constraints]  edge_distance_mm, ligament_mm, volume_change_max_percent, symmetry
    [objective]    measures, aggregate, combine, weights, thresholds, min_axis_px, rotation_length_mm,
                   smoothmin_beta, normalisation (payoff | initial | natural | none), fov_measure (cone | image)
    [optimizer]    method, starts, maxiter, seed, local_solver, snap_standard_sizes
    [tracking]     optional closed-loop check (``cadfeat track``, cadfeat.vision): ``TRACKING_KEYS``

Everything is checked before any work is done (``load_study``): unknown sections and keys, types, ranges,
enumerations, that files exist, that design parameters exist in the part script and that their bounds lie
inside the part's own bounds. The first problem raises one ``StudyError`` naming the file, the dotted key
(``objective.aggregate``) and what is allowed. Integer part parameters stay ``int`` throughout.

Reading a part script's ``PARAMETERS`` is cheap: the script is parsed (``ast``), not executed, when the
table is a literal; otherwise ``cadfeat.cad.parts.load_part`` is used.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cadfeat.design.objectives import AGGREGATES, COMBINES, ObjectiveConfig
from cadfeat.design.objectives import MEASURES as _OBJECTIVE_MEASURES
from cadfeat.design.optimize import METHODS, OptimizerConfig
from cadfeat.errors import CadfeatError
from cadfeat.study.part_parameters import PartParameter, part_parameters
from cadfeat.study.settings import (
    LIMITS,
    SYMMETRIES,
    TRACKING_ESTIMATORS,
    ConstraintSettings,
    ObjectiveSettings,
    OptimizerSettings,
    RobustnessSettings,
    ShopSettings,
    StudyError,
    TrackingSettings,
    validate_section,
)
from cadfeat.study.table import Table, check_seed, fmt, is_num, vector_value

__all__ = [
    "AGGREGATES",
    "COMBINES",
    "MEASURES",
    "METHODS",
    "SYMMETRIES",
    "TRACKING_ESTIMATORS",
    "TRACKING_KEYS",
    "CameraSpec",
    "ConstraintSpec",
    "DesignSpec",
    "HoleSpec",
    "ParameterSpec",
    "PartParameter",
    "PartPose",
    "StudyConfig",
    "StudyError",
    "StudyInfo",
    "TrackingSpec",
    "TrajectorySpec",
    "load_study",
    "part_parameters",
]

MEASURES = tuple(_OBJECTIVE_MEASURES)
"""The measure names of ``[objective] measures`` (the design layer's ``MEASURES``; enumerations are not copied)."""
#: The keys of ``[objective]`` and ``[optimizer]``: the fields of ``ObjectiveConfig`` / ``OptimizerConfig``
#: a study file may set (the others keep their defaults).
OBJECTIVE_KEYS = ObjectiveSettings.study_keys()
OPTIMIZER_KEYS = OptimizerSettings.study_keys()
STUDY_KEYS = ("name", "part", "seed", "description", "build_timeout_s")
PART_POSE_KEYS = ("position_mm", "rotvec_deg", "quaternion")
DESIGN_KEYS = ("parameters", "holes", "standard_diameters_mm", "fixed", "patterns", "view_direction")
SCRIPT_SUFFIXES = (".py",)
STEP_SUFFIXES = (".step", ".stp")

SECTIONS = ("study", "camera", "part_pose", "trajectory", "design", "constraints", "objective", "optimizer", "shop",
            "robustness", "tracking")
SHOP_KEYS = tuple(ShopSettings.model_fields)
ROBUSTNESS_KEYS = tuple(RobustnessSettings.model_fields)
REQUIRED_SECTIONS = ("study", "camera", "trajectory", "design")
BUILD_TIMEOUT_S = 60.0
"""Default ``[study] build_timeout_s``: time limit of one part-script import or CAD build (worker process)."""

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


# ----------------------------------------------------------------------------------------- dataclasses
@dataclass(frozen=True)
class StudyInfo:
    """``[study]``: ``part`` as written (relative to the study file), ``part_path`` resolved."""

    name: str
    part: str
    part_path: Path
    part_kind: str          # "script" | "step"
    seed: int
    description: str
    build_timeout_s: float = BUILD_TIMEOUT_S


@dataclass(frozen=True)
class CameraSpec:
    """``[camera]``: the validated table (calibration path resolved); ``build()`` gives the ``Camera``."""

    table: Mapping[str, Any]
    origin: str

    def build(self) -> Any:
        from cadfeat.camera import camera_from_dict

        return camera_from_dict(dict(copy.deepcopy(dict(self.table))), self.origin)


@dataclass(frozen=True)
class PartPose:
    """``[part_pose]``: the part frame in the task frame (mm; rotation as a rotation vector in degrees)."""

    position_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotvec_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def T_task_part(self) -> np.ndarray:
        """4x4 transform mapping part coordinates to task coordinates."""
        from scipy.spatial.transform import Rotation

        T = np.eye(4)
        T[:3, :3] = Rotation.from_rotvec(np.radians(self.rotvec_deg)).as_matrix()
        T[:3, 3] = self.position_mm
        return T


@dataclass(frozen=True)
class TrajectorySpec:
    """``[trajectory]``: the validated table; ``build()`` gives the ``Trajectory`` (T_task_cam)."""

    table: Mapping[str, Any]
    origin: str
    base_dir: Path

    def build(self) -> Any:
        from cadfeat.trajectory import trajectory_from_dict

        return trajectory_from_dict(copy.deepcopy(dict(self.table)), self.origin, self.base_dir)


@dataclass(frozen=True)
class ParameterSpec:
    """A varying part parameter with its study bounds (``int`` bounds for integer parameters)."""

    name: str
    lower: float | int
    upper: float | int
    default: float | int
    unit: str
    is_int: bool
    standard_sizes: tuple[float, ...] | None = None
    start: float | int | None = None
    """The design the study starts from (``evaluate`` scores it, ``run`` starts the optimiser there); None:
    the part's default."""


@dataclass(frozen=True)
class HoleSpec:
    """A movable STEP hole: ``select`` is a 1-based index, a name ("H2") or a position (x, y, z) in mm."""

    select: int | str | tuple[float, float, float]
    move: bool = True
    resize: bool = False
    max_offset_mm: float | None = None


Selector = int | str | tuple[float, float, float]


@dataclass(frozen=True)
class DesignSpec:
    """``[design]``: what may change."""

    parameters: tuple[ParameterSpec, ...] = ()
    holes: tuple[HoleSpec, ...] = ()
    standard_diameters_mm: tuple[float, ...] | None = None
    fixed: tuple[Selector, ...] = ()
    patterns: tuple[tuple[Selector, ...], ...] = ()
    view_direction: tuple[float, float, float] | None = None
    """STEP parts: unit direction (part frame) from the part towards the camera; picks the entrance end of
    through holes. Default: from the trajectory (mean direction to the camera positions)."""


ConstraintSpec = ConstraintSettings
"""``[constraints]`` (``cadfeat.study.settings``)."""


#: The keys of ``[tracking]`` (the fields of ``TrackingSettings``).
TRACKING_KEYS = tuple(TrackingSettings.model_fields)
TrackingSpec = TrackingSettings
ShopSpec = ShopSettings
RobustnessSpec = RobustnessSettings
"""The ``[tracking]``, ``[shop]`` and ``[robustness]`` sections (``cadfeat.study.settings``): the old names."""


@dataclass(frozen=True)
class StudyConfig:
    """A validated study. ``file`` is None for a study given as a dict; ``base_dir`` resolves paths."""

    file: Path | None
    base_dir: Path
    study: StudyInfo
    camera: CameraSpec
    part_pose: PartPose
    trajectory: TrajectorySpec
    design: DesignSpec
    constraints: ConstraintSpec
    objective: ObjectiveConfig
    optimizer: OptimizerConfig
    part_params: Mapping[str, PartParameter] = field(default_factory=dict, repr=False)
    data: Mapping[str, Any] = field(default_factory=dict, repr=False)
    shop: ShopSpec = field(default_factory=ShopSpec)
    robustness: RobustnessSpec = field(default_factory=RobustnessSpec)
    tracking: TrackingSpec | None = None

    @property
    def label(self) -> str:
        return str(self.file) if self.file is not None else "<study dict>"

    def to_dict(self) -> dict[str, Any]:
        """The validated study as plain data (defaults filled in, None left out), for echoing into results.json;
        ``load_study(config.to_dict(), base_dir=config.base_dir)`` gives the same study."""
        return copy.deepcopy(dict(self.data))

    def with_seed(self, seed: int) -> StudyConfig:
        """The same study with ``study.seed`` and ``optimizer.seed`` replaced."""
        check_seed(seed, self.label, "seed")
        data = copy.deepcopy(dict(self.data))
        data["study"]["seed"] = int(seed)
        data["optimizer"]["seed"] = int(seed)
        return dataclasses.replace(self, study=dataclasses.replace(self.study, seed=int(seed)),
                                   optimizer=self.optimizer.replace(seed=int(seed)), data=data)


# ------------------------------------------------------------------------------------------- sections
def _study_section(t: Table, base_dir: Path) -> StudyInfo:
    name = t.string("name", pattern=_NAME, what="a name of letters, digits, '_', '-', '.' (a folder name)")
    part = t.string("part", what="a part script (.py) or STEP file (.step, .stp), relative to the study file")
    suffix = Path(part).suffix.lower()
    if suffix in SCRIPT_SUFFIXES:
        kind = "script"
    elif suffix in STEP_SUFFIXES:
        kind = "step"
    else:
        t.fail("study.part", f"{part!r} is neither a part script nor a STEP file",
               "a path ending in .py, .step or .stp")
    path = (base_dir / part).resolve()
    if not path.is_file():
        shown = base_dir / part if (base_dir / part).is_symlink() else path
        problem = f"{shown} is not a regular file ({path}: a device, folder or pipe)" if path.exists() else \
            f"file {path} does not exist"
        t.fail("study.part", problem, "an existing part script or STEP file")
    if kind == "step":
        _check_step_header(t, path)
    seed = t.integer("seed", 0, 0, 2**32 - 1)
    description = t.string("description", default="")
    timeout = t.number("build_timeout_s", BUILD_TIMEOUT_S, 0.0, 86_400.0, lo_open=True)
    return StudyInfo(name, part, path, kind, seed, description, float(timeout))


def _check_step_header(t: Table, path: Path) -> None:
    """A STEP file is readable and starts like one (``ISO-10303-21;`` header, ``HEADER;`` section)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError as exc:
        t.fail("study.part", f"{path} cannot be read ({exc.strerror})", "a readable STEP file")
    text = head.lstrip(b"\xef\xbb\xbf \t\r\n")
    if not text.startswith(b"ISO-10303-21") or b"HEADER" not in head:
        what = "is empty" if not head else "does not start with the STEP header 'ISO-10303-21;'"
        t.fail("study.part", f"{path} {what}", "a STEP file (ISO 10303-21 text, as CAD programs export)")


def _check_size(t: Table, key: str, value: Any, limit: str, what: str) -> None:
    """``value`` (an int) must not exceed ``LIMITS[limit]`` (checked before anything is allocated)."""
    if isinstance(value, int) and not isinstance(value, bool) and value > LIMITS[limit]:
        t.fail(key, f"{value} {what} is more than the limit of {LIMITS[limit]:,}",
               f"at most {LIMITS[limit]:,} (cadfeat.study.schema.LIMITS[{limit!r}])")


def _camera_section(data: Any, label: str, base_dir: Path) -> tuple[CameraSpec, dict[str, Any]]:
    from cadfeat.camera import Camera, camera_from_dict

    fields = [f.name for f in dataclasses.fields(Camera)]
    t = Table(data, "camera", label, ["preset", "calibration", *fields])
    table = dict(t.data)
    for side in ("width", "height"):
        _check_size(t, f"camera.{side}", table.get(side), "image_side_px", "pixels")
    if all(isinstance(table.get(k), int) for k in ("width", "height")):
        _check_size(t, "camera.width * camera.height", table["width"] * table["height"], "image_pixels", "pixels")
    if t.has("preset") and t.has("calibration"):
        t.fail("camera.calibration", "given together with camera.preset", "one of preset or calibration")
    if t.has("calibration"):
        cal = table["calibration"]
        if not isinstance(cal, str):
            t.fail("camera.calibration", f"{fmt(cal)} is not allowed", "a path to an OpenCV calibration file")
        path = (base_dir / cal).resolve()
        if not path.is_file():
            t.fail("camera.calibration", f"file {path} does not exist", "an existing OpenCV calibration file")
        table["calibration"] = str(path)
    origin = f"{label}: camera"
    try:
        camera_from_dict(copy.deepcopy(table), origin)
    except CadfeatError as exc:
        raise StudyError(str(exc)) from exc
    except Exception as exc:  # noqa: BLE001 — a bad calibration file may raise anything from OpenCV
        raise StudyError(f"{origin}: {exc}") from exc
    echo = dict(t.data)
    return CameraSpec(table, origin), echo


def _pose_section(t: Table) -> PartPose:
    position = t.vector("position_mm", 3, (0.0, 0.0, 0.0))
    if t.has("rotvec_deg") and t.has("quaternion"):
        t.fail("part_pose.quaternion", "given together with part_pose.rotvec_deg", "one of rotvec_deg or quaternion")
    if t.has("quaternion"):
        from scipy.spatial.transform import Rotation

        q = np.array(t.vector("quaternion", 4, None))
        if abs(np.linalg.norm(q) - 1.0) > 1e-3:
            t.fail("part_pose.quaternion", f"norm {np.linalg.norm(q):.6g} is not 1",
                   "a unit quaternion [x, y, z, w] (scalar last)")
        rotvec = tuple(float(v) for v in np.degrees(Rotation.from_quat(q / np.linalg.norm(q)).as_rotvec()))
    else:
        rotvec = t.vector("rotvec_deg", 3, (0.0, 0.0, 0.0))
    return PartPose(position, rotvec)


def _trajectory_section(data: Any, label: str, base_dir: Path) -> TrajectorySpec:
    if not isinstance(data, Mapping):
        raise StudyError(f"{label}: trajectory: expected a table; allowed: kind = <library kind> + arguments, "
                         "or csv = <file>")
    t = Table(data, "trajectory", label, list(data))
    _check_size(t, "trajectory.n", data.get("n"), "trajectory_samples", "samples")
    _check_size(t, "trajectory.lines", data.get("lines"), "trajectory_lines", "lines")
    if isinstance(data.get("csv"), str):
        csv = base_dir / data["csv"]
        if csv.is_file() and csv.stat().st_size > LIMITS["trajectory_csv_bytes"]:
            t.fail("trajectory.csv", f"{csv} has {csv.stat().st_size:,} bytes, more than the limit of "
                   f"{LIMITS['trajectory_csv_bytes']:,}", "a smaller CSV (cadfeat.study.schema.LIMITS"
                   "['trajectory_csv_bytes'])")
        if csv.exists() and not csv.is_file():
            t.fail("trajectory.csv", f"{csv} is not a regular file (a device, folder or pipe)", "a CSV file of poses")
    spec = TrajectorySpec(dict(data), f"{label}: trajectory", base_dir)
    try:
        spec.build()
    except CadfeatError as exc:
        raise StudyError(str(exc)) from exc
    return spec


def _selector(value: Any, key: str, label: str) -> Selector:
    if isinstance(value, int) and not isinstance(value, bool):
        if value < 1:
            raise StudyError(f"{label}: {key}: {value} is not allowed; allowed: a 1-based hole index ≥ 1, "
                             "a hole name (\"H2\") or a position [x, y, z] in mm")
        return value
    if isinstance(value, str) and value.strip():
        return value
    if isinstance(value, list):
        return vector_value(value, 3, key, label)  # type: ignore[return-value]
    raise StudyError(f"{label}: {key}: {fmt(value)} is not allowed; allowed: a 1-based hole index, a hole "
                     "name (\"H2\") or a position [x, y, z] in mm")


def _selectors(value: Any, key: str, label: str) -> tuple[Selector, ...]:
    if not isinstance(value, list):
        raise StudyError(f"{label}: {key}: {fmt(value)} is not allowed; allowed: a list of hole selectors "
                         "(index, name or [x, y, z])")
    return tuple(_selector(v, f"{key}[{i}]", label) for i, v in enumerate(value))


def _design_section(t: Table, info: StudyInfo, label: str) -> tuple[DesignSpec, dict[str, PartParameter],
                                                                     dict[str, Any]]:
    echo: dict[str, Any] = {}
    params: dict[str, PartParameter] = {}
    specs: tuple[ParameterSpec, ...] = ()
    holes: tuple[HoleSpec, ...] = ()
    if info.part_kind == "script":
        if t.has("holes"):
            t.fail("design.holes", "only for STEP parts (script parts vary their parameters)", "design.parameters")
        from cadfeat.cad.sandbox import build_time_limit

        with build_time_limit(info.build_timeout_s, start=False):  # (the script runs only for a computed table)
            params = part_parameters(info.part_path)
        raw = t.raw("parameters")
        _check_size(t, "design.parameters", len(raw) if isinstance(raw, list | dict) else None, "design_variables",
                    "parameters")
        specs = _parameter_specs(t, params, label, info)
        echo["parameters"] = {p.name: {"lower": p.lower, "upper": p.upper,
                                       **({"standard_sizes": list(p.standard_sizes)} if p.standard_sizes else {}),
                                       **({"start": p.start} if p.start is not None else {})}
                              for p in specs}
    else:
        if t.has("parameters"):
            t.fail("design.parameters", "only for part scripts (STEP parts have no parameters)", "design.holes")
        raw = t.raw("holes")
        _check_size(t, "design.holes", len(raw) if isinstance(raw, list) else None, "design_variables", "holes")
        holes = _hole_specs(t, label)
        echo["holes"] = [{"select": list(h.select) if isinstance(h.select, tuple) else h.select, "move": h.move,
                          "resize": h.resize, "max_offset_mm": h.max_offset_mm} for h in holes]
    std = None
    if t.has("standard_diameters_mm") and info.part_kind == "script":
        t.fail("design.standard_diameters_mm", "only for STEP parts (a script part's sizes are its parameters)",
               "design.parameters.<name>.standard_sizes")
    if t.has("standard_diameters_mm"):
        value = t.raw("standard_diameters_mm")
        if not isinstance(value, list) or not value or not all(is_num(v) and v > 0 and math.isfinite(v)
                                                               for v in value):
            t.fail("design.standard_diameters_mm", f"{fmt(value)} is not allowed",
                   "a non-empty list of positive diameters in mm")
        std = tuple(sorted(float(v) for v in value))
    fixed = _selectors(t.raw("fixed", []), "design.fixed", label)
    patterns_raw = t.raw("patterns", [])
    if not isinstance(patterns_raw, list):
        t.fail("design.patterns", f"{fmt(patterns_raw)} is not allowed", "a list of lists of hole selectors")
    patterns = tuple(_selectors(p, f"design.patterns[{i}]", label) for i, p in enumerate(patterns_raw))
    for i, p in enumerate(patterns):
        if len(p) < 2:
            t.fail(f"design.patterns[{i}]", "a pattern needs at least two holes", "a list of ≥ 2 hole selectors")
    if info.part_kind == "step":
        _check_step_design(t, holes, fixed)
    view = None
    if t.has("view_direction"):
        if info.part_kind != "step":
            t.fail("design.view_direction", "only for STEP parts (a part script gives VIEW_DIRECTION)",
                   "VIEW_DIRECTION in the part script")
        view = vector_value(t.raw("view_direction"), 3, "design.view_direction", label)
        norm = math.sqrt(sum(v * v for v in view))
        if norm == 0:
            t.fail("design.view_direction", "[0, 0, 0] is not allowed", "a non-zero direction [x, y, z]")
        view = tuple(v / norm for v in view)
        echo["view_direction"] = list(view)
    echo.update({"standard_diameters_mm": None if std is None else list(std),
                 "fixed": [list(s) if isinstance(s, tuple) else s for s in fixed],
                 "patterns": [[list(s) if isinstance(s, tuple) else s for s in p] for p in patterns]})
    return DesignSpec(specs, holes, std, fixed, patterns, view), params, echo


def _parameter_specs(t: Table, params: Mapping[str, PartParameter], label: str,
                     info: StudyInfo) -> tuple[ParameterSpec, ...]:
    raw = t.raw("parameters")
    names_allowed = ", ".join(params) or "(the part has no parameters)"
    if raw is None:
        t.fail("design.parameters", "missing", f"a list or table of parameter names of {info.part}: "
               f"{names_allowed}")
    if isinstance(raw, list):
        if not all(isinstance(n, str) for n in raw):
            t.fail("design.parameters", f"{fmt(raw)} is not allowed", f"parameter names: {names_allowed}")
        table: dict[str, Any] = {n: {} for n in raw}
        if len(table) != len(raw):
            t.fail("design.parameters", "a parameter is listed twice", f"distinct names of {names_allowed}")
    elif isinstance(raw, Mapping):
        table = dict(raw)
    else:
        t.fail("design.parameters", f"{fmt(raw)} is not allowed",
               "a list of names or a table name = {lower, upper, standard_sizes}")
    if not table:
        t.fail("design.parameters", "empty", f"at least one of {names_allowed}")
    out = []
    for name, spec in table.items():
        key = f"design.parameters.{name}"
        if name not in params:
            raise StudyError(f"{label}: {key}: unknown parameter of {info.part}; allowed: {names_allowed}")
        p = params[name]
        st = Table(spec, key, label, ["lower", "upper", "standard_sizes", "start"])
        lo = st.number("lower", p.lower, float(p.lower), float(p.upper))
        hi = st.number("upper", p.upper, float(p.lower), float(p.upper))
        if not (math.isfinite(lo) and math.isfinite(hi)):  # a CQGI constant without a bounds comment
            st.fail(key, f"{name} has no bounds in {info.part}", "lower and upper here (or a '# [lower, upper] "
                    "unit' comment on the constant's line in the script)")
        if p.is_int:
            for which, v in (("lower", lo), ("upper", hi)):
                if float(v) != round(float(v)):
                    st.fail(f"{key}.{which}", f"{v!r} is not an integer", f"an integer in [{p.lower}, {p.upper}] "
                            f"({name} is an integer parameter)")
            lo, hi = int(round(lo)), int(round(hi))
        if not lo < hi:
            st.fail(key, f"lower {lo} is not below upper {hi}", f"lower < upper within [{p.lower}, {p.upper}]")
        sizes = None
        if st.has("standard_sizes"):
            v = st.raw("standard_sizes")
            if not isinstance(v, list) or not v or not all(is_num(s) and lo <= s <= hi for s in v):
                st.fail(f"{key}.standard_sizes", f"{fmt(v)} is not allowed",
                        f"a non-empty list of values in [{lo}, {hi}]")
            sizes = tuple(sorted(float(s) for s in v))
        start = st.number("start", None, float(lo), float(hi))
        if start is not None and p.is_int:
            if float(start) != round(float(start)):
                st.fail(f"{key}.start", f"{start!r} is not an integer", f"an integer in [{lo}, {hi}]")
            start = int(round(start))
        out.append(ParameterSpec(name, lo, hi, p.default, p.unit, p.is_int, sizes, start))
    return tuple(out)


def _hole_specs(t: Table, label: str) -> tuple[HoleSpec, ...]:
    raw = t.raw("holes")
    if not isinstance(raw, list) or not raw:
        t.fail("design.holes", "missing or empty" if raw is None or raw == [] else f"{fmt(raw)} is not allowed",
               "a list of tables {select = index | name | [x, y, z], move, resize, max_offset_mm}")
    out = []
    for i, spec in enumerate(raw):
        key = f"design.holes[{i}]"
        ht = Table(spec, key, label, ["select", "move", "resize", "max_offset_mm"])
        if not ht.has("select"):
            ht.fail(f"{key}.select", "missing", "a 1-based hole index, a hole name (\"H2\") or a position [x, y, z]")
        select = _selector(ht.raw("select"), f"{key}.select", label)
        move = ht.boolean("move", True)
        resize = ht.boolean("resize", False)
        offset = ht.number("max_offset_mm", None, 0.0, None, lo_open=True)
        if not (move or resize):
            ht.fail(key, "neither move nor resize is true", "move = true and/or resize = true")
        out.append(HoleSpec(select, move, resize, offset))
    return tuple(out)


def _check_step_design(t: Table, holes: Sequence[HoleSpec], fixed: Sequence[Selector]) -> None:
    seen = {}
    for i, h in enumerate(holes):
        if h.select in seen:
            t.fail(f"design.holes[{i}].select", f"hole {h.select!r} is already design.holes[{seen[h.select]}]",
                   "each hole once")
        seen[h.select] = i
    for i, s in enumerate(fixed):
        if s in seen:
            t.fail(f"design.fixed[{i}]", f"hole {s!r} is also movable (design.holes[{seen[s]}])",
                   "fixed holes that are not in design.holes")


# ------------------------------------------------------------------------------------------- entry point
def _read(path_or_dict: Any, base_dir: str | Path | None) -> tuple[dict[str, Any], Path | None, Path, str]:
    if isinstance(path_or_dict, Mapping):
        base = Path(base_dir) if base_dir is not None else Path.cwd()
        return copy.deepcopy(dict(path_or_dict)), None, base.resolve(), "<study dict>"
    if not isinstance(path_or_dict, str | Path):
        raise StudyError(f"study: expected a TOML file path or a dict, got {type(path_or_dict).__name__}")
    path = Path(path_or_dict)
    label = str(path)
    if not path.is_file():
        raise StudyError(f"{label}: study file does not exist; allowed: a path to a .toml study file")
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise StudyError(f"{label}: not valid TOML: {exc}; allowed: a TOML study file (see README, "
                         "\"Study files\")") from exc
    except UnicodeDecodeError as exc:
        raise StudyError(f"{label}: not a UTF-8 text file; allowed: a TOML study file") from exc
    return data, path, (Path(base_dir) if base_dir is not None else path.parent).resolve(), label


def load_study(path_or_dict: Any, base_dir: str | Path | None = None) -> StudyConfig:
    """Read and validate a study (a TOML path, or a dict with the same tables) — before any work.

    Relative paths are resolved against the study file's folder (for a dict: ``base_dir`` or the current
    folder). Raises ``StudyError`` naming the file, the dotted key and the allowed values.
    """
    data, path, base, label = _read(path_or_dict, base_dir)
    top = Table(data, "", label, SECTIONS)
    for section in REQUIRED_SECTIONS:
        if section not in data:
            raise StudyError(f"{label}: [{section}]: missing section; required sections: "
                             f"{', '.join(REQUIRED_SECTIONS)}; optional: "
                             f"{', '.join(s for s in SECTIONS if s not in REQUIRED_SECTIONS)}")
    st = Table(top.raw("study"), "study", label, STUDY_KEYS)
    info = _study_section(st, base)
    camera, camera_echo = _camera_section(top.raw("camera"), label, base)
    pose = _pose_section(Table(top.raw("part_pose", {}), "part_pose", label, PART_POSE_KEYS))
    trajectory = _trajectory_section(top.raw("trajectory"), label, base)
    design, params, design_echo = _design_section(
        Table(top.raw("design"), "design", label, DESIGN_KEYS), info, label)
    constraints = validate_section(ConstraintSettings, top.raw("constraints", {}), "constraints", label)
    objective = validate_section(ObjectiveSettings, top.raw("objective", {}), "objective", label)
    optimizer = validate_section(OptimizerSettings, top.raw("optimizer", {}), "optimizer", label,
                                 {"seed": info.seed, "limits": LIMITS})
    shop = validate_section(ShopSettings, top.raw("shop", {}), "shop", label)
    robustness = validate_section(RobustnessSettings, top.raw("robustness", {}), "robustness", label)
    if objective.combine == "pareto" and optimizer.method != "pareto":
        raise StudyError(f"{label}: optimizer.method: {optimizer.method!r} cannot give a Pareto front "
                         "(objective.combine = \"pareto\"); allowed: pareto")
    if optimizer.method == "pareto" and objective.combine != "pareto":
        raise StudyError(f"{label}: objective.combine: {objective.combine!r} with optimizer.method = \"pareto\"; "
                         "allowed: pareto")
    tracking = None
    if "tracking" in data:
        tracking = validate_section(TrackingSettings, top.raw("tracking"), "tracking", label, {"seed": info.seed})
    echo = {
        "study": {"name": info.name, "part": info.part, "seed": info.seed,
                  "description": info.description, "build_timeout_s": info.build_timeout_s},
        "camera": camera_echo,
        "part_pose": {"position_mm": list(pose.position_mm), "rotvec_deg": list(pose.rotvec_deg)},
        "trajectory": copy.deepcopy(dict(trajectory.table)),
        "design": design_echo,
        "constraints": constraints.model_dump(mode="json"),
        "objective": objective.study_dump(),
        "optimizer": optimizer.study_dump(),
        "shop": shop.model_dump(mode="json"),
        "robustness": robustness.model_dump(mode="json"),
    }
    if tracking is not None:
        echo["tracking"] = tracking.model_dump(mode="json")
    return StudyConfig(path, base, info, camera, pose, trajectory, design, constraints, objective, optimizer,
                       params, _drop_none(echo), shop=shop, robustness=robustness, tracking=tracking)


def _drop_none(value: Any) -> Any:
    """Plain data without None entries (TOML has no null): the echo can be loaded again."""
    if isinstance(value, Mapping):
        return {k: _drop_none(v) for k, v in value.items() if v is not None}
    if isinstance(value, list | tuple):
        return [_drop_none(v) for v in value]
    return value
