"""``[study]`` and ``[part_pose]`` of a study file, declared once as ``Settings`` models.

``StudyInfo`` checks the part file through validation context (``base_dir``: the study file's folder): it
exists, is a regular file, is a part script (.py) or a STEP file (.step/.stp) whose header reads like one; its
resolved ``part_path`` and ``part_kind`` are derived fields (not study keys). ``PartPose`` takes a rotation
vector (deg) or a unit quaternion [x, y, z, w] (converted to the rotation vector).
"""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar, TypeVar, cast

import numpy as np
from pydantic import Field, ValidationInfo, model_validator
from scipy.spatial.transform import Rotation  # pyright: ignore[reportMissingTypeStubs]

from cadfeat.settings import Finite, Settings, Tuple, choice, context_of, integer, number, reject

__all__ = ["BUILD_TIMEOUT_S", "SCRIPT_SUFFIXES", "STEP_SUFFIXES", "PartPose", "StudyInfo", "Vector"]

BUILD_TIMEOUT_S = 60.0
"""Default ``[study] build_timeout_s``: time limit of one part-script import or CAD build (worker process)."""
SCRIPT_SUFFIXES = (".py",)
STEP_SUFFIXES = (".step", ".stp")
_NAME = r"^[A-Za-z0-9][A-Za-z0-9_.-]*$"

Vector = Tuple[Finite]
"""A list of finite numbers (mm, deg, …); its length is checked by the field's validator."""


F = TypeVar("F")


def vector(default: F, n: int, *, description: str = "") -> F:
    """A field of ``n`` finite numbers (a TOML array); integers become floats (a field definition typed as its
    value, as ``cadfeat.settings.number``)."""
    return Field(default, min_length=n, max_length=n, description=description,
                 json_schema_extra={"x-allowed": f"a list of {n} finite numbers"})


class StudyInfo(Settings):
    """``[study]``: ``part`` as written (relative to the study file), ``part_path`` resolved, ``part_kind``
    "script" or "step" (derived: not study keys)."""

    section: ClassVar[str] = "study"

    name: str = Field(pattern=_NAME, description="the study's name (the output folder's)", json_schema_extra={
        "x-allowed": "a name of letters, digits, '_', '-', '.' (a folder name)"})
    part: str = Field(description="part script (.py) or STEP file (.step, .stp), relative to the study file",
                      json_schema_extra={"x-allowed": "a part script (.py) or STEP file (.step, .stp), relative "
                                                      "to the study file"})
    seed: int = integer(0, 0, 2**32 - 1)
    description: str = choice("", "a string")
    build_timeout_s: float = number(BUILD_TIMEOUT_S, 0.0, 86_400.0, lo_open=True,
                                    description="time limit of one part-script import or CAD build (s)")
    part_path: Path = Field(Path(), json_schema_extra={"x-internal": True, "x-allowed": "(derived)"})
    part_kind: str = choice("script", ("script", "step"), internal=True)

    @model_validator(mode="before")
    @classmethod
    def _part_file(cls, data: object, info: ValidationInfo) -> object:
        """``part_path``/``part_kind`` from ``part`` and the study's folder (context ``base_dir``)."""
        context = context_of(info)
        if not isinstance(data, dict) or "base_dir" not in context:
            return cast(object, data)
        table = cast("dict[str, object]", data)
        part = table.get("part")
        if not isinstance(part, str):
            return table
        base_dir = Path(context["base_dir"])
        suffix = Path(part).suffix.lower()
        if suffix not in SCRIPT_SUFFIXES + STEP_SUFFIXES:
            raise reject("part", f"{part!r} is neither a part script nor a STEP file",
                         "a path ending in .py, .step or .stp")
        path = (base_dir / part).resolve()
        if not path.is_file():
            shown = base_dir / part if (base_dir / part).is_symlink() else path
            problem = f"{shown} is not a regular file ({path}: a device, folder or pipe)" if path.exists() else \
                f"file {path} does not exist"
            raise reject("part", problem, "an existing part script or STEP file")
        kind = "script" if suffix in SCRIPT_SUFFIXES else "step"
        if kind == "step":
            _check_step_header(path)
        return {**table, "part_path": path, "part_kind": kind}


def _check_step_header(path: Path) -> None:
    """A STEP file is readable and starts like one (``ISO-10303-21;`` header, ``HEADER;`` section)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError as exc:
        raise reject("part", f"{path} cannot be read ({exc.strerror})", "a readable STEP file") from None
    text = head.lstrip(b"\xef\xbb\xbf \t\r\n")
    if not text.startswith(b"ISO-10303-21") or b"HEADER" not in head:
        what = "is empty" if not head else "does not start with the STEP header 'ISO-10303-21;'"
        raise reject("part", f"{path} {what}", "a STEP file (ISO 10303-21 text, as CAD programs export)")


class PartPose(Settings):
    """``[part_pose]``: the part frame in the task frame (mm; rotation as a rotation vector in degrees, or
    ``quaternion`` = [x, y, z, w], scalar last, converted to it)."""

    section: ClassVar[str] = "part_pose"

    position_mm: Vector = vector((0.0, 0.0, 0.0), 3)
    rotvec_deg: Vector = vector((0.0, 0.0, 0.0), 3)
    quaternion: Vector | None = vector(None, 4, description="unit quaternion [x, y, z, w] (instead of rotvec_deg)")

    @model_validator(mode="after")
    def _one_rotation(self) -> PartPose:
        """A quaternion (unit, either sign) becomes ``rotvec_deg``; it may not come with ``rotvec_deg``."""
        if self.quaternion is None:
            return self
        if "rotvec_deg" in self.model_fields_set:
            raise reject("quaternion", "given together with part_pose.rotvec_deg", "one of rotvec_deg or quaternion")
        q = np.asarray(self.quaternion, float)
        norm = float(np.linalg.norm(q))
        if abs(norm - 1.0) > 1e-3:
            raise reject("quaternion", f"norm {norm:.6g} is not 1", "a unit quaternion [x, y, z, w] (scalar last)")

        rotvec = np.degrees(Rotation.from_quat(q / norm).as_rotvec())
        object.__setattr__(self, "rotvec_deg", tuple(float(v) for v in rotvec))
        object.__setattr__(self, "quaternion", None)
        return self

    @property
    def T_task_part(self) -> np.ndarray:
        """4x4 transform mapping part coordinates to task coordinates."""
        T = np.eye(4)
        T[:3, :3] = Rotation.from_rotvec(np.radians(self.rotvec_deg)).as_matrix()
        T[:3, 3] = self.position_mm
        return T
