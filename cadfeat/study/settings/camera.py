"""``[camera]`` of a study file, declared once: its keys are the ``Camera`` dataclass's fields (generated from
it, not copied) over a ``preset`` or an OpenCV ``calibration`` file.

The model checks each key's type (strict: a TOML string is not a number, a float is not an integer), the size
limits (validation context ``limits``: ``LIMITS['image_side_px']``, ``LIMITS['image_pixels']``) and the
calibration file (context ``base_dir``: the study file's folder); its after-validator then builds the ``Camera``
(``cadfeat.camera.build_camera``), so ``Camera``'s own checks (positive focal lengths, principal point inside
the image, focus beyond the focal length, f-number and aperture consistent, 4 or 5 distortion terms) keep their
wording, now with the dotted key and what is allowed: ``s.toml: camera.cx: camera 'custom': principal point
(cx, cy) = (700.0, 61.5) must lie inside the 128x128 image; allowed: 0 ≤ cx ≤ width and 0 ≤ cy ≤ height (px)``.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from pathlib import Path
from typing import Any, ClassVar, Self, cast

from pydantic import PrivateAttr, ValidationInfo, create_model, field_validator, model_validator

from cadfeat.camera import PRESETS, Camera, CameraError, build_camera
from cadfeat.settings import Settings, Tuple, check_limit, choice, context_of, reject
from cadfeat.study.settings.scene import Finite

__all__ = ["CAMERA_FIELDS", "REQUIRED_FIELDS", "CameraSettings"]

CAMERA_FIELDS = tuple(f.name for f in dataclasses.fields(Camera))
"""The ``Camera`` fields a study's ``[camera]`` may set (each overrides the preset's or calibration's)."""
REQUIRED_FIELDS = tuple(f.name for f in dataclasses.fields(Camera)
                        if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING)
"""The fields ``[camera]`` must give when it names neither a preset nor a calibration file."""
_CALIBRATION = ("an OpenCV FileStorage calibration file (YAML, XML or JSON) with camera_matrix, "
                "distortion_coefficients, image_width and image_height")


class _CameraTable(Settings):
    """``[camera]`` without the ``Camera`` fields (``CameraSettings`` adds them): preset, calibration file, and
    the checks that build the camera. ``build()`` gives the ``Camera``; ``table`` the keys the file gave."""

    section: ClassVar[str] = "camera"

    preset: str | None = choice(None, sorted(PRESETS), description="a named camera (cadfeat cameras)")
    calibration: str | None = choice(None, "a path to an OpenCV calibration file",
                                     description="OpenCV FileStorage file (.yaml, .xml, .json), relative to the "
                                                 "study file")
    _camera: Camera | None = PrivateAttr(None)

    @field_validator("preset", mode="before")
    @classmethod
    def _preset_name(cls, value: object) -> object:
        """Preset names are matched without case or surrounding blanks (as ``Camera.preset`` does)."""
        return value.strip().lower() if isinstance(value, str) else value

    @field_validator("calibration")
    @classmethod
    def _calibration_file(cls, value: str | None, info: ValidationInfo) -> str | None:
        """The file, relative to the study's folder (context ``base_dir``), exists: its resolved path."""
        if value is None:
            return None
        base_dir = context_of(info).get("base_dir")
        path = (Path(base_dir) / value if base_dir is not None else Path(value)).resolve()
        if not path.is_file():
            raise reject("calibration", f"file {path} does not exist", "an existing OpenCV calibration file")
        return str(path)

    @model_validator(mode="after")
    def _build(self, info: ValidationInfo) -> Self:
        """Size limits, one source (preset or calibration) and the ``Camera`` itself (its checks, its wording)."""
        limits = context_of(info).get("limits")
        given = self.table
        if limits is not None:
            for side in ("width", "height"):
                check_limit(side, given.get(side), limits, "image_side_px", "pixels")
            if isinstance(width := given.get("width"), int) and isinstance(height := given.get("height"), int):
                check_limit("width * camera.height", width * height, limits, "image_pixels", "pixels")
        if self.preset is not None and self.calibration is not None:
            raise reject("calibration", "given together with camera.preset", "one of preset or calibration")
        if self.preset is None and self.calibration is None:
            missing = [k for k in REQUIRED_FIELDS if k not in given]
            if missing:
                raise reject(missing[0], "missing", "with neither camera.preset nor camera.calibration: all of "
                                                    f"{', '.join(REQUIRED_FIELDS)}")
        self._camera = self._camera_of(given)
        return self

    def _camera_of(self, given: dict[str, object]) -> Camera:
        overrides = {k: v for k, v in given.items() if k in CAMERA_FIELDS}
        try:
            return build_camera(overrides, self.preset, self.calibration)
        except CameraError as exc:
            key = exc.key or ("calibration" if self.calibration is not None else "")
            raise reject(key, str(exc), exc.allowed or _CALIBRATION) from None
        except Exception as exc:  # noqa: BLE001 — a bad calibration file may raise anything from OpenCV
            raise reject("calibration", f"{self.calibration}: {exc}", _CALIBRATION) from None

    def build(self) -> Camera:
        """The ``Camera`` (built once, when the section was validated)."""
        assert self._camera is not None
        return self._camera


def _field(name: str, hint: object) -> tuple[object, object]:
    """A ``Camera`` field as an optional study key of the same type (strict; tuples as TOML arrays)."""
    union = typing.get_origin(hint) in (typing.Union, types.UnionType)
    kind = next(a for a in typing.get_args(hint) if a is not type(None)) if union else hint
    if typing.get_origin(kind) is tuple:
        return (typing.Optional[Tuple[Finite]],  # noqa: UP045 (a runtime type, not an annotation)
                choice(None, "a list of finite numbers", description=f"Camera.{name}"))
    if kind is float:
        return (typing.Optional[Finite],  # noqa: UP045 (a runtime type, not an annotation)
                choice(None, "a finite number", description=f"Camera.{name}"))
    if kind is int:
        return int | None, choice(None, "an integer", description=f"Camera.{name}")
    if kind is str:
        return str | None, choice(None, "a string", description=f"Camera.{name}")
    raise TypeError(f"Camera.{name}: no study-file type for {kind!r}")


_HINTS = typing.get_type_hints(Camera)
CameraSettings = create_model("CameraSettings", __base__=_CameraTable, __module__=__name__,
                              __doc__="``[camera]``: ``preset`` or ``calibration`` and any ``Camera`` field "
                                      "(an override), or all of fx, fy, cx, cy, width, height.",
                              # (create_model takes its field definitions untyped: pydantic's dynamic API)
                              **{f: cast(Any, _field(f, _HINTS[f])) for f in CAMERA_FIELDS})
"""``[camera]``: the ``_CameraTable`` keys plus one optional key per ``Camera`` field."""
