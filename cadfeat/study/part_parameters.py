"""A part script's ``PARAMETERS`` table, read for a study without running the script when it is a literal.

``part_parameters(path)`` parses the script (``ast``) and evaluates the table with ``ast.literal_eval``; a table
that is computed or changed after its assignment is read by importing the script (``cadfeat.cad.parts``).
"""

from __future__ import annotations

import ast
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

from cadfeat.cad.cqgi_parts import is_cqgi_script
from cadfeat.study.settings import StudyError
from cadfeat.study.table import is_num

__all__ = ["PartParameter", "part_parameters"]


@dataclass(frozen=True)
class PartParameter:
    """A part script's parameter as declared in its ``PARAMETERS`` table."""

    name: str
    default: float | int
    lower: float | int
    upper: float | int
    unit: str
    description: str
    is_int: bool


def part_parameters(path: str | Path, time_limit_s: float | None = None) -> dict[str, PartParameter]:
    """A part script's ``PARAMETERS`` (name → ``PartParameter``), read without running the script when the
    table is a literal (``ast.literal_eval``), else via ``cadfeat.cad.parts.load_part`` (its import in a worker
    process within ``time_limit_s`` seconds; None: in this process).

    Raises ``StudyError`` naming the script for a syntax error, a missing or malformed table.
    """
    path = Path(path)
    try:
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    except SyntaxError as exc:
        raise StudyError(f"{path}: line {exc.lineno}: syntax error: {exc.msg}") from exc
    node = next((n.value for n in tree.body if isinstance(n, ast.Assign | ast.AnnAssign)
                 and any(isinstance(t, ast.Name) and t.id == "PARAMETERS"
                         for t in (n.targets if isinstance(n, ast.Assign) else [n.target]))), None)
    if node is None and _is_cqgi(path):
        return _parameters_by_loading(path, time_limit_s)  # a cq-editor / CQGI script: its constants (cqgi_parts)
    if node is None:
        raise StudyError(f"{path}: PARAMETERS: missing; allowed: a module-level dict "
                         "{name: {default, bounds, unit, description}}")
    if _mutated(tree):
        return _parameters_by_loading(path, time_limit_s)
    try:
        table = ast.literal_eval(node)
    except ValueError:
        return _parameters_by_loading(path, time_limit_s)
    return _parse_parameters(table, path)


_MUTATORS = {"update", "setdefault", "pop", "popitem", "clear", "__setitem__"}


def _is_cqgi(path: Path) -> bool:
    return is_cqgi_script(path)


def _mutated(tree: ast.Module) -> bool:
    """Whether module-level code (outside functions/classes) changes ``PARAMETERS`` after assigning it:
    ``PARAMETERS[k] = ...``, ``del PARAMETERS[k]``, ``PARAMETERS.update(...)``, or a second assignment."""
    assigned = 0
    for stmt in tree.body:
        if isinstance(stmt, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            continue
        for n in ast.walk(stmt):
            if isinstance(n, ast.Name) and n.id == "PARAMETERS" and isinstance(n.ctx, ast.Store):
                assigned += 1
            elif isinstance(n, ast.Subscript) and isinstance(n.value, ast.Name) and n.value.id == "PARAMETERS" \
                    and isinstance(n.ctx, ast.Store | ast.Del):
                return True
            elif isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name) and n.value.id == "PARAMETERS" \
                    and n.attr in _MUTATORS:
                return True
    return assigned > 1


def _parameters_by_loading(path: Path, time_limit_s: float | None) -> dict[str, PartParameter]:
    from cadfeat.cad.parts import load_part  # runs the script (imports cadquery): only for non-literal tables

    part = load_part(path, time_limit_s)
    return {name: PartParameter(name, p.default, p.lower, p.upper, getattr(p, "unit", ""),
                                getattr(p, "description", ""), bool(getattr(p, "is_int", False)))
            for name, p in part.parameters.items()}


def _parse_parameters(table: object, path: Path) -> dict[str, PartParameter]:
    allowed = "a dict {name: {default, bounds: (lower, upper), unit, description}}"
    if not isinstance(table, Mapping):
        raise StudyError(f"{path}: PARAMETERS: not a dict; allowed: {allowed}")
    out: dict[str, PartParameter] = {}
    for name, spec in cast("Mapping[object, object]", table).items():
        if not isinstance(name, str) or not isinstance(spec, Mapping) or "default" not in spec or \
                "bounds" not in spec or not isinstance(spec["bounds"], Sequence) or \
                len(cast("Sequence[object]", spec["bounds"])) != 2:
            raise StudyError(f"{path}: PARAMETERS.{name}: malformed; allowed: {allowed}")
        spec = cast("Mapping[str, object]", spec)
        default, (lo, hi) = spec["default"], cast("Sequence[object]", spec["bounds"])
        if not (is_num(default) and is_num(lo) and is_num(hi)):
            raise StudyError(f"{path}: PARAMETERS.{name}: default and bounds must be numbers; allowed: {allowed}")
        is_int = isinstance(default, int)
        out[name] = PartParameter(name, cast(float, default), cast(float, lo), cast(float, hi),
                                  str(spec.get("unit", "")), str(spec.get("description", "")), is_int)
    return out
