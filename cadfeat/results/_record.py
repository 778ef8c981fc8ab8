"""The base of every results.json object (``Record``) and its JSON value types."""

from __future__ import annotations

from typing import Any, TypeAlias

from pydantic import BaseModel, ConfigDict, JsonValue

__all__ = ["Json", "Number", "Record"]

Json: TypeAlias = JsonValue
"""A section (or value) kept as plain JSON: not typed here yet."""
Number: TypeAlias = int | float
"""A JSON number as written (an integer stays an integer, a float a float: strict, no coercion)."""


class Record(BaseModel):
    """A results.json object: strict (no coercion, so the data round-trips), keys not declared are kept."""

    model_config = ConfigDict(strict=True, extra="allow", frozen=False, ser_json_inf_nan="null")

    def to_data(self) -> dict[str, Any]:
        """The object as plain JSON data: the keys that were given (or set), nothing added."""
        return self.model_dump(exclude_unset=True)
