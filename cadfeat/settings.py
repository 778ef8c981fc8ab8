"""The base of every configuration model: pydantic v2, strict, unknown keys refused, frozen.

A setting is declared once, as a field of a ``Settings`` subclass carrying its type, default, bounds and the
"allowed" text of the error message (``number``, ``integer``, ``boolean``, ``choice``). The same model is the
configuration the code uses (``cadfeat.design.objectives.ObjectiveConfig`` is ``[objective]``) and the study
file's section: ``validate_section`` turns a pydantic ``ValidationError`` into one ``StudyError`` line naming
the file, the dotted key and what is allowed (``s.toml: tracking.r_px2: -1.0 is not allowed; allowed: a number
> 0``); built directly in Python (``ObjectiveConfig(aggregate="median")``) the same line, without the file, is
a ``CadfeatError``. Fields declared ``internal=True`` are solver tuning the study file does not set (they are
left out of its keys, its echo and its JSON Schema).

Context-dependent checks read the validation context (``info.context``) that ``validate_section`` gives:
``study`` (True: a study file's rules), ``seed`` (the study's seed, a default), ``limits`` (size limits),
``part`` / ``base_dir`` (bounds inside the part's own, files relative to the study).

This module sits at the package root (no cadfeat imports but ``errors``) so every layer can declare its
configuration with it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Annotated, ClassVar, Literal, Self, TypedDict, TypeVar, cast, overload

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    JsonValue,
    ValidationError,
    ValidationInfo,
    model_validator,
)
from pydantic_core import ErrorDetails, PydanticCustomError

from cadfeat.errors import CadfeatError

__all__ = ["Finite", "Settings", "StudyError", "Tuple", "ValidationContext", "boolean", "check_limit", "choice",
           "context_of", "integer", "number", "range_text", "reject", "seed_from_context", "validate_nested",
           "validate_section"]


class StudyError(CadfeatError):
    """A study file is invalid: the message names the file, the dotted key and what is allowed."""


class ValidationContext(TypedDict, total=False):
    """What ``validate_section`` gives the validators (``info.context``; module docstring): ``study`` (a study
    file's rules), ``seed`` (the study's), ``limits`` (``cadfeat.study.schema.LIMITS``), ``base_dir`` (files relative
    to the study), ``part_kind`` / ``part`` (the part's kind, its label), ``part_params`` (name → the part's
    ``cad.parts.PartParameter``) and ``parameter`` (the one a ``[design.parameters]`` entry names)."""

    study: bool
    seed: int
    limits: Mapping[str, int]
    base_dir: Path
    part_kind: str
    part: str
    part_params: Mapping[str, object]
    parameter: object


def _as_tuple(value: object) -> object:
    """TOML arrays are lists: a tuple field takes a list as its items (strict validation of each item)."""
    return tuple(cast("list[object]", value)) if isinstance(value, list) else value


Finite = Annotated[float, Field(allow_inf_nan=False)]
"""A finite float (an integer is accepted and becomes a float)."""

T = TypeVar("T")
Tuple = Annotated[tuple[T, ...], BeforeValidator(_as_tuple)]
"""A tuple field that accepts a TOML array (list)."""


class Settings(BaseModel):
    """A study-file section: strict types (no "5" for 5, no 1.0 for an integer, no 1 for true), unknown keys
    refused, immutable. Each field's ``x-allowed`` (JSON Schema extra) is the "allowed:" part of its errors."""

    model_config = ConfigDict(strict=True, extra="forbid", frozen=True, validate_default=False)
    section: ClassVar[str] = ""
    """The study-file table this model is (``"objective"``): the first part of each error's dotted key."""
    moved: ClassVar[dict[str, str]] = {}
    """Keys that moved elsewhere → where (a one-line error names it: ``tracking.placement_mm: this key moved; allowed:
    [robustness] placement_position_mm …``)."""

    def __init__(self, /, **data: object) -> None:
        """Built in Python: a bad value is one ``CadfeatError`` line (``objective.aggregate: 'median' is not
        allowed; allowed: sum, mean, min, smoothmin``), as from a study file."""
        try:
            super().__init__(**data)
        except ValidationError as exc:
            raise CadfeatError(_message(type(self), exc.errors()[0], data, self.section)) from None

    # pydantic calls a custom __init__ from model_validate too (dropping the validation context); marked as the
    # base's, it is only called for direct construction
    __init__.__pydantic_base_init__ = True  # type: ignore[attr-defined]

    @classmethod
    def study_keys(cls) -> tuple[str, ...]:
        """The keys a study file may set (the fields not declared ``internal``)."""
        return tuple(n for n, f in cls.model_fields.items() if not _extra_of(f.json_schema_extra).get("x-internal"))

    def study_dump(self) -> dict[str, object]:
        """The study-file keys as plain JSON data (tuples as lists): the echo in results.json."""
        return self.model_dump(mode="json", include=set(self.study_keys()))

    @model_validator(mode="after")
    def _enumerations(self) -> Self:
        """A field declared with ``choice(default, names)`` holds one of ``names`` (its schema ``enum``)."""
        for name, field in type(self).model_fields.items():
            extra = _extra_of(field.json_schema_extra)
            enum, value = extra.get("enum"), getattr(self, name)
            if isinstance(enum, list) and value is not None and value not in cast("list[object]", enum):
                raise reject(name, f"{_fmt(value)} is not allowed", str(extra["x-allowed"]))
        return self

    @property
    def table(self) -> dict[str, object]:
        """The keys the study file (or the caller) gave, as validated (defaults left out)."""
        return {k: getattr(self, k) for k in type(self).model_fields if k in self.model_fields_set}

    def replace(self, **changes: object) -> Self:
        """A validated copy with ``changes`` (``dataclasses.replace`` for a settings model); the other fields as
        they are (a nested model stays that model)."""
        return type(self)(**{**{k: getattr(self, k) for k in type(self).model_fields}, **changes})


def _extra_of(extra: object) -> dict[str, object]:
    """A field's JSON Schema extra as a dict (empty when it has none)."""
    return dict(cast("dict[str, object]", extra)) if isinstance(extra, dict) else {}


def context_of(info: ValidationInfo) -> ValidationContext:
    """The validation context (empty when the model is built in Python)."""
    context: ValidationContext | None = info.context  # (what validate_section gave pydantic)
    return ValidationContext(**(context or {}))


def seed_from_context(data: object, info: ValidationInfo) -> object:
    """A section's table with ``seed`` defaulting to the study's (validation context ``seed``)."""
    context = context_of(info)
    if not isinstance(data, dict) or "seed" not in context:
        return cast(object, data)
    table = cast("dict[str, object]", data)
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


def _extra(allowed: str, internal: bool, **more: JsonValue) -> dict[str, JsonValue]:
    return {"x-allowed": allowed, **({"x-internal": True} if internal else {}), **more}


F = TypeVar("F")
"""A field's value type. The field helpers return the field's definition (pydantic's ``FieldInfo``) typed as the
value it gives, as ``dataclasses.field`` is typed: ``x: float = number(1.0, 0.0)`` checks the default against the
declared type."""


def number(default: F, lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
           hi_open: bool = False, description: str = "", internal: bool = False) -> F:
    """A finite float field in [lo, hi] (lo/hi excluded when ``lo_open``/``hi_open``); integers are accepted."""
    text = range_text(lo, hi, lo_open)
    if hi_open and lo is not None and hi is not None:
        text = text[:-1] + ")"
    return Field(default, ge=None if lo_open else lo, gt=lo if lo_open else None, le=None if hi_open else hi,
                 lt=hi if hi_open else None, allow_inf_nan=False, description=description,
                 json_schema_extra=_extra(text, internal))


def integer(default: F, lo: int, hi: int | None = None, *, description: str = "", internal: bool = False) -> F:
    """An integer field in [lo, hi] (a float or a boolean is refused)."""
    text = f"an integer ≥ {lo}" if hi is None else f"an integer in [{lo}, {hi}]"
    return Field(default, ge=lo, le=hi, description=description, json_schema_extra=_extra(text, internal))


def boolean(default: bool, *, description: str = "", internal: bool = False) -> bool:
    return Field(default, description=description, json_schema_extra=_extra("true or false", internal))


@overload
def choice(default: Callable[[], F], allowed: Sequence[str] | str, *, description: str = "",
           internal: bool = False, factory: Literal[True]) -> F: ...
@overload
def choice(default: F, allowed: Sequence[str] | str, *, description: str = "", internal: bool = False,
           factory: Literal[False] = False) -> F: ...
def choice(default: object, allowed: Sequence[str] | str, *, description: str = "", internal: bool = False,
           factory: bool = False) -> object:
    """A field of an enumeration (``allowed``: its names) or any field with a hand-written allowed text
    (``allowed``: the text); ``factory``: ``default`` is a zero-argument callable (a mutable default)."""
    extra = _extra(allowed, internal) if isinstance(allowed, str) else \
        _extra(", ".join(allowed), internal, enum=list(allowed))
    if factory:
        return Field(default_factory=cast("Callable[[], object]", default), description=description,
                     json_schema_extra=extra)
    return Field(default, description=description, json_schema_extra=extra)


def reject(key: str, problem: str, allowed: str) -> PydanticCustomError:
    """An error of a model-level check: ``raise reject("objective.thresholds", "missing", "…")``; ``key`` is
    relative to the section."""
    return PydanticCustomError("cadfeat", "{problem}", {"key": key, "problem": problem, "allowed": allowed})


def check_limit(key: str, value: object, limits: Mapping[str, int], limit: str, what: str) -> None:
    """An integer ``value`` (of ``key``, relative to the section) must not exceed ``limits[limit]`` (the study's
    size limits, validation context ``limits``): checked before anything is allocated."""
    if isinstance(value, int) and not isinstance(value, bool) and value > limits[limit]:
        raise reject(key, f"{value} {what} is more than the limit of {limits[limit]:,}",
                     f"at most {limits[limit]:,} (cadfeat.study.schema.LIMITS[{limit!r}])")


def _fmt(value: object) -> str:
    return repr(value) if isinstance(value, str) else str(value)


M = TypeVar("M", bound=Settings)


def validate_section(model: type[M], data: object, section: str, label: str,
                     context: ValidationContext | None = None) -> M:
    """``data`` (the TOML table of ``[section]``) validated as ``model`` with the study's rules (validation
    context ``study=True`` plus ``context``); one ``StudyError`` line otherwise."""
    keys = model.study_keys()
    if not isinstance(data, Mapping):
        raise StudyError(f"{label}: {section}: expected a table, got {_fmt(data)}; allowed: a table with keys "
                         f"{', '.join(keys)}")
    table = dict(cast("Mapping[str, object]", data))
    for key in table:
        if key in model.moved:
            raise StudyError(f"{label}: {section}.{key}: this key moved; allowed: {model.moved[key]}")
        if key not in keys:
            raise StudyError(f"{label}: {section}.{key}: unknown key; allowed: keys of [{section}]: {', '.join(keys)}")
    try:
        return model.model_validate(table, context={"study": True, **dict(context or {})})
    except ValidationError as exc:
        raise StudyError(f"{label}: {_message(model, exc.errors()[0], table, section)}") from None


def _parts(model: type[Settings], err: ErrorDetails, data: Mapping[str, object], section: str) -> tuple[str, str, str]:
    """(key relative to the section, problem, allowed) of a pydantic error."""
    loc = [str(x) for x in err["loc"]]
    ctx: dict[str, object] = dict(err.get("ctx") or {})
    if err["type"] == "cadfeat":
        return str(ctx["key"]), str(ctx["problem"]), str(ctx["allowed"])
    name = loc[0] if loc else ""
    if err["type"] == "extra_forbidden":
        return name, "unknown key", f"keys of [{section}]: {', '.join(model.study_keys())}"
    field = model.model_fields.get(name)
    allowed = str(_extra_of(field.json_schema_extra if field is not None else None).get("x-allowed", err["msg"]))
    if err["type"] == "missing":
        return name, "missing", allowed
    return name, f"{_fmt(data.get(name, err.get('input')))} is not allowed", allowed


def _message(model: type[Settings], err: ErrorDetails, data: Mapping[str, object], section: str) -> str:
    name, problem, allowed = _parts(model, err, data, section)
    key = ".".join(k for k in (section, name) if k)
    return f"{key}: {problem}; allowed: {allowed}"


def validate_nested(model: type[M], data: object, key: str, section: str, context: ValidationContext) -> M:
    """A sub-table (``data`` at ``key``, relative to the enclosing section) validated as ``model`` inside a
    validator of the enclosing model: an error becomes that model's error with the full dotted key
    (``holes[0].select``); unknown keys are named with the sub-table's allowed keys (``[section.key]``)."""
    where = f"{section}.{key}"
    if not isinstance(data, Mapping):
        raise reject(key, f"expected a table, got {_fmt(data)}", f"a table with keys {', '.join(model.study_keys())}")
    table = dict(cast("Mapping[str, object]", data))
    for k in table:
        if k not in model.study_keys():
            raise reject(f"{key}.{k}", "unknown key", f"keys of [{where}]: {', '.join(model.study_keys())}")
    try:
        return model.model_validate(table, context=dict(context))
    except ValidationError as exc:
        name, problem, allowed = _parts(model, exc.errors()[0], table, where)
        raise reject(f"{key}.{name}" if name else key, problem, allowed) from None
