"""Reading one TOML table of a study file by hand, key by key, for the sections that are not (yet) pydantic
models (``[study]``, ``[camera]``, ``[part_pose]``, ``[trajectory]``, ``[design]``): ``Table`` checks each key's
type and range and refuses keys it did not read; every error is one ``StudyError`` line (file, dotted key,
allowed values), as ``cadfeat.study.settings.validate_section`` gives for the model sections.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from typing import NoReturn, cast

import numpy as np

from cadfeat.study.settings import StudyError, range_text

__all__ = ["MISSING", "Table", "check_seed", "fmt", "is_num", "number_value", "vector_value"]

class _Missing:
    """The type of ``MISSING``."""


MISSING = _Missing()
"""The default of a required key."""


def check_seed(seed: object, label: str, key: str) -> None:
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= int(cast(int, seed)) < 2**32:
        raise StudyError(f"{label}: {key}: {seed!r} is not allowed; allowed: an integer in [0, 2^32)")


def fmt(value: object) -> str:
    return repr(value) if isinstance(value, str) else str(value)


class Table:
    """Reads one TOML table, checking each key; ``done()`` rejects keys that were not read."""

    def __init__(self, data: object, key: str, label: str, allowed: Sequence[str]) -> None:
        self.key, self.label, self.allowed = key, label, tuple(allowed)
        if not isinstance(data, Mapping):
            self.fail(key, f"expected a table, got {fmt(data)}", f"a table with keys {', '.join(allowed)}")
        self.data: dict[str, object] = dict(cast("Mapping[str, object]", data))  # (TOML keys are strings)
        unknown = sorted(set(self.data) - set(allowed))
        if unknown:
            self.fail(self.dotted(unknown[0]), "unknown key", f"keys of [{key}]: {', '.join(allowed)}")

    def dotted(self, name: str) -> str:
        return f"{self.key}.{name}" if self.key else name

    def fail(self, key: str, problem: str, allowed: str) -> NoReturn:
        raise StudyError(f"{self.label}: {key}: {problem}; allowed: {allowed}")

    def has(self, name: str) -> bool:
        return name in self.data

    def raw(self, name: str, default: object = None) -> object:
        return self.data.get(name, default)

    def string(self, name: str, default: str | _Missing = MISSING, choices: Sequence[str] | None = None,
               pattern: re.Pattern[str] | None = None, what: str = "a string") -> str:
        allowed = ", ".join(choices) if choices else what
        if name not in self.data:
            if isinstance(default, _Missing):
                self.fail(self.dotted(name), "missing", allowed)
            return default
        value = self.data[name]
        if not isinstance(value, str) or (choices is not None and value not in choices) or \
                (pattern is not None and not pattern.fullmatch(value)):
            self.fail(self.dotted(name), f"{fmt(value)} is not allowed", allowed)
        return value

    def number(self, name: str, default: float | None, lo: float | None = None, hi: float | None = None,
               lo_open: bool = False, required: bool = False) -> float | None:
        if name not in self.data:
            if required:
                self.fail(self.dotted(name), "missing", range_text(lo, hi, lo_open))
            return default
        return number_value(self.data[name], self.dotted(name), self.label, lo, hi, lo_open)

    def integer(self, name: str, default: int, lo: int, hi: int | None = None) -> int:
        if name not in self.data:
            return default
        value = self.data[name]
        text = f"an integer ≥ {lo}" if hi is None else f"an integer in [{lo}, {hi}]"
        if isinstance(value, bool) or not isinstance(value, int) or value < lo or (hi is not None and value > hi):
            self.fail(self.dotted(name), f"{fmt(value)} is not allowed", text)
        return int(value)

    def boolean(self, name: str, default: bool) -> bool:
        if name not in self.data:
            return default
        value = self.data[name]
        if not isinstance(value, bool):
            self.fail(self.dotted(name), f"{fmt(value)} is not allowed", "true or false")
        return value

    def vector(self, name: str, n: int, default: Sequence[float] | None) -> tuple[float, ...] | None:
        if name not in self.data:
            return None if default is None else tuple(float(x) for x in default)
        return vector_value(self.data[name], n, self.dotted(name), self.label)


def is_num(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def number_value(value: object, key: str, label: str, lo: float | None = None, hi: float | None = None,
            lo_open: bool = False) -> float:
    if not (isinstance(value, int | float) and not isinstance(value, bool)):  # (is_num)
        raise StudyError(f"{label}: {key}: {fmt(value)} is not allowed; allowed: {range_text(lo, hi, lo_open)}")
    ok = math.isfinite(value)
    if ok and lo is not None:
        ok = value > lo if lo_open else value >= lo
    if ok and hi is not None:
        ok = value <= hi
    if not ok:
        raise StudyError(f"{label}: {key}: {fmt(value)} is not allowed; allowed: {range_text(lo, hi, lo_open)}")
    return float(value)


def vector_value(value: object, n: int, key: str, label: str) -> tuple[float, ...]:
    is_list = isinstance(value, list)
    items = cast("list[object]", value) if is_list else []
    numbers = [v for v in items if isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)]
    if not is_list or len(items) != n or len(numbers) != n:
        raise StudyError(f"{label}: {key}: {fmt(cast(object, value))} is not allowed; allowed: a list of {n} finite "
                         "numbers")
    return tuple(float(v) for v in numbers)
