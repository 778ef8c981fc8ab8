"""cq-editor / CQGI scripts as cadfeat parts: a user's script, unchanged.

A CadQuery user's script has top-level constants and passes its result to ``show_object``::

    import cadquery as cq

    length = 80.0          # [40, 120] mm  Length of the block
    hole_dia = 22.0        # Diameter of the centre hole
    describe_parameter(hole_dia, "bore for the bearing")    # optional, CQGI's own description

    result = cq.Workplane("XY").box(length, 60, 10).faces(">Z").workplane().hole(hole_dia)
    show_object(result)

It loads through CadQuery's own gateway interface (``cadquery.cqgi.parse(source).build(build_parameters=...)``,
as cq-editor and cq-cli run it), so the script is never imported as a module. Its parameters are the
NUMERIC constants CQGI finds (``int`` / ``float``; strings, booleans and tuples stay as the script sets them):

- description: ``describe_parameter(name, "text")`` where given, else the constant's line comment (without the
  bounds);
- bounds, unit: the comment convention ``# [lower, upper] unit`` on the constant's line (``unit`` optional);
  without it the parameter is unbounded here and a study that varies it must give ``lower`` and ``upper`` in
  ``[design.parameters]`` (``cadfeat.study.schema`` says so by name);
- optional constants ``DESCRIPTION = "one line"``, ``FIXED_HOLES = "..."`` and ``VIEW_DIRECTION = (x, y, z)``
  mean what they mean in cadfeat's own protocol (``cadfeat.cad.parts``).

``load_cqgi_part(path)`` returns the same ``Part`` that ``load_part`` returns for a cadfeat script (its
``module`` is a small stand-in whose ``build(**params)`` runs CQGI), so time-limited builds
(``cadfeat.cad.parts.build_shape``: a worker process re-loads the part by path), the hole names (matched by
geometry to the default build, ``Part.name_holes``) and every study path work unchanged. ``load_part``
dispatches here when ``is_cqgi_script(path)``. The result shown must hold exactly one solid: a CadQuery
Workplane / Shape, or a build123d ``Part`` / ``Solid`` (any object whose ``wrapped`` is an OCP shape).

``getparams(path)`` is cq-cli's ``--getparams`` listing (the same JSON objects, from the same CQGI metadata).
"""

from __future__ import annotations

import ast
import contextlib
import math
import re
import sys
import types
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from cadfeat.errors import CadfeatError

__all__ = ["BOUNDS_COMMENT", "cad_shapes", "cqgi_parameters", "getparams", "is_cqgi_script", "load_cqgi_part",
           "unit_view_direction"]

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
#: The bounds comment on a constant's line: ``# [lower, upper] unit  description``.
BOUNDS_COMMENT = re.compile(rf"\[\s*({_NUM})\s*,\s*({_NUM})\s*\]\s*([^\W\d][\w/°]*)?")
_TEXT_CONSTANTS = ("DESCRIPTION", "FIXED_HOLES", "VIEW_DIRECTION")


def _tree(path: Path) -> ast.Module:
    try:
        return ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    except SyntaxError as exc:
        raise CadfeatError(f"{exc.filename or path}:{exc.lineno}: syntax error: {exc.msg}") from None


def is_cqgi_script(path: str | Path) -> bool:
    """Whether ``path`` is a cq-editor / CQGI script rather than a cadfeat part script: it calls
    ``show_object`` at module level and defines neither ``build`` nor ``PARAMETERS`` at the top level.
    A file that does not parse is not (``load_part`` then reports the syntax error)."""
    path = Path(path)
    if path.suffix != ".py" or not path.is_file():
        return False
    try:
        tree = ast.parse(path.read_text(encoding="utf-8"))
    except (SyntaxError, UnicodeDecodeError, ValueError):
        return False
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.name == "build":
            return False
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] \
            if isinstance(node, ast.AnnAssign) else []
        if any(isinstance(t, ast.Name) and t.id == "PARAMETERS" for t in targets):
            return False
    top = [n for n in tree.body if not isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef)]
    return any(isinstance(c, ast.Call) and isinstance(c.func, ast.Name) and c.func.id == "show_object"
               for n in top for c in ast.walk(n))


def _model(path: Path) -> Any:
    """CQGI's model of the script (parsing only: nothing of the script runs)."""
    from cadquery import cqgi

    _tree(path)  # a syntax error names the file and line
    return cqgi.parse(path.read_text(encoding="utf-8"))


def cqgi_parameters(path: str | Path, parameter_cls: Callable[..., Any], model: Any = None) -> dict[str, Any]:
    """The numeric constants CQGI finds in the script, as ``parameter_cls`` (``cadfeat.cad.parts.Parameter``,
    passed in so that this module does not import ``parts``, which dispatches here) by name, in the script's
    order; bounds and unit from the ``# [lower, upper] unit`` comment (else ±inf)."""
    from cadquery import cqgi

    path = Path(path)
    model = model if model is not None else _model(path)
    lines = path.read_text(encoding="utf-8").splitlines()
    out = {}
    for name, p in model.metadata.parameters.items():
        if p.varType is not cqgi.NumberParameterType or name in _TEXT_CONSTANTS:
            continue
        default = p.default_value
        is_int = isinstance(default, int) and not isinstance(default, bool)
        line = lines[p.ast_node.lineno - 1] if getattr(p.ast_node, "lineno", None) else ""
        comment = line.split("#", 1)[1].strip() if "#" in line else ""
        lower, upper, unit = -math.inf, math.inf, ""
        match = BOUNDS_COMMENT.search(comment)
        where = f"{path}:{getattr(p.ast_node, 'lineno', '?')}"
        if match:
            lower, upper = float(match.group(1)), float(match.group(2))
            unit = match.group(3) or ""
            comment = (comment[:match.start()] + comment[match.end():]).strip(" -:;,")
            if is_int:
                if lower != int(lower) or upper != int(upper):
                    raise CadfeatError(f"{where}: bounds comment [{match.group(1)}, {match.group(2)}] of the integer "
                                       f"constant {name!r} must be integers")
                lower, upper = int(lower), int(upper)
            if not lower <= default <= upper:
                raise CadfeatError(f"{where}: {name} = {default!r} is outside its bounds comment "
                                   f"[{match.group(1)}, {match.group(2)}]; allowed: lower <= value <= upper")
        description = p.desc if isinstance(p.desc, str) and p.desc else comment
        out[name] = parameter_cls(name, default, lower, upper, unit, description, is_int)
    return out


def _text_constants(model: Any, path: Path) -> dict[str, Any]:
    params = model.metadata.parameters
    out: dict[str, Any] = {}
    for key in ("DESCRIPTION", "FIXED_HOLES"):
        value = params[key].default_value if key in params else ""
        if not isinstance(value, str):
            raise CadfeatError(f"{path}: {key} must be a string, got {type(value).__name__}")
        out[key] = value.strip()
    view = params["VIEW_DIRECTION"].default_value if "VIEW_DIRECTION" in params else None
    out["VIEW_DIRECTION"] = unit_view_direction(view, str(path))
    return out



def unit_view_direction(view: Any, where: str) -> np.ndarray | None:
    """A part script's ``VIEW_DIRECTION`` (any 3-sequence, or None) as a read-only unit vector (part frame), or
    None; ``CadfeatError`` naming ``where`` if it is not a finite non-zero 3-vector. Shared by Python part
    scripts (``parts.load_part``) and CQGI scripts."""
    if view is None:
        return None
    arr = np.asarray(view, dtype=float)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)) or np.linalg.norm(arr) == 0:
        raise CadfeatError(f"{where}: VIEW_DIRECTION = {view!r} must be a non-zero 3-vector")
    arr = arr / np.linalg.norm(arr)
    arr.flags.writeable = False
    return arr


def cad_shapes(obj: Any) -> list[Any] | None:
    """The ``cadquery.Shape`` objects of a build result: a Workplane's shapes, a Shape, or an OCP shape cast to
    one; None for anything else. (``parts.load_part``'s scripts and CQGI's shown objects both go through it.)"""
    import cadquery as cq
    from OCP.TopoDS import TopoDS_Shape

    if isinstance(obj, cq.Workplane):
        return [v for v in obj.vals() if isinstance(v, cq.Shape)]
    if isinstance(obj, cq.Shape):
        return [obj]
    if isinstance(obj, TopoDS_Shape):
        return [cq.Shape.cast(obj)]
    return None


def _shown_shape(results: list[Any], where: str) -> Any:
    """The one solid among the objects the script passed to ``show_object`` (a ``cadquery.Solid``)."""
    import cadquery as cq
    from OCP.TopoDS import TopoDS_Shape

    solids = []
    for r in results:
        obj = r.shape
        if isinstance(getattr(obj, "wrapped", None), TopoDS_Shape) and not isinstance(obj, cq.Shape):
            obj = cq.Shape.cast(obj.wrapped)  # build123d Part / Solid / Compound
        solids += [s for shape in cad_shapes(obj) or [] for s in shape.Solids()]
    if len(solids) != 1:
        raise CadfeatError(f"{where} showed {len(results)} object(s) with {len(solids)} solid(s); a part must show "
                           "exactly one solid (show_object(result) once, result a Workplane / Shape / build123d Part)")
    return solids[0]


@contextlib.contextmanager
def _two_argument_describe() -> Iterator[None]:
    """CQGI reads ``describe_parameter(name, "text")`` (two arguments: its parser and cadquery's docs), but its
    run-time callback ``ScriptCallback.describe_parameter(self, var_data)`` takes one, so such a script fails in
    ``CQModel.build`` (cadquery 2.5-2.8; ``tests/cad/test_cqgi_parts.py`` pins it). During a build the callback
    accepts both forms; it does nothing either way, as CQGI's own."""
    from cadquery import cqgi

    original = cqgi.ScriptCallback.describe_parameter

    def describe_parameter(self: Any, var_data: Any, *args: Any, **kwargs: Any) -> None:
        """Does nothing (CQGI took the description from the syntax tree)."""

    cqgi.ScriptCallback.describe_parameter = describe_parameter
    try:
        yield
    finally:
        cqgi.ScriptCallback.describe_parameter = original


@contextlib.contextmanager
def _script_dir_on_path(path: Path) -> Iterator[None]:
    """The script's folder on ``sys.path`` during a build, as cq-cli sets it: a script may import its own
    helper modules from beside it."""
    folder = str(path.parent)
    added = folder not in sys.path
    if added:
        sys.path.insert(0, folder)
    try:
        yield
    finally:
        if added and folder in sys.path:
            sys.path.remove(folder)


def _builder(path: Path, model: Any, names: list[str]) -> Any:
    """``build(**params)``: run the script through CQGI with ``params`` and return its one solid."""

    def build(**params: Any) -> Any:
        unknown = sorted(set(params) - set(names))
        if unknown:
            raise CadfeatError(f"{path}: unknown parameter(s) {', '.join(unknown)}; allowed: {', '.join(names)}")
        # CQGI writes the values into its syntax tree: every build passes every parameter, so none keeps a
        # value of an earlier build.
        with _two_argument_describe(), _script_dir_on_path(path):
            result = model.build(build_parameters={k: params[k] for k in names if k in params})
        if not result.success:
            exc = result.exception
            raise CadfeatError(f"{path}: CQGI build raised {type(exc).__name__}: {exc}")
        return _shown_shape(result.results, f"{path}: the script")

    return build


def load_cqgi_part(path: str | Path, part_cls: Callable[..., Any], parameter_cls: Callable[..., Any]) -> Any:
    """A cq-editor / CQGI script as a ``part_cls`` (``cadfeat.cad.parts.Part``, whose ``load_part`` dispatches
    here and passes its classes in; nothing of the script runs here: CQGI only parses it; ``Part.build`` runs
    it). Raises ``CadfeatError`` naming the file for a syntax error or a bad bounds comment."""
    path = Path(path).resolve()
    model = _model(path)
    parameters = cqgi_parameters(path, parameter_cls, model)
    text = _text_constants(model, path)
    module = types.ModuleType(f"cadfeat_cqgi_{path.stem}")
    module.__file__ = str(path)
    module.build = _builder(path, model, list(parameters))  # type: ignore[attr-defined]
    module.PARAMETERS = {n: {"default": p.default, "bounds": (p.lower, p.upper), "unit": p.unit,  # type: ignore
                             "description": p.description} for n, p in parameters.items()}
    module.CQGI_MODEL = model  # type: ignore[attr-defined]
    return part_cls(path.stem, path, parameters, text["DESCRIPTION"], text["FIXED_HOLES"], text["VIEW_DIRECTION"],
                module)


def getparams(path: str | Path) -> list[dict[str, Any]]:
    """cq-cli's ``--getparams`` listing of a CQGI script: one object per constant CQGI finds, with ``type``
    (number | string | boolean; none for tuples), ``name``, ``caption`` (the ``describe_parameter`` text),
    ``initial`` (the default when it is truthy) and ``min`` / ``max`` / ``step`` from CQGI's valid values —
    the fields and rules of cq-cli's ``main.py``."""
    model = _model(Path(path))
    kinds = {"NumberParameterType": "number", "StringParameterType": "string", "BooleanParameterType": "boolean"}
    out = []
    for p in model.metadata.parameters.values():
        entry: dict[str, Any] = {}
        if p.varType.__name__ in kinds:
            entry["type"] = kinds[p.varType.__name__]
        entry["name"] = p.name
        if p.desc:
            entry["caption"] = p.desc
        if p.default_value:
            entry["initial"] = p.default_value
        if p.valid_values:
            entry["min"], entry["max"] = p.valid_values[0], p.valid_values[-1]
            entry["step"] = entry["max"] - entry["min"] if entry["max"] - entry["min"] > 0 else 1
        out.append(entry)
    return out
