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

import ast
import copy
import dataclasses
import math
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from cadfeat.design.objectives import ObjectiveConfig
from cadfeat.design.optimize import OptimizerConfig
from cadfeat.errors import CadfeatError

__all__ = [
    "AGGREGATES",
    "COMBINES",
    "MEASURES",
    "METHODS",
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

MEASURES = ("fov", "focus", "resolution", "resolvability")
AGGREGATES = ("sum", "mean", "min", "smoothmin")
COMBINES = ("weighted", "maxmin", "constraint", "pareto")
METHODS = ("multistart", "local", "global", "pareto")
LOCAL_SOLVERS = ("SLSQP", "trust-constr")
SYMMETRIES = ("none", "x", "y", "xy")
NORMALISATIONS = ("payoff", "initial", "natural", "none")
SCORES = ("movable", "all")
FOV_MEASURES = ("cone", "image")
#: The keys of ``[objective]`` and ``[optimizer]``: the fields of ``ObjectiveConfig`` / ``OptimizerConfig``
#: a study file may set (the others keep their defaults).
OBJECTIVE_KEYS = ("measures", "aggregate", "combine", "weights", "thresholds", "min_axis_px", "rotation_length_mm",
                  "smoothmin_beta", "normalisation", "fov_measure", "occlusion", "score")
OPTIMIZER_KEYS = ("method", "starts", "maxiter", "seed", "local_solver", "snap_standard_sizes")
SCRIPT_SUFFIXES = (".py",)
STEP_SUFFIXES = (".step", ".stp")

SECTIONS = ("study", "camera", "part_pose", "trajectory", "design", "constraints", "objective", "optimizer", "shop",
            "robustness", "tracking")
SHOP_KEYS = ("hole_sizes", "grid_mm", "keep_patterns")
ROBUSTNESS_KEYS = ("position_tol_mm", "size_steps", "camera_position_mm", "camera_angle_deg", "samples")
REQUIRED_SECTIONS = ("study", "camera", "trajectory", "design")
LIMITS = {
    "trajectory_samples": 100_000,   # [trajectory] n (and the rows of a trajectory CSV)
    "trajectory_lines": 10_000,      # [trajectory] lines (raster_scan)
    "trajectory_csv_bytes": 64 * 2**20,
    "design_variables": 64,          # [design] parameters / movable holes
    "optimizer_starts": 10_000,      # [optimizer] starts
    "optimizer_maxiter": 1_000_000,  # [optimizer] maxiter
    "image_pixels": 50_000_000,      # [camera] width * height
    "image_side_px": 20_000,         # [camera] width, height
}
"""Size limits checked when a study is validated, before anything is allocated (each error names its limit).
They bound memory and time on an ordinary machine; for a bigger study, raise them here
(``cadfeat.study.schema.LIMITS[key] = value`` before ``load_study``)."""
BUILD_TIMEOUT_S = 60.0
"""Default ``[study] build_timeout_s``: time limit of one part-script import or CAD build (worker process)."""

_MISSING: Any = object()
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


class StudyError(CadfeatError):
    """A study file is invalid: the message names the file, the dotted key and what is allowed."""


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
class PartParameter:
    """A part script's parameter as declared in its ``PARAMETERS`` table."""

    name: str
    default: float | int
    lower: float | int
    upper: float | int
    unit: str
    description: str
    is_int: bool


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


@dataclass(frozen=True)
class ConstraintSpec:
    """``[constraints]``: the kept mechanical requirements (mm; percent of the original volume)."""

    edge_distance_mm: float = 1.0
    ligament_mm: float = 1.0
    volume_change_max_percent: float | None = None
    symmetry: str = "none"


TRACKING_ESTIMATORS = ("ekf", "iekf", "pnp")
#: The keys of ``[tracking]`` (the fields of ``TrackingSpec``).
TRACKING_KEYS = ("estimators", "runs", "seed", "noise_grey", "defocus", "exposure_s", "initial_error_mm",
                 "initial_error_deg", "r_px2", "q_rate_mm2_s2", "q_omega_rad2_s2", "iterations", "tau", "frame_step",
                 "settle_frames", "converged_mm", "converged_deg", "gate_px", "rim_model", "alpha",
                 "min_change_percent")


@dataclass(frozen=True)
class TrackingSpec:
    """``[tracking]``: the closed-loop check of ``cadfeat track`` (``cadfeat.vision.closed_loop.TrackingConfig``).

    Estimators, Monte-Carlo runs and seed; sensor: grey-level noise σ (0..255 scale), thin-lens defocus on/off,
    exposure (s, 0 = no motion blur); initial pose error (mm, deg); filter tuning (thesis §6.3.3): R = r I (px²),
    Q = diag(0, q, …) on the linear (mm²/s²) and angular (rad²/s²) rates, IEKF iterations n and threshold τ;
    every ``frame_step``-th trajectory sample; statistics after ``settle_frames``; convergence bounds;
    association gate (px); rim ellipse-centre model; significance ``alpha`` of the paired test, and the smallest
    change of the median RMS error (percent of the error before) that a verdict counts.
    """

    estimators: tuple[str, ...] = TRACKING_ESTIMATORS
    runs: int = 20
    seed: int = 0
    noise_grey: float = 2.0
    defocus: bool = True
    exposure_s: float = 0.0
    initial_error_mm: float = 10.0
    initial_error_deg: float = 2.0
    r_px2: float = 0.25
    q_rate_mm2_s2: float = 100.0
    q_omega_rad2_s2: float = 1e-3
    iterations: int = 30
    tau: float = 1e-16
    frame_step: int = 1
    settle_frames: int = 5
    converged_mm: float = 2.0
    converged_deg: float = 1.0
    gate_px: float = 10.0
    rim_model: bool = True
    alpha: float = 0.05
    min_change_percent: float = 5.0


@dataclass(frozen=True)
class ShopSpec:
    """``[shop]``: shop-ready output (``cadfeat.design.shop``). ``hole_sizes``: a table name of
    ``shop.HOLE_SIZE_TABLES`` or diameters (mm); ``grid_mm``: drawing grid of moved hole positions (0: off);
    ``keep_patterns``: holes forming a pattern in the original move as a pattern (false lets them break)."""

    hole_sizes: str | tuple[float, ...] = "iso273-medium"
    grid_mm: float = 0.1
    keep_patterns: bool = True


@dataclass(frozen=True)
class RobustnessSpec:
    """``[robustness]``: tolerances of the robustness study (``cadfeat.design.robustness``): hole positions
    ±``position_tol_mm``, diameters ±``size_steps`` table steps, camera mount ±``camera_position_mm`` and
    ±``camera_angle_deg``; ``samples`` random draws each (0: off)."""

    position_tol_mm: float = 0.1
    size_steps: int = 1
    camera_position_mm: float = 2.0
    camera_angle_deg: float = 1.0
    samples: int = 200


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
        _check_seed(seed, self.label, "seed")
        data = copy.deepcopy(dict(self.data))
        data["study"]["seed"] = int(seed)
        data["optimizer"]["seed"] = int(seed)
        return dataclasses.replace(self, study=dataclasses.replace(self.study, seed=int(seed)),
                                   optimizer=dataclasses.replace(self.optimizer, seed=int(seed)), data=data)


# ------------------------------------------------------------------------------------------- validator
def _check_seed(seed: Any, label: str, key: str) -> None:
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= int(seed) < 2**32:
        raise StudyError(f"{label}: {key}: {seed!r} is not allowed; allowed: an integer in [0, 2^32)")


def _fmt(value: Any) -> str:
    return repr(value) if isinstance(value, str) else str(value)


class _Table:
    """Reads one TOML table, checking each key; ``done()`` rejects keys that were not read."""

    def __init__(self, data: Any, key: str, label: str, allowed: Sequence[str]) -> None:
        self.key, self.label, self.allowed = key, label, tuple(allowed)
        if not isinstance(data, Mapping):
            self.fail(key, f"expected a table, got {_fmt(data)}", f"a table with keys {', '.join(allowed)}")
        self.data = dict(data)
        unknown = sorted(set(self.data) - set(allowed))
        if unknown:
            self.fail(self.dotted(unknown[0]), "unknown key", f"keys of [{key}]: {', '.join(allowed)}")

    def dotted(self, name: str) -> str:
        return f"{self.key}.{name}" if self.key else name

    def fail(self, key: str, problem: str, allowed: str) -> NoReturn:
        raise StudyError(f"{self.label}: {key}: {problem}; allowed: {allowed}")

    def has(self, name: str) -> bool:
        return name in self.data

    def raw(self, name: str, default: Any = None) -> Any:
        return self.data.get(name, default)

    def string(self, name: str, default: Any = _MISSING, choices: Sequence[str] | None = None,
               pattern: re.Pattern[str] | None = None, what: str = "a string") -> str:
        allowed = ", ".join(choices) if choices else what
        if name not in self.data:
            if default is _MISSING:
                self.fail(self.dotted(name), "missing", allowed)
            return default
        value = self.data[name]
        if not isinstance(value, str) or (choices is not None and value not in choices) or \
                (pattern is not None and not pattern.fullmatch(value)):
            self.fail(self.dotted(name), f"{_fmt(value)} is not allowed", allowed)
        return value

    def number(self, name: str, default: float | None, lo: float | None = None, hi: float | None = None,
               lo_open: bool = False, required: bool = False) -> float | None:
        if name not in self.data:
            if required:
                self.fail(self.dotted(name), "missing", _range_text(lo, hi, lo_open))
            return default
        return _number(self.data[name], self.dotted(name), self.label, lo, hi, lo_open)

    def integer(self, name: str, default: int, lo: int, hi: int | None = None) -> int:
        if name not in self.data:
            return default
        value = self.data[name]
        text = f"an integer ≥ {lo}" if hi is None else f"an integer in [{lo}, {hi}]"
        if isinstance(value, bool) or not isinstance(value, int) or value < lo or (hi is not None and value > hi):
            self.fail(self.dotted(name), f"{_fmt(value)} is not allowed", text)
        return int(value)

    def boolean(self, name: str, default: bool) -> bool:
        if name not in self.data:
            return default
        value = self.data[name]
        if not isinstance(value, bool):
            self.fail(self.dotted(name), f"{_fmt(value)} is not allowed", "true or false")
        return value

    def vector(self, name: str, n: int, default: Sequence[float] | None) -> tuple[float, ...] | None:
        if name not in self.data:
            return None if default is None else tuple(float(x) for x in default)
        return _vector(self.data[name], n, self.dotted(name), self.label)


def _range_text(lo: float | None, hi: float | None, lo_open: bool = False) -> str:
    if lo is None and hi is None:
        return "a finite number"
    if hi is None:
        return f"a number {'>' if lo_open else '≥'} {lo:g}"
    if lo is None:
        return f"a number ≤ {hi:g}"
    return f"a number in {'(' if lo_open else '['}{lo:g}, {hi:g}]"


def _is_num(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _number(value: Any, key: str, label: str, lo: float | None = None, hi: float | None = None,
            lo_open: bool = False) -> float:
    ok = _is_num(value) and math.isfinite(value)
    if ok and lo is not None:
        ok = value > lo if lo_open else value >= lo
    if ok and hi is not None:
        ok = value <= hi
    if not ok:
        raise StudyError(f"{label}: {key}: {_fmt(value)} is not allowed; allowed: {_range_text(lo, hi, lo_open)}")
    return float(value)


def _vector(value: Any, n: int, key: str, label: str) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != n or not all(_is_num(v) and math.isfinite(v) for v in value):
        raise StudyError(f"{label}: {key}: {_fmt(value)} is not allowed; allowed: a list of {n} finite numbers")
    return tuple(float(v) for v in value)


# ------------------------------------------------------------------------------------ part parameters
def part_parameters(path: str | Path) -> dict[str, PartParameter]:
    """A part script's ``PARAMETERS`` (name → ``PartParameter``), read without running the script when the
    table is a literal (``ast.literal_eval``), else via ``cadfeat.cad.parts.load_part``.

    Raises ``StudyError`` naming the script for a syntax error, a missing or malformed table.
    """
    path = Path(path)
    try:
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    except SyntaxError as exc:
        raise StudyError(f"{path}: line {exc.lineno}: syntax error: {exc.msg}") from exc
    node = next((n.value for n in tree.body if isinstance(n, ast.Assign | ast.AnnAssign)
                 and any(isinstance(t, ast.Name) and t.id == "PARAMETERS"
                         for t in (n.targets if isinstance(n, ast.Assign) else [n.target]))), None)
    if node is None and _is_cqgi(path):
        return _parameters_by_loading(path)  # a cq-editor / CQGI script: its constants (cadfeat.cad.cqgi_parts)
    if node is None:
        raise StudyError(f"{path}: PARAMETERS: missing; allowed: a module-level dict "
                         "{name: {default, bounds, unit, description}}")
    if _mutated(tree):
        return _parameters_by_loading(path)
    try:
        table = ast.literal_eval(node)
    except ValueError:
        return _parameters_by_loading(path)
    return _parse_parameters(table, path)


_MUTATORS = {"update", "setdefault", "pop", "popitem", "clear", "__setitem__"}


def _is_cqgi(path: Path) -> bool:
    from cadfeat.cad.cqgi_parts import is_cqgi_script

    return is_cqgi_script(path)


def _mutated(tree: ast.Module) -> bool:
    """Whether module-level code (outside functions/classes) changes ``PARAMETERS`` after assigning it:
    ``PARAMETERS[k] = ...``, ``del PARAMETERS[k]``, ``PARAMETERS.update(...)``, or a second assignment."""
    assigned = 0
    for stmt in tree.body:
        if isinstance(stmt, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            continue
        for n in ast.walk(stmt):
            if isinstance(n, ast.Name) and n.id == "PARAMETERS" and isinstance(n.ctx, ast.Store):
                assigned += 1
            elif isinstance(n, ast.Subscript) and isinstance(n.value, ast.Name) and n.value.id == "PARAMETERS" \
                    and isinstance(n.ctx, ast.Store | ast.Del):
                return True
            elif isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name) and n.value.id == "PARAMETERS" \
                    and n.attr in _MUTATORS:
                return True
    return assigned > 1


def _parameters_by_loading(path: Path) -> dict[str, PartParameter]:
    from cadfeat.cad.parts import load_part  # runs the script (imports cadquery): only for non-literal tables

    part = load_part(path)
    return {name: PartParameter(name, p.default, p.lower, p.upper, getattr(p, "unit", ""),
                                getattr(p, "description", ""), bool(getattr(p, "is_int", False)))
            for name, p in part.parameters.items()}


def _parse_parameters(table: Any, path: Path) -> dict[str, PartParameter]:
    allowed = "a dict {name: {default, bounds: (lower, upper), unit, description}}"
    if not isinstance(table, Mapping):
        raise StudyError(f"{path}: PARAMETERS: not a dict; allowed: {allowed}")
    out = {}
    for name, spec in table.items():
        if not isinstance(name, str) or not isinstance(spec, Mapping) or "default" not in spec or \
                "bounds" not in spec or not isinstance(spec["bounds"], Sequence) or len(spec["bounds"]) != 2:
            raise StudyError(f"{path}: PARAMETERS.{name}: malformed; allowed: {allowed}")
        default, (lo, hi) = spec["default"], spec["bounds"]
        if not all(_is_num(v) for v in (default, lo, hi)):
            raise StudyError(f"{path}: PARAMETERS.{name}: default and bounds must be numbers; allowed: {allowed}")
        is_int = isinstance(default, int)
        out[name] = PartParameter(name, default, lo, hi, str(spec.get("unit", "")),
                                  str(spec.get("description", "")), is_int)
    return out


# ------------------------------------------------------------------------------------------- sections
def _study_section(t: _Table, base_dir: Path) -> StudyInfo:
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


def _check_step_header(t: _Table, path: Path) -> None:
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


def _check_size(t: _Table, key: str, value: Any, limit: str, what: str) -> None:
    """``value`` (an int) must not exceed ``LIMITS[limit]`` (checked before anything is allocated)."""
    if isinstance(value, int) and not isinstance(value, bool) and value > LIMITS[limit]:
        t.fail(key, f"{value} {what} is more than the limit of {LIMITS[limit]:,}",
               f"at most {LIMITS[limit]:,} (cadfeat.study.schema.LIMITS[{limit!r}])")


def _camera_section(data: Any, label: str, base_dir: Path) -> tuple[CameraSpec, dict[str, Any]]:
    from cadfeat.camera import Camera, camera_from_dict

    fields = [f.name for f in dataclasses.fields(Camera)]
    t = _Table(data, "camera", label, ["preset", "calibration", *fields])
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
            t.fail("camera.calibration", f"{_fmt(cal)} is not allowed", "a path to an OpenCV calibration file")
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


def _pose_section(t: _Table) -> PartPose:
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
    t = _Table(data, "trajectory", label, list(data))
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
        return _vector(value, 3, key, label)  # type: ignore[return-value]
    raise StudyError(f"{label}: {key}: {_fmt(value)} is not allowed; allowed: a 1-based hole index, a hole "
                     "name (\"H2\") or a position [x, y, z] in mm")


def _selectors(value: Any, key: str, label: str) -> tuple[Selector, ...]:
    if not isinstance(value, list):
        raise StudyError(f"{label}: {key}: {_fmt(value)} is not allowed; allowed: a list of hole selectors "
                         "(index, name or [x, y, z])")
    return tuple(_selector(v, f"{key}[{i}]", label) for i, v in enumerate(value))


def _design_section(t: _Table, info: StudyInfo, label: str) -> tuple[DesignSpec, dict[str, PartParameter],
                                                                     dict[str, Any]]:
    echo: dict[str, Any] = {}
    params: dict[str, PartParameter] = {}
    specs: tuple[ParameterSpec, ...] = ()
    holes: tuple[HoleSpec, ...] = ()
    if info.part_kind == "script":
        if t.has("holes"):
            t.fail("design.holes", "only for STEP parts (script parts vary their parameters)", "design.parameters")
        from cadfeat.cad.parts import build_time_limit

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
        if not isinstance(value, list) or not value or not all(_is_num(v) and v > 0 and math.isfinite(v)
                                                               for v in value):
            t.fail("design.standard_diameters_mm", f"{_fmt(value)} is not allowed",
                   "a non-empty list of positive diameters in mm")
        std = tuple(sorted(float(v) for v in value))
    fixed = _selectors(t.raw("fixed", []), "design.fixed", label)
    patterns_raw = t.raw("patterns", [])
    if not isinstance(patterns_raw, list):
        t.fail("design.patterns", f"{_fmt(patterns_raw)} is not allowed", "a list of lists of hole selectors")
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
        view = _vector(t.raw("view_direction"), 3, "design.view_direction", label)
        norm = math.sqrt(sum(v * v for v in view))
        if norm == 0:
            t.fail("design.view_direction", "[0, 0, 0] is not allowed", "a non-zero direction [x, y, z]")
        view = tuple(v / norm for v in view)
        echo["view_direction"] = list(view)
    echo.update({"standard_diameters_mm": None if std is None else list(std),
                 "fixed": [list(s) if isinstance(s, tuple) else s for s in fixed],
                 "patterns": [[list(s) if isinstance(s, tuple) else s for s in p] for p in patterns]})
    return DesignSpec(specs, holes, std, fixed, patterns, view), params, echo


def _parameter_specs(t: _Table, params: Mapping[str, PartParameter], label: str,
                     info: StudyInfo) -> tuple[ParameterSpec, ...]:
    raw = t.raw("parameters")
    names_allowed = ", ".join(params) or "(the part has no parameters)"
    if raw is None:
        t.fail("design.parameters", "missing", f"a list or table of parameter names of {info.part}: "
               f"{names_allowed}")
    if isinstance(raw, list):
        if not all(isinstance(n, str) for n in raw):
            t.fail("design.parameters", f"{_fmt(raw)} is not allowed", f"parameter names: {names_allowed}")
        table: dict[str, Any] = {n: {} for n in raw}
        if len(table) != len(raw):
            t.fail("design.parameters", "a parameter is listed twice", f"distinct names of {names_allowed}")
    elif isinstance(raw, Mapping):
        table = dict(raw)
    else:
        t.fail("design.parameters", f"{_fmt(raw)} is not allowed",
               "a list of names or a table name = {lower, upper, standard_sizes}")
    if not table:
        t.fail("design.parameters", "empty", f"at least one of {names_allowed}")
    out = []
    for name, spec in table.items():
        key = f"design.parameters.{name}"
        if name not in params:
            raise StudyError(f"{label}: {key}: unknown parameter of {info.part}; allowed: {names_allowed}")
        p = params[name]
        st = _Table(spec, key, label, ["lower", "upper", "standard_sizes", "start"])
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
            if not isinstance(v, list) or not v or not all(_is_num(s) and lo <= s <= hi for s in v):
                st.fail(f"{key}.standard_sizes", f"{_fmt(v)} is not allowed",
                        f"a non-empty list of values in [{lo}, {hi}]")
            sizes = tuple(sorted(float(s) for s in v))
        start = st.number("start", None, float(lo), float(hi))
        if start is not None and p.is_int:
            if float(start) != round(float(start)):
                st.fail(f"{key}.start", f"{start!r} is not an integer", f"an integer in [{lo}, {hi}]")
            start = int(round(start))
        out.append(ParameterSpec(name, lo, hi, p.default, p.unit, p.is_int, sizes, start))
    return tuple(out)


def _hole_specs(t: _Table, label: str) -> tuple[HoleSpec, ...]:
    raw = t.raw("holes")
    if not isinstance(raw, list) or not raw:
        t.fail("design.holes", "missing or empty" if raw is None or raw == [] else f"{_fmt(raw)} is not allowed",
               "a list of tables {select = index | name | [x, y, z], move, resize, max_offset_mm}")
    out = []
    for i, spec in enumerate(raw):
        key = f"design.holes[{i}]"
        ht = _Table(spec, key, label, ["select", "move", "resize", "max_offset_mm"])
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


def _check_step_design(t: _Table, holes: Sequence[HoleSpec], fixed: Sequence[Selector]) -> None:
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


def _constraints_section(t: _Table) -> ConstraintSpec:
    return ConstraintSpec(
        edge_distance_mm=t.number("edge_distance_mm", 1.0, 0.0),
        ligament_mm=t.number("ligament_mm", 1.0, 0.0),
        volume_change_max_percent=t.number("volume_change_max_percent", None, 0.0, 100.0, lo_open=True),
        symmetry=t.string("symmetry", "none", SYMMETRIES),
    )


def _shop_section(t: _Table) -> ShopSpec:
    from cadfeat.design.shop import HOLE_SIZE_TABLES, hole_sizes

    raw = t.raw("hole_sizes", "iso273-medium")
    allowed = f"one of {', '.join(HOLE_SIZE_TABLES)} or a list of diameters > 0 (mm)"
    if isinstance(raw, str):
        sizes: str | tuple[float, ...] = t.string("hole_sizes", "iso273-medium", tuple(HOLE_SIZE_TABLES))
    elif isinstance(raw, list | tuple) and raw and all(_is_num(v) and v > 0 for v in raw):
        sizes = hole_sizes(raw)
    else:
        t.fail("shop.hole_sizes", f"{_fmt(raw)} is not allowed", allowed)
    return ShopSpec(hole_sizes=sizes, grid_mm=t.number("grid_mm", 0.1, 0.0, 10.0),
                    keep_patterns=t.boolean("keep_patterns", True))


def _robustness_section(t: _Table) -> RobustnessSpec:
    return RobustnessSpec(position_tol_mm=t.number("position_tol_mm", 0.1, 0.0, 10.0),
                          size_steps=t.integer("size_steps", 1, 0, 5),
                          camera_position_mm=t.number("camera_position_mm", 2.0, 0.0, 100.0),
                          camera_angle_deg=t.number("camera_angle_deg", 1.0, 0.0, 30.0),
                          samples=t.integer("samples", 200, 0, 10000))


def _objective_section(t: _Table) -> ObjectiveConfig:
    measures = t.raw("measures", list(MEASURES))
    if not isinstance(measures, list) or not measures or not all(isinstance(m, str) and m in MEASURES
                                                                 for m in measures) \
            or len(set(measures)) != len(measures):
        t.fail("objective.measures", f"{_fmt(measures)} is not allowed",
               f"a non-empty list of distinct names from {', '.join(MEASURES)}")
    aggregate = t.string("aggregate", "sum", AGGREGATES)
    combine = t.string("combine", "maxmin", COMBINES)
    weights = _measure_table(t, "weights", measures, lo=0.0)
    thresholds = _measure_table(t, "thresholds", measures, lo=None)
    if combine == "weighted" and weights and not any(w > 0 for w in weights.values()):
        t.fail("objective.weights", "all weights are zero", "non-negative weights, at least one positive")
    if combine == "constraint":
        if not thresholds:
            t.fail("objective.thresholds", "missing (combine = \"constraint\" makes these measures hard "
                   "constraints)", f"a table measure = minimum value, measures from {', '.join(measures)}")
        if set(thresholds) == set(measures):
            t.fail("objective.thresholds", "every measure is a constraint, none is left to optimise",
                   "thresholds for some of the measures, not all")
    elif thresholds:
        t.fail("objective.thresholds", f"only used with combine = \"constraint\" (combine is {combine!r})",
               "remove it, or combine = \"constraint\"")
    return ObjectiveConfig(
        measures=tuple(measures), aggregate=aggregate, combine=combine, weights=weights, thresholds=thresholds,
        min_axis_px=t.number("min_axis_px", 5.0, 0.0, lo_open=True),
        rotation_length_mm=t.number("rotation_length_mm", 1.0, 0.0, lo_open=True),
        smoothmin_beta=t.number("smoothmin_beta", 20.0, 0.0, lo_open=True),
        normalisation=t.string("normalisation", "payoff", NORMALISATIONS),
        fov_measure=t.string("fov_measure", "cone", FOV_MEASURES),
        occlusion=t.boolean("occlusion", True),
        score=_score(t),
    )


def _score(t: _Table) -> str | tuple[str, ...]:
    """``objective.score``: which holes' FOV/focus/resolution are scored — "movable" (default: the holes
    the design moves; all when none moves), "all", or a list of hole names (checked against the part later)."""
    raw = t.raw("score", "movable")
    if isinstance(raw, str) and raw in SCORES:
        return raw
    if isinstance(raw, list) and raw and all(isinstance(x, str) and x for x in raw) and len(set(raw)) == len(raw):
        return tuple(raw)
    t.fail("objective.score", f"{_fmt(raw)} is not allowed",
           '"movable", "all" or a non-empty list of distinct hole names (e.g. ["H1", "H3"])')


def _measure_table(t: _Table, name: str, measures: Sequence[str], lo: float | None) -> dict[str, float]:
    raw = t.raw(name, {})
    key = f"objective.{name}"
    if not isinstance(raw, Mapping):
        t.fail(key, f"{_fmt(raw)} is not allowed", f"a table measure = number, measures from {', '.join(measures)}")
    out = {}
    for m, v in raw.items():
        if m not in measures:
            t.fail(f"{key}.{m}", "not one of objective.measures", ", ".join(measures))
        out[m] = _number(v, f"{key}.{m}", t.label, lo)
    return dict(sorted(out.items()))


def _optimizer_section(t: _Table, seed: int) -> OptimizerConfig:
    return OptimizerConfig(
        method=t.string("method", "multistart", METHODS),
        starts=t.integer("starts", 8, 1, LIMITS["optimizer_starts"]),
        maxiter=t.integer("maxiter", 100, 1, LIMITS["optimizer_maxiter"]),
        seed=t.integer("seed", seed, 0, 2**32 - 1),
        local_solver=t.string("local_solver", "SLSQP", LOCAL_SOLVERS),
        snap_standard_sizes=t.boolean("snap_standard_sizes", True),
    )


def _tracking_section(t: _Table, seed: int) -> TrackingSpec:
    estimators = t.raw("estimators", list(TRACKING_ESTIMATORS))
    if not isinstance(estimators, list) or not estimators or len(set(map(str, estimators))) != len(estimators) or \
            not all(isinstance(e, str) and e in TRACKING_ESTIMATORS for e in estimators):
        t.fail("tracking.estimators", f"{_fmt(estimators)} is not allowed",
               f"a non-empty list of distinct names from {', '.join(TRACKING_ESTIMATORS)}")
    return TrackingSpec(
        estimators=tuple(estimators), runs=t.integer("runs", 20, 1, 10_000), seed=t.integer("seed", seed, 0, 2**32 - 1),
        noise_grey=t.number("noise_grey", 2.0, 0.0, 100.0), defocus=t.boolean("defocus", True),
        exposure_s=t.number("exposure_s", 0.0, 0.0, 1.0),
        initial_error_mm=t.number("initial_error_mm", 10.0, 0.0, 10_000.0),
        initial_error_deg=t.number("initial_error_deg", 2.0, 0.0, 180.0),
        r_px2=t.number("r_px2", 0.25, 0.0, lo_open=True), q_rate_mm2_s2=t.number("q_rate_mm2_s2", 100.0, 0.0),
        q_omega_rad2_s2=t.number("q_omega_rad2_s2", 1e-3, 0.0), iterations=t.integer("iterations", 30, 1, 1000),
        tau=t.number("tau", 1e-16, 0.0), frame_step=t.integer("frame_step", 1, 1),
        settle_frames=t.integer("settle_frames", 5, 0), converged_mm=t.number("converged_mm", 2.0, 0.0, lo_open=True),
        converged_deg=t.number("converged_deg", 1.0, 0.0, lo_open=True),
        gate_px=t.number("gate_px", 10.0, 0.0, lo_open=True), rim_model=t.boolean("rim_model", True),
        alpha=t.number("alpha", 0.05, 0.0, 0.5, lo_open=True),
        min_change_percent=t.number("min_change_percent", 5.0, 0.0, 100.0),
    )


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
    top = _Table(data, "", label, SECTIONS)
    for section in REQUIRED_SECTIONS:
        if section not in data:
            raise StudyError(f"{label}: [{section}]: missing section; required sections: "
                             f"{', '.join(REQUIRED_SECTIONS)}; optional: "
                             f"{', '.join(s for s in SECTIONS if s not in REQUIRED_SECTIONS)}")
    st = _Table(top.raw("study"), "study", label, ["name", "part", "seed", "description", "build_timeout_s"])
    info = _study_section(st, base)
    camera, camera_echo = _camera_section(top.raw("camera"), label, base)
    pose = _pose_section(_Table(top.raw("part_pose", {}), "part_pose", label,
                                ["position_mm", "rotvec_deg", "quaternion"]))
    trajectory = _trajectory_section(top.raw("trajectory"), label, base)
    design, params, design_echo = _design_section(
        _Table(top.raw("design"), "design", label,
               ["parameters", "holes", "standard_diameters_mm", "fixed", "patterns", "view_direction"]), info, label)
    constraints = _constraints_section(_Table(top.raw("constraints", {}), "constraints", label,
                                              ["edge_distance_mm", "ligament_mm", "volume_change_max_percent",
                                               "symmetry"]))
    objective = _objective_section(_Table(top.raw("objective", {}), "objective", label, list(OBJECTIVE_KEYS)))
    optimizer = _optimizer_section(_Table(top.raw("optimizer", {}), "optimizer", label, list(OPTIMIZER_KEYS)),
                                   info.seed)
    shop = _shop_section(_Table(top.raw("shop", {}), "shop", label, list(SHOP_KEYS)))
    robustness = _robustness_section(_Table(top.raw("robustness", {}), "robustness", label, list(ROBUSTNESS_KEYS)))
    if objective.combine == "pareto" and optimizer.method != "pareto":
        raise StudyError(f"{label}: optimizer.method: {optimizer.method!r} cannot give a Pareto front "
                         "(objective.combine = \"pareto\"); allowed: pareto")
    if optimizer.method == "pareto" and objective.combine != "pareto":
        raise StudyError(f"{label}: objective.combine: {objective.combine!r} with optimizer.method = \"pareto\"; "
                         "allowed: pareto")
    tracking = None
    if "tracking" in data:
        tracking = _tracking_section(_Table(top.raw("tracking"), "tracking", label, TRACKING_KEYS), info.seed)
    echo = {
        "study": {"name": info.name, "part": info.part, "seed": info.seed,
                  "description": info.description, "build_timeout_s": info.build_timeout_s},
        "camera": camera_echo,
        "part_pose": {"position_mm": list(pose.position_mm), "rotvec_deg": list(pose.rotvec_deg)},
        "trajectory": copy.deepcopy(dict(trajectory.table)),
        "design": design_echo,
        "constraints": _asdict(constraints),
        "objective": {**_asdict(objective, OBJECTIVE_KEYS), "measures": list(objective.measures),
                      "weights": dict(objective.weights), "thresholds": dict(objective.thresholds)},
        "optimizer": _asdict(optimizer, OPTIMIZER_KEYS),
        "shop": {**_asdict(shop), "hole_sizes": shop.hole_sizes if isinstance(shop.hole_sizes, str)
                 else list(shop.hole_sizes)},
        "robustness": _asdict(robustness),
    }
    if tracking is not None:
        echo["tracking"] = {**_asdict(tracking), "estimators": list(tracking.estimators)}
    return StudyConfig(path, base, info, camera, pose, trajectory, design, constraints, objective, optimizer,
                       params, _drop_none(echo), shop=shop, robustness=robustness, tracking=tracking)


def _drop_none(value: Any) -> Any:
    """Plain data without None entries (TOML has no null): the echo can be loaded again."""
    if isinstance(value, Mapping):
        return {k: _drop_none(v) for k, v in value.items() if v is not None}
    if isinstance(value, list | tuple):
        return [_drop_none(v) for v in value]
    return value


def _asdict(obj: Any, keys: Sequence[str] | None = None) -> dict[str, Any]:
    """The fields of a dataclass (only ``keys``, the ones a study file can set, when given)."""
    names = [f.name for f in dataclasses.fields(obj)] if keys is None else keys
    return {k: getattr(obj, k) for k in names}
