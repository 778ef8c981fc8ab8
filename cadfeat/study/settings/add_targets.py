"""``[add_targets]`` of a study file: cadfeat proposes NEW blind target holes (issue 31).

Moving and resizing the holes a part already has gains little when the part has few of them; drilling a few
small blind target holes where the camera sees them well is the lever that lowers the predicted pose error most.
This section says where holes may be added (``faces``, minus ``keepout_boxes``, within ``keepin_boxes``), the
drill (a diameter of the study's ``[shop] hole_sizes`` table, a blind depth, a 45° rim chamfer), the most to add,
and when to stop (``target_error_mm`` reached, or one more hole gains less than ``min_gain_percent``). The study
phase is ``cadfeat.study.added_targets``; units are in the key names (mm, percent).
"""

from __future__ import annotations

import re
from typing import ClassVar, Self

from pydantic import Field, ValidationInfo, field_validator, model_validator

from cadfeat.study.settings._base import Settings, Tuple, boolean, choice, integer, number, reject

__all__ = ["FACE_DIRECTIONS", "MIN_DEPTH_RATIO", "AddTargetsSettings", "face_pattern"]

FACE_DIRECTIONS = ("+x", "-x", "+y", "-y", "+z", "-z")
"""A face by its outward normal: the largest planar face of the part facing that way."""
MIN_DEPTH_RATIO = 0.5
"""The least depth/diameter of an added hole: the PBR-calibrated pose models do not describe a shallower blind hole
(the note in studies/nema17_mount.toml)."""
_FACE = re.compile(r"^([+-][xyz]|host:[A-Za-z0-9_.\-]+)$")
FACE_TEXT = ("a list of faces, each \"+x\", \"-x\", \"+y\", \"-y\", \"+z\" or \"-z\" (the largest planar face "
             "with that outward normal) or \"host:<hole name>\" (the planar face a hole of the part opens into)")


def face_pattern(face: str) -> bool:
    """True if ``face`` is a face selector of ``[add_targets] faces`` (``FACE_TEXT``)."""
    return bool(_FACE.match(face))


class AddTargetsSettings(Settings):
    """``[add_targets]``: where and how cadfeat may drill new target holes, and when it stops adding them."""

    section: ClassVar[str] = "add_targets"

    faces: Tuple[str] = Field(..., description="the planar faces new holes may be drilled into",
                              json_schema_extra={"x-allowed": FACE_TEXT})  # (required: no default)
    keepout_boxes: Tuple[Tuple[float]] = choice(
        (), "a list of boxes [xmin, ymin, zmin, xmax, ymax, zmax] (mm, part frame), each min < max",
        description="regions no added hole's rim may enter (e.g. a motor's outline), plus [constraints] ligament_mm")
    keepin_boxes: Tuple[Tuple[float]] = choice(
        (), "a list of boxes [xmin, ymin, zmin, xmax, ymax, zmax] (mm, part frame), each min < max and holding part "
            "of an allowed face",
        description="a keep-in region: each added hole's whole rim must lie inside one of these boxes; none: "
                    "anywhere on the allowed faces")
    diameter_mm: float = number(5.5, 0.0, 50.0, lo_open=True,
                                description="drill diameter, a size of the study's [shop] hole_sizes table")
    depth_mm: float = number(3.0, 0.0, 100.0, lo_open=True,
                             description="blind depth below the face, at least half the diameter")
    chamfer_mm: float = number(0.0, 0.0, 5.0, description="45° rim chamfer (the rim the camera sees: radius + this)")
    max_added: int = integer(3, 1, 12, description="the most holes added")
    target_error_mm: float | None = number(None, 0.0, lo_open=True,
                                           description="stop when the predicted RMS pose error reaches this")
    min_gain_percent: float = number(5.0, 0.0, 100.0,
                                     description="stop when one more hole lowers the error by less than this")
    pitch_mm: float = number(2.0, 0.1, 50.0, description="spacing of the candidate sites on each face")
    refine: bool = boolean(True, description="refine the added holes' positions continuously after the greedy choice")

    @field_validator("faces")
    @classmethod
    def _faces(cls, value: tuple[str, ...]) -> tuple[str, ...]:
        if not value:
            raise reject("faces", "[] is not allowed", FACE_TEXT)
        for face in value:
            if not face_pattern(face):
                raise reject("faces", f"{face!r} is not allowed", FACE_TEXT)
        if len(set(value)) != len(value):
            raise reject("faces", "a face is listed twice", FACE_TEXT)
        return value

    @field_validator("keepout_boxes", "keepin_boxes")
    @classmethod
    def _boxes(cls, value: tuple[tuple[float, ...], ...], info: ValidationInfo) -> tuple[tuple[float, ...], ...]:
        for box in value:
            if len(box) != 6 or not all(box[i] < box[i + 3] for i in range(3)):
                raise reject(str(info.field_name), f"{list(box)} is not allowed",
                             "a list of boxes [xmin, ymin, zmin, xmax, ymax, zmax] (mm), each min < max")
        return value

    @model_validator(mode="after")
    def _describable(self) -> Self:
        """The chamfer fits in the hole; depth/diameter ≥ ``MIN_DEPTH_RATIO`` (the pose models, calibrated under
        physical light, do not describe a shallower blind hole: its found rim sits 0.6–0.8 px off, unmodelled —
        the greedy choice must not exploit what the models do not see)."""
        if self.chamfer_mm >= self.depth_mm:
            raise reject("chamfer_mm", f"{self.chamfer_mm:g} is not allowed",
                         f"a chamfer shallower than depth_mm = {self.depth_mm:g} mm")
        if self.depth_mm < MIN_DEPTH_RATIO * self.diameter_mm - 1e-9:
            raise reject("depth_mm", f"{self.depth_mm:g} is not allowed",
                         f"a depth ≥ {MIN_DEPTH_RATIO:g} × diameter_mm = {MIN_DEPTH_RATIO * self.diameter_mm:g} mm "
                         "(a shallower blind hole is outside what the pose models describe)")
        return self

    @property
    def rim_radius_mm(self) -> float:
        """The radius of the rim the camera sees (mm): the drill's radius plus the chamfer."""
        return 0.5 * self.diameter_mm + self.chamfer_mm
