"""Study files: the TOML format, its validation, and the frozen ``StudyConfig`` it becomes.

A study says which part to redesign, with which camera moving along which trajectory, what may change,
what must be kept, what to optimise and how (docs/guide/study-files.md has a full annotated example)::

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
    [robustness]   the robust objective and its draws; path and shop tolerances
    [tracking]     optional closed-loop check (``cadfeat track``, cadfeat.vision): ``TRACKING_KEYS``
    [add_targets]  optional new target holes (``cadfeat.study.added_targets``): faces, keepout_boxes, the drill
                   (diameter_mm, depth_mm, chamfer_mm), max_added, target_error_mm, min_gain_percent, pitch_mm
    [cell]         the robot cell, declared once (``cadfeat.cell.Cell``): camera mount and part placement
                   tolerances (± bounds), sensor noise and light gain (σ), the detector and its gate, hole ends

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
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, cast, overload

from cadfeat.cell import Cell
from cadfeat.design.objectives import AGGREGATES, COMBINES, ObjectiveConfig
from cadfeat.design.objectives import MEASURES as _OBJECTIVE_MEASURES
from cadfeat.design.optimize import METHODS, OptimizerConfig
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
from cadfeat.study.settings.add_targets import AddTargetsSettings
from cadfeat.study.settings.camera import CameraSettings
from cadfeat.study.settings.design import DesignSpec, HoleSpec, ParameterSpec, Selector
from cadfeat.study.settings.scene import (
    PartPose,
    StudyInfo,
)
from cadfeat.study.table import Table, check_seed
from cadfeat.trajectory import TrajectorySettings, validate_trajectory

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import JsonDict

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
    "Selector",
    "StudyConfig",
    "StudyError",
    "StudyInfo",
    "StudySource",
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
STUDY_KEYS = StudyInfo.study_keys()
PART_POSE_KEYS = PartPose.study_keys()
DESIGN_KEYS = DesignSpec.study_keys()

StudySource = str | Path | Mapping[str, object]
"""A study: a TOML file's path, or a dict with the same tables."""

SECTIONS = ("study", "camera", "part_pose", "trajectory", "design", "constraints", "objective", "optimizer", "shop",
            "robustness", "tracking", "cell", "add_targets")
SHOP_KEYS = tuple(ShopSettings.model_fields)
ROBUSTNESS_KEYS = tuple(RobustnessSettings.model_fields)
REQUIRED_SECTIONS = ("study", "camera", "trajectory", "design")

# ----------------------------------------------------------------------------------------- dataclasses
CameraSpec = CameraSettings
TrajectorySpec = TrajectorySettings
"""``[camera]`` (``cadfeat.study.settings.camera``) and ``[trajectory]`` (``cadfeat.trajectory``): ``build()`` gives
the ``Camera`` / the ``Trajectory``."""
ConstraintSpec = ConstraintSettings
"""``[constraints]`` (``cadfeat.study.settings``)."""


#: The keys of ``[tracking]`` (the study keys of ``TrackingSettings``: its cell is the study's ``[cell]``).
TRACKING_KEYS = TrackingSettings.study_keys()
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
    part_params: Mapping[str, PartParameter] = field(default_factory=dict[str, PartParameter], repr=False)
    data: Mapping[str, object] = field(default_factory=dict[str, object], repr=False)
    shop: ShopSpec = field(default_factory=ShopSpec)
    robustness: RobustnessSpec = field(default_factory=RobustnessSpec)
    tracking: TrackingSpec | None = None
    cell: Cell = field(default_factory=Cell)
    """``[cell]``: the robot cell, declared once (``cadfeat.cell``)."""
    add_targets: AddTargetsSettings | None = None
    """``[add_targets]``: new target holes cadfeat may propose (``cadfeat.study.added_targets``); None: none."""

    @property
    def label(self) -> str:
        return str(self.file) if self.file is not None else "<study dict>"

    def tracking_settings(self) -> TrackingSpec:
        """The ``[tracking]`` settings every closed loop of this study runs with (``cadfeat run``'s check, ``cadfeat
        track``, the physical views, ``track_design``, g_POSE's filter tuning): the study's ``[tracking]`` table, or
        — what a study without one means, decided here only — the section's defaults with the study's seed (as a
        ``[tracking]`` table that does not set ``seed``). Whether the check runs, and how, is
        ``closed_loop_check.check_mode``'s."""
        return self.tracking if self.tracking is not None else TrackingSpec(seed=self.study.seed)

    def to_dict(self) -> JsonDict:
        """The validated study as plain data (defaults filled in, None left out), for echoing into results.json;
        ``load_study(config.to_dict(), base_dir=config.base_dir)`` gives the same study."""
        return copy.deepcopy(dict(self.data))

    def with_seed(self, seed: int) -> StudyConfig:
        """The same study with ``study.seed`` and ``optimizer.seed`` replaced."""
        check_seed(seed, self.label, "seed")
        data = copy.deepcopy(dict(self.data))
        for section in ("study", "optimizer"):  # (the echo's tables: load_study made them)
            cast("dict[str, object]", data[section])["seed"] = int(seed)
        return dataclasses.replace(self, study=self.study.replace(seed=int(seed)),
                                   optimizer=self.optimizer.replace(seed=int(seed)), data=data)


# ------------------------------------------------------------------------------------------- entry point
def _read(path_or_dict: StudySource, base_dir: str | Path | None) -> tuple[JsonDict, Path | None, Path, str]:
    if isinstance(path_or_dict, Mapping):
        base = Path(base_dir) if base_dir is not None else Path.cwd()
        return copy.deepcopy(dict(path_or_dict)), None, base.resolve(), "<study dict>"
    if not isinstance(path_or_dict, str | Path):  # pyright: ignore[reportUnnecessaryIsInstance] (a caller's bad input)
        raise StudyError(f"study: expected a TOML file path or a dict, got {type(path_or_dict).__name__}")
    path = Path(path_or_dict)
    label = str(path)
    if not path.is_file():
        raise StudyError(f"{label}: study file does not exist; allowed: a path to a .toml study file")
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise StudyError(f"{label}: not valid TOML: {exc}; allowed: a TOML study file (see "
                         "docs/guide/study-files.md)") from exc
    except UnicodeDecodeError as exc:
        raise StudyError(f"{label}: not a UTF-8 text file; allowed: a TOML study file") from exc
    return data, path, (Path(base_dir) if base_dir is not None else path.parent).resolve(), label


def load_study(path_or_dict: StudySource, base_dir: str | Path | None = None) -> StudyConfig:
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
    info = validate_section(StudyInfo, top.raw("study"), "study", label, {"base_dir": base})
    camera = validate_section(CameraSettings, top.raw("camera"), "camera", label, {"base_dir": base, "limits": LIMITS})
    pose = validate_section(PartPose, top.raw("part_pose", {}), "part_pose", label)
    trajectory = validate_trajectory(top.raw("trajectory"), label, {"base_dir": base, "limits": LIMITS})
    params: dict[str, PartParameter] = {}
    if info.part_kind == "script":
        params = part_parameters(info.part_path, info.build_timeout_s)  # (runs the script only for a computed table)
    design = validate_section(DesignSpec, top.raw("design"), "design", label, {
        "part_kind": info.part_kind, "part_params": params, "part": info.part, "limits": LIMITS})
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
    cell = validate_section(Cell, top.raw("cell", {}), "cell", label)
    add_targets = None
    if "add_targets" in data:
        add_targets = validate_section(AddTargetsSettings, top.raw("add_targets"), "add_targets", label)
    echo = {
        "study": info.study_dump(),
        "camera": dict(cast("Mapping[str, object]", top.raw("camera"))),  # (validated: a table)
        "part_pose": pose.study_dump(),
        "trajectory": copy.deepcopy(dict(cast("Mapping[str, object]", top.raw("trajectory")))),
        "design": design.echo(),
        "constraints": constraints.model_dump(mode="json"),
        "objective": objective.study_dump(),
        "optimizer": optimizer.study_dump(),
        "shop": shop.model_dump(mode="json"),
        "robustness": robustness.model_dump(mode="json"),
        "cell": cell.model_dump(mode="json"),
    }
    if tracking is not None:
        echo["tracking"] = tracking.study_dump()
    if add_targets is not None:
        echo["add_targets"] = add_targets.model_dump(mode="json")
    return StudyConfig(path, base, info, camera, pose, trajectory, design, constraints, objective, optimizer,
                       params, _drop_none(echo), shop=shop, robustness=robustness, tracking=tracking,
                       cell=cell, add_targets=add_targets)


@overload
def _drop_none(value: Mapping[str, object]) -> JsonDict: ...
@overload
def _drop_none(value: object) -> object: ...
def _drop_none(value: object) -> object:
    """Plain data without None entries (TOML has no null): the echo can be loaded again."""
    if isinstance(value, Mapping):
        return {k: _drop_none(v) for k, v in cast("Mapping[object, object]", value).items() if v is not None}
    if isinstance(value, list | tuple):
        return [_drop_none(v) for v in cast("Sequence[object]", value)]
    return value
