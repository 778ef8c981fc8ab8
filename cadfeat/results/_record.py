"""The base of every results.json object (``Record``) and its JSON value types."""

from __future__ import annotations

from typing import Any, TypeAlias

from pydantic import BaseModel, ConfigDict, JsonValue

__all__ = ["Json", "JsonDict", "Number", "Record"]

Json: TypeAlias = JsonValue
"""A section (or value) kept as plain JSON: not typed here yet."""
JsonDict: TypeAlias = dict[str, object]
"""A JSON object being built and passed on to be written (a results.json section, an optimiser's history entry, a
``score_design`` answer): plain data whose numbers may still be numpy scalars or arrays until
``study.outputs.plain``. Its values are opaque (``object``): a reader that looks inside narrows them, or the
object has a ``TypedDict`` of its keys; its typed form, where there is one, is a ``Record`` of this package
(``StudyResults``)."""
Number: TypeAlias = int | float
"""A JSON number as written (an integer stays an integer, a float a float: strict, no coercion)."""


class Record(BaseModel):
    """A results.json object: strict (no coercion, so the data round-trips), keys not declared are kept."""

    model_config = ConfigDict(strict=True, extra="allow", frozen=False, ser_json_inf_nan="null")

    def to_data(self) -> dict[str, Any]:
        """The object as plain JSON data: the keys that were given (or set), nothing added."""
        return self.model_dump(exclude_unset=True)
