"""The settings base (moved to ``cadfeat.settings`` so every layer declares its configuration with it)."""

from __future__ import annotations

from cadfeat.settings import (
    Settings,
    StudyError,
    Tuple,
    boolean,
    choice,
    context_of,
    integer,
    number,
    range_text,
    reject,
    seed_from_context,
    validate_section,
)

__all__ = ["Settings", "StudyError", "Tuple", "boolean", "choice", "context_of", "integer", "number", "range_text",
           "reject", "seed_from_context", "validate_section"]
