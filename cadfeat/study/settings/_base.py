"""The base of every study-file section model: pydantic v2, strict, unknown keys refused, frozen.

A section is declared once, as a ``Settings`` subclass whose fields carry their type, default, bounds and the
"allowed" text of the error message (``number``, ``integer``, ``boolean``, ``choice``). ``validate_section``
turns a pydantic ``ValidationError`` into one ``StudyError`` line naming the file, the dotted key and what is
allowed (today's message format: ``s.toml: tracking.r_px2: -1.0 is not allowed; allowed: a number > 0``).
Context-dependent checks (a default from the study's seed, bounds inside the part's own) read the validation
context (``info.context``) given to ``validate_section``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Annotated, Any, TypeVar, cast

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, ValidationError, ValidationInfo, model_validator
from pydantic_core import ErrorDetails, PydanticCustomError

from cadfeat.errors import CadfeatError

__all__ = ["Settings", "StudyError", "Tuple", "boolean", "choice", "integer", "number", "range_text",
           "reject", "seed_from_context", "validate_section"]


class StudyError(CadfeatError):
    """A study file is invalid: the message names the file, the dotted key and what is allowed."""


def _as_tuple(value: object) -> object:
    """TOML arrays are lists: a tuple field takes a list as its items (strict validation of each item)."""
    return tuple(cast("list[object]", value)) if isinstance(value, list) else value


T = TypeVar("T")
Tuple = Annotated[tuple[T, ...], BeforeValidator(_as_tuple)]
"""A tuple field that accepts a TOML array (list)."""


class Settings(BaseModel):
    """A study-file section: strict types (no "5" for 5, no 1.0 for an integer, no 1 for true), unknown keys
    refused, immutable. Each field's ``x-allowed`` (JSON Schema extra) is the "allowed:" part of its errors."""

    model_config = ConfigDict(strict=True, extra="forbid", frozen=True, validate_default=False)

    @model_validator(mode="after")
    def _enumerations(self) -> Any:
        """A field declared with ``choice(default, names)`` holds one of ``names`` (its schema ``enum``)."""
        for name, field in type(self).model_fields.items():
            extra = cast("dict[str, Any] | None", field.json_schema_extra)
            if isinstance(extra, dict) and "enum" in extra and getattr(self, name) not in extra["enum"]:
                raise reject(name, f"{_fmt(getattr(self, name))} is not allowed", str(extra["x-allowed"]))
        return self

    def replace(self, **changes: Any) -> Any:
        """A validated copy with ``changes`` (``dataclasses.replace`` for a settings model)."""
        return type(self).model_validate({**self.model_dump(), **changes})


def seed_from_context(data: object, info: ValidationInfo) -> object:
    """A section's table with ``seed`` defaulting to the study's (validation context ``seed``)."""
    context = cast("dict[str, Any] | None", info.context)
    if not isinstance(data, dict) or not context or "seed" not in context:
        return cast(object, data)
    table = cast("dict[str, Any]", data)
    return table if "seed" in table else {**table, "seed": context["seed"]}


def range_text(lo: float | None, hi: float | None, lo_open: bool = False) -> str:
    """"a number ≥ 0", "a number in (0, 100]", … — the allowed text of a bounded number."""
    if lo is None and hi is None:
        return "a finite number"
    if hi is None:
        return f"a number {'>' if lo_open else '≥'} {lo:g}"
    if lo is None:
        return f"a number ≤ {hi:g}"
    return f"a number in {'(' if lo_open else '['}{lo:g}, {hi:g}]"


def number(default: Any, lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
           description: str = "") -> Any:
    """A finite float field in [lo, hi] (lo excluded when ``lo_open``); integers are accepted as numbers."""
    return Field(default, ge=None if lo_open else lo, gt=lo if lo_open else None, le=hi, allow_inf_nan=False,
                 description=description, json_schema_extra={"x-allowed": range_text(lo, hi, lo_open)})


def integer(default: Any, lo: int, hi: int | None = None, *, description: str = "") -> Any:
    """An integer field in [lo, hi] (a float or a boolean is refused)."""
    text = f"an integer ≥ {lo}" if hi is None else f"an integer in [{lo}, {hi}]"
    return Field(default, ge=lo, le=hi, description=description, json_schema_extra={"x-allowed": text})


def boolean(default: bool, *, description: str = "") -> Any:
    return Field(default, description=description, json_schema_extra={"x-allowed": "true or false"})


def choice(default: Any, allowed: Sequence[str] | str, *, description: str = "") -> Any:
    """A field of an enumeration (``Literal``) or any field with a hand-written allowed text."""
    if isinstance(allowed, str):
        return Field(default, description=description, json_schema_extra={"x-allowed": allowed})
    return Field(default, description=description,
                 json_schema_extra={"x-allowed": ", ".join(allowed), "enum": list(allowed)})


def reject(key: str, problem: str, allowed: str) -> PydanticCustomError:
    """An error of a model-level check: ``raise reject("objective.thresholds", "missing", "…")``; ``key`` is
    relative to the section."""
    return PydanticCustomError("cadfeat", "{problem}", {"key": key, "problem": problem, "allowed": allowed})


def _fmt(value: Any) -> str:
    return repr(value) if isinstance(value, str) else str(value)


M = TypeVar("M", bound=Settings)


def validate_section(model: type[M], data: Any, section: str, label: str,
                     context: Mapping[str, Any] | None = None) -> M:
    """``data`` (the TOML table of ``[section]``) validated as ``model``; one ``StudyError`` line otherwise."""
    keys = ", ".join(model.model_fields)
    if not isinstance(data, Mapping):
        raise StudyError(f"{label}: {section}: expected a table, got {_fmt(data)}; allowed: a table with keys {keys}")
    table = dict(cast("Mapping[str, Any]", data))
    try:
        return model.model_validate(table, context=dict(context or {}))
    except ValidationError as exc:
        raise StudyError(f"{label}: {_message(model, exc.errors()[0], table, section)}") from None


def _message(model: type[Settings], err: ErrorDetails, data: Mapping[str, Any], section: str) -> str:
    loc = [str(x) for x in err["loc"]]
    ctx: dict[str, Any] = dict(err.get("ctx") or {})
    if err["type"] == "cadfeat":
        return f"{section}.{ctx['key']}: {ctx['problem']}; allowed: {ctx['allowed']}"
    name = loc[0] if loc else ""
    key = f"{section}.{name}" if name else section
    if err["type"] == "extra_forbidden":
        return f"{key}: unknown key; allowed: keys of [{section}]: {', '.join(model.model_fields)}"
    field = model.model_fields.get(name)
    extra = cast("dict[str, Any] | None", field.json_schema_extra if field is not None else None)
    allowed = str(extra.get("x-allowed", err["msg"])) if isinstance(extra, dict) else err["msg"]
    if err["type"] == "missing":
        return f"{key}: missing; allowed: {allowed}"
    return f"{key}: {_fmt(data.get(name, err.get('input')))} is not allowed; allowed: {allowed}"
