"""``[design]`` of a study file — what may change — declared once as ``Settings`` models.

Script parts vary their parameters: ``parameters = ["d", ...]`` or ``[design.parameters] d = {lower, upper,
standard_sizes, start}`` (``ParameterSpec``); the bounds must lie inside the part's own (validation context
``part_params``: the script's ``PARAMETERS``, read without running it, ``cadfeat.study.part_parameters``).
STEP parts move or resize holes: ``holes = [{select = 2 | "H2" | [x, y, z], move, resize, max_offset_mm}]``
(``HoleSpec``) and may give ``view_direction``. Both: ``standard_diameters_mm`` (STEP), ``fixed`` and
``patterns`` (hole selectors). Which keys apply depends on the part (context ``part_kind``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Annotated, ClassVar, TypeGuard, cast

from pydantic import Field, JsonValue, ValidationInfo, WithJsonSchema, field_validator, model_validator

from cadfeat.settings import (
    Settings,
    ValidationContext,
    boolean,
    context_of,
    number,
    range_text,
    reject,
    validate_nested,
)
from cadfeat.study.part_parameters import PartParameter

__all__ = ["DesignSpec", "HoleSpec", "ParameterSpec", "Selector"]

Selector = int | str | tuple[float, float, float]
"""A hole: 1-based index, name ("H2") or position (x, y, z) in mm (part frame)."""
_SELECTOR_TEXT = "a 1-based hole index, a hole name (\"H2\") or a position [x, y, z] in mm"
_SELECTOR_SCHEMA: dict[str, JsonValue] = {"anyOf": [
    {"type": "integer", "minimum": 1}, {"type": "string", "minLength": 1},
    {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}]}


def _is_list(value: object) -> TypeGuard[list[object]]:
    return isinstance(value, list)


def _is_seq(value: object) -> TypeGuard[list[object] | tuple[object, ...]]:
    return isinstance(value, list | tuple)


def _fmt(value: object) -> str:
    return repr(value) if isinstance(value, str) else str(value)


def _is_num(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _vector(value: object, n: int, key: str) -> tuple[float, ...]:
    if not _is_seq(value) or len(value) != n or not all(_is_num(v) for v in value):
        raise reject(key, f"{_fmt(value)} is not allowed", f"a list of {n} finite numbers")
    return tuple(float(cast(float, v)) for v in value)


def selector(value: object, key: str) -> Selector:
    """A hole selector of the study file (a TOML array becomes a position tuple)."""
    if isinstance(value, int) and not isinstance(value, bool):
        if value < 1:
            raise reject(key, f"{value} is not allowed",
                         "a 1-based hole index ≥ 1, a hole name (\"H2\") or a position [x, y, z] in mm")
        return value
    if isinstance(value, str) and value.strip():
        return value
    if _is_seq(value):
        x, y, z = _vector(value, 3, key)
        return (x, y, z)
    raise reject(key, f"{_fmt(value)} is not allowed", _SELECTOR_TEXT)


def _selectors(value: object, key: str) -> tuple[Selector, ...]:
    if not _is_seq(value):
        raise reject(key, f"{_fmt(value)} is not allowed", "a list of hole selectors (index, name or [x, y, z])")
    return tuple(selector(v, f"{key}[{i}]") for i, v in enumerate(value))


def _echo_selector(s: Selector) -> object:
    return list(s) if isinstance(s, tuple) else s


class HoleSpec(Settings):
    """A movable STEP hole (``design.holes[i]``): ``select`` is a 1-based index, a name ("H2") or a position
    (x, y, z) in mm; it moves and/or is resized, at most ``max_offset_mm`` from where it is."""

    section: ClassVar[str] = "hole"

    select: Annotated[Selector, WithJsonSchema(_SELECTOR_SCHEMA)] = Field(
        description="which hole", json_schema_extra={"x-allowed": _SELECTOR_TEXT})
    move: bool = boolean(True)
    resize: bool = boolean(False)
    max_offset_mm: float | None = number(None, 0.0, lo_open=True)

    @field_validator("select", mode="before")
    @classmethod
    def _select(cls, value: object) -> Selector:
        return selector(value, "select")

    @model_validator(mode="after")
    def _changes(self) -> HoleSpec:
        if not (self.move or self.resize):
            raise reject("", "neither move nor resize is true", "move = true and/or resize = true")
        return self

    def echo(self) -> dict[str, object]:
        return {"select": _echo_selector(self.select), "move": self.move, "resize": self.resize,
                "max_offset_mm": self.max_offset_mm}


class ParameterSpec(Settings):
    """A varying part parameter with its study bounds (``int`` bounds for integer parameters), inside the
    part's own (validation context ``parameter``: the script's ``PartParameter``; ``name``, ``default``,
    ``unit`` and ``is_int`` come from it). ``start``: the design the study starts from (None: the default)."""

    section: ClassVar[str] = "parameter"

    lower: float | int = Field(json_schema_extra={"x-allowed": "a number within the part's bounds"})
    upper: float | int = Field(json_schema_extra={"x-allowed": "a number within the part's bounds"})
    standard_sizes: tuple[float, ...] | None = Field(None, json_schema_extra={
        "x-allowed": "a non-empty list of values in [lower, upper]"})
    start: float | int | None = Field(None, json_schema_extra={"x-allowed": "a number in [lower, upper]"})
    name: str = Field("", json_schema_extra={"x-internal": True})
    default: float | int = Field(0.0, json_schema_extra={"x-internal": True})
    unit: str = Field("", json_schema_extra={"x-internal": True})
    is_int: bool = boolean(False, internal=True)

    @model_validator(mode="before")
    @classmethod
    def _in_part_bounds(cls, data: object, info: ValidationInfo) -> object:
        p = context_of(info).get("parameter")
        if not isinstance(p, PartParameter) or not isinstance(data, Mapping):
            return data
        table = cast("Mapping[str, object]", data)
        lo, hi = (_bound(table, which, p) for which in ("lower", "upper"))
        if not (math.isfinite(lo) and math.isfinite(hi)):  # a CQGI constant without a bounds comment
            raise reject("", f"{p.name} has no bounds in {context_of(info).get('part', 'the part')}",
                         "lower and upper here (or a '# [lower, upper] unit' comment on the constant's line in "
                         "the script)")
        if p.is_int:
            lo, hi = int(round(lo)), int(round(hi))
        if not lo < hi:
            raise reject("", f"lower {lo} is not below upper {hi}", f"lower < upper within [{p.lower}, {p.upper}]")
        sizes = None
        if "standard_sizes" in table:
            v = table["standard_sizes"]
            if not _is_list(v) or not v or not all(_is_num(s) and lo <= cast(float, s) <= hi for s in v):
                raise reject("standard_sizes", f"{_fmt(v)} is not allowed",
                             f"a non-empty list of values in [{lo}, {hi}]")
            sizes = tuple(sorted(float(cast(float, s)) for s in v))
        start = table.get("start")
        if start is not None:
            if not _is_num(start) or not lo <= cast(float, start) <= hi:
                raise reject("start", f"{_fmt(start)} is not allowed", range_text(float(lo), float(hi)))
            if p.is_int:
                if float(cast(float, start)) != round(cast(float, start)):
                    raise reject("start", f"{start!r} is not an integer", f"an integer in [{lo}, {hi}]")
                start = int(round(cast(float, start)))
        return {"lower": lo, "upper": hi, "standard_sizes": sizes, "start": start, "name": p.name,
                "default": p.default, "unit": p.unit, "is_int": p.is_int}

    def echo(self) -> dict[str, object]:
        return {"lower": self.lower, "upper": self.upper,
                **({"standard_sizes": list(self.standard_sizes)} if self.standard_sizes else {}),
                **({"start": self.start} if self.start is not None else {})}


def _bound(table: Mapping[str, object], which: str, p: PartParameter) -> float | int:
    """The study's bound ``which`` (a float), or the part's own as declared (int or float) when not given."""
    if which not in table:
        return p.lower if which == "lower" else p.upper
    value = table[which]
    lo, hi = float(p.lower), float(p.upper)
    if not _is_num(value) or not lo <= cast(float, value) <= hi:
        raise reject(which, f"{_fmt(value)} is not allowed", range_text(lo, hi))
    v = float(cast(float, value))
    if p.is_int and v != round(v):
        raise reject(which, f"{value!r} is not an integer",
                     f"an integer in [{p.lower}, {p.upper}] ({p.name} is an integer parameter)")
    return v


_PARAMETERS_SCHEMA: dict[str, JsonValue] = {
    "anyOf": [{"type": "array", "items": {"type": "string"}},
              {"type": "object", "additionalProperties": {
                  "type": "object", "additionalProperties": False,
                  "properties": {"lower": {"type": "number"}, "upper": {"type": "number"},
                                 "standard_sizes": {"type": "array", "items": {"type": "number"}},
                                 "start": {"type": "number"}}}}],
    "description": "script parts: the parameters that vary (names, or name = {lower, upper, standard_sizes, start})"}
_HOLES_SCHEMA: dict[str, JsonValue] = {
    "type": "array", "minItems": 1, "description": "STEP parts: the holes that move or are resized",
    "items": {"type": "object", "additionalProperties": False, "required": ["select"],
              "properties": {"select": _SELECTOR_SCHEMA, "move": {"type": "boolean"}, "resize": {"type": "boolean"},
                             "max_offset_mm": {"type": "number", "exclusiveMinimum": 0}}}}


class DesignSpec(Settings):
    """``[design]``: what may change (validation context: ``part_kind``, ``part_params``, ``part``, ``limits``)."""

    section: ClassVar[str] = "design"

    parameters: Annotated[tuple[ParameterSpec, ...], WithJsonSchema(_PARAMETERS_SCHEMA)] = Field(
        (), json_schema_extra={"x-allowed": "a list of names or a table name = {lower, upper, standard_sizes}"})
    holes: Annotated[tuple[HoleSpec, ...], WithJsonSchema(_HOLES_SCHEMA)] = Field(
        (), json_schema_extra={"x-allowed": "a list of tables {select = index | name | [x, y, z], move, resize, "
                                            "max_offset_mm}"})
    standard_diameters_mm: tuple[float, ...] | None = Field(None, json_schema_extra={
        "x-allowed": "a non-empty list of positive diameters in mm"})
    fixed: Annotated[tuple[Selector, ...], WithJsonSchema({"type": "array", "items": _SELECTOR_SCHEMA})] = Field(
        (), json_schema_extra={"x-allowed": "a list of hole selectors (index, name or [x, y, z])"})
    patterns: Annotated[tuple[tuple[Selector, ...], ...], WithJsonSchema(
        {"type": "array", "items": {"type": "array", "items": _SELECTOR_SCHEMA, "minItems": 2}})] = Field(
        (), json_schema_extra={"x-allowed": "a list of lists of hole selectors"})
    view_direction: tuple[float, float, float] | None = Field(None, json_schema_extra={
        "x-allowed": "a non-zero direction [x, y, z]"}, description="STEP parts: unit direction (part frame) from "
        "the part towards the camera; picks the entrance end of through holes. Default: from the trajectory")

    @model_validator(mode="before")
    @classmethod
    def _read(cls, data: object, info: ValidationInfo) -> object:
        """The TOML table (names, tables, arrays) as the model's fields, checked against the part."""
        context = context_of(info)
        if "part_kind" not in context or not isinstance(data, Mapping):
            return data
        t = cast("Mapping[str, object]", data)
        step = context["part_kind"] == "step"
        out: dict[str, object] = {}
        holes: tuple[HoleSpec, ...] = ()
        if step:
            if "parameters" in t:
                raise reject("parameters", "only for part scripts (STEP parts have no parameters)", "design.holes")
            holes = _holes(t.get("holes"), context)
            out["holes"] = holes
        else:
            if "holes" in t:
                raise reject("holes", "only for STEP parts (script parts vary their parameters)", "design.parameters")
            if "standard_diameters_mm" in t:
                raise reject("standard_diameters_mm", "only for STEP parts (a script part's sizes are its "
                             "parameters)", "design.parameters.<name>.standard_sizes")
            out["parameters"] = _parameters(t.get("parameters"), context)
        if "standard_diameters_mm" in t:
            v = t["standard_diameters_mm"]
            if not _is_list(v) or not v or not all(_is_num(d) and cast(float, d) > 0 for d in v):
                raise reject("standard_diameters_mm", f"{_fmt(v)} is not allowed",
                             "a non-empty list of positive diameters in mm")
            out["standard_diameters_mm"] = tuple(sorted(float(cast(float, d)) for d in v))
        fixed = _selectors(t.get("fixed", []), "fixed")
        raw = t.get("patterns", [])
        if not _is_list(raw):
            raise reject("patterns", f"{_fmt(raw)} is not allowed", "a list of lists of hole selectors")
        patterns = tuple(_selectors(p, f"patterns[{i}]") for i, p in enumerate(raw))
        for i, p in enumerate(patterns):
            if len(p) < 2:
                raise reject(f"patterns[{i}]", "a pattern needs at least two holes", "a list of ≥ 2 hole selectors")
        out["fixed"], out["patterns"] = fixed, patterns
        if step:
            _check_step_design(holes, fixed)
        if "view_direction" in t:
            if not step:
                raise reject("view_direction", "only for STEP parts (a part script gives VIEW_DIRECTION)",
                             "VIEW_DIRECTION in the part script")
            view = _vector(t["view_direction"], 3, "view_direction")
            norm = math.sqrt(sum(v * v for v in view))
            if norm == 0:
                raise reject("view_direction", "[0, 0, 0] is not allowed", "a non-zero direction [x, y, z]")
            out["view_direction"] = tuple(v / norm for v in view)
        return out

    def echo(self) -> dict[str, object]:
        """The design as plain data for results.json ``inputs.design`` (loads again as the same design)."""
        out: dict[str, object] = {}
        if self.parameters:
            out["parameters"] = {p.name: p.echo() for p in self.parameters}
        if self.holes:
            out["holes"] = [h.echo() for h in self.holes]
        if self.view_direction is not None:
            out["view_direction"] = list(self.view_direction)
        out.update({"standard_diameters_mm": None if self.standard_diameters_mm is None
                    else list(self.standard_diameters_mm),
                    "fixed": [_echo_selector(s) for s in self.fixed],
                    "patterns": [[_echo_selector(s) for s in p] for p in self.patterns]})
        return out


def _too_many(n: int, key: str, what: str, context: ValidationContext) -> None:
    limit = context.get("limits", {}).get("design_variables")
    if limit is not None and n > limit:
        raise reject(key, f"{n} {what} is more than the limit of {limit:,}",
                     f"at most {limit:,} (cadfeat.study.schema.LIMITS['design_variables'])")


def _parameters(raw: object, context: ValidationContext) -> tuple[ParameterSpec, ...]:
    params = cast("Mapping[str, PartParameter]", context.get("part_params", {}))
    part = context.get("part", "the part")
    names_allowed = ", ".join(params) or "(the part has no parameters)"
    if raw is None:
        raise reject("parameters", "missing", f"a list or table of parameter names of {part}: {names_allowed}")
    if _is_list(raw):
        _too_many(len(raw), "parameters", "parameters", context)
        names = raw
        if not all(isinstance(n, str) for n in names):
            raise reject("parameters", f"{_fmt(raw)} is not allowed", f"parameter names: {names_allowed}")
        table: dict[str, object] = {cast(str, n): {} for n in names}
        if len(table) != len(names):
            raise reject("parameters", "a parameter is listed twice", f"distinct names of {names_allowed}")
    elif isinstance(raw, Mapping):
        table = dict(cast("Mapping[str, object]", raw))
        _too_many(len(table), "parameters", "parameters", context)
    else:
        raise reject("parameters", f"{_fmt(raw)} is not allowed",
                     "a list of names or a table name = {lower, upper, standard_sizes}")
    if not table:
        raise reject("parameters", "empty", f"at least one of {names_allowed}")
    out: list[ParameterSpec] = []
    for name, spec in table.items():
        if name not in params:
            raise reject(f"parameters.{name}", f"unknown parameter of {part}", names_allowed)
        out.append(validate_nested(ParameterSpec, spec, f"parameters.{name}", "design",
                                   {**context, "parameter": params[name]}))
    return tuple(out)


def _holes(raw: object, context: ValidationContext) -> tuple[HoleSpec, ...]:
    if _is_list(raw):
        _too_many(len(raw), "holes", "holes", context)
    if not _is_list(raw) or not raw:
        raise reject("holes", "missing or empty" if raw is None or raw == [] else f"{_fmt(raw)} is not allowed",
                     "a list of tables {select = index | name | [x, y, z], move, resize, max_offset_mm}")
    return tuple(validate_nested(HoleSpec, spec, f"holes[{i}]", "design", context) for i, spec in enumerate(raw))


def _check_step_design(holes: tuple[HoleSpec, ...], fixed: tuple[Selector, ...]) -> None:
    seen: dict[Selector, int] = {}
    for i, h in enumerate(holes):
        if h.select in seen:
            raise reject(f"holes[{i}].select", f"hole {h.select!r} is already design.holes[{seen[h.select]}]",
                         "each hole once")
        seen[h.select] = i
    for i, s in enumerate(fixed):
        if s in seen:
            raise reject(f"fixed[{i}]", f"hole {s!r} is also movable (design.holes[{seen[s]}])",
                         "fixed holes that are not in design.holes")
