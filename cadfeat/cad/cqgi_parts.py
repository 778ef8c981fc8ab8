"""cq-editor / CQGI scripts as cadfeat parts: a user's script, unchanged.

A CadQuery user's script has top-level constants and passes its result to ``show_object``::

    import cadquery as cq

    length = 80.0          # [40, 120] mm  Length of the block
    hole_dia = 22.0        # Diameter of the centre hole
    describe_parameter(hole_dia, "bore for the bearing")    # optional, CQGI's own description

    result = cq.Workplane("XY").box(length, 60, 10).faces(">Z").workplane().hole(hole_dia)
    show_object(result)

It loads through CadQuery's own gateway interface (``cadquery.cqgi.parse(source).build()``, as cq-editor and cq-cli
run it), so the script is never imported as a module. A script that names cq-editor's ``__name__`` (``if __name__ ==
"__cq_main__": show_object(result)``) runs with that ``__name__``, as cq-editor runs it; a script that calls
cq-editor's ``log`` gets one. Its constants are read from the script's own syntax tree (``script_constants``): every
top-level ``name = literal`` or ``name: type = literal`` whose literal is an int, float (a leading ``-`` / ``+``
included), bool, str or a tuple of those. CQGI's own finder misses negative numbers (``-12.0`` is a unary minus, not
a constant) and annotated assignments, and its ``build(build_parameters=...)`` substitutes only what it found; here
a build writes every value into a copy of the syntax tree (the constant's assignment, ``_substituted``) and hands
that tree to CQGI. The part's parameters are the NUMERIC constants (``int`` / ``float``; strings, booleans and
tuples stay as the script sets them):

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

``getparams(path)`` is cq-cli's ``--getparams`` listing (the same JSON objects) of every constant, each with its
value (``initial``, also when it is 0 or False, which cq-cli drops).
"""

from __future__ import annotations

import ast
import contextlib
import copy
import io
import math
import re
import sys
import types
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import JsonDict

__all__ = ["BOUNDS_COMMENT", "ScriptConstant", "cad_shapes", "cqgi_parameters", "getparams", "is_cqgi_script",
           "load_cqgi_part", "script_constants", "unit_view_direction"]

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
    ``show_object`` (at module level, or in a function of its own that it calls: ``def main(): ...
    show_object(part)``) and does not define ``PARAMETERS`` at the top level (cadfeat's protocol: ``PARAMETERS``
    and ``build``; a cq-editor script may have a helper named ``build`` of its own). A file that does not parse
    is not (``load_part`` then reports the syntax error)."""
    path = Path(path)
    if path.suffix != ".py" or not path.is_file():
        return False
    try:
        tree = ast.parse(path.read_text(encoding="utf-8"))
    except (SyntaxError, UnicodeDecodeError, ValueError):
        return False
    for node in tree.body:
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] \
            if isinstance(node, ast.AnnAssign) else []
        if any(isinstance(t, ast.Name) and t.id == "PARAMETERS" for t in targets):
            return False
    return any(isinstance(c, ast.Call) and isinstance(c.func, ast.Name) and c.func.id == "show_object"
               for c in ast.walk(tree))


@dataclass(frozen=True)
class ScriptConstant:
    """One top-level constant of a CQGI script: ``name = value`` (or ``name: type = value``, or one name of
    ``a, b = 1.0, 2.0``) with a literal value (int, float, bool, str or a tuple of those; a leading ``-`` / ``+``
    included). ``statement`` is its statement's index in the module body, ``element`` its index in a tuple
    unpacking (None for one name), ``lineno`` its 1-based line."""

    name: str
    value: Any
    statement: int
    element: int | None
    lineno: int


def _literal(node: ast.expr) -> tuple[bool, Any]:
    """``(True, value)`` if ``node`` is a literal int / float / bool / str, a signed number (``-12.0``) or a
    tuple of those; else ``(False, None)``."""
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float | str):  # bool is an int
        return True, node.value
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd) \
            and isinstance(node.operand, ast.Constant) and isinstance(node.operand.value, int | float) \
            and not isinstance(node.operand.value, bool):
        return True, -node.operand.value if isinstance(node.op, ast.USub) else node.operand.value
    if isinstance(node, ast.Tuple):
        items = [_literal(e) for e in node.elts]
        if all(ok for ok, _ in items):
            return True, tuple(v for _, v in items)
    return False, None


def script_constants(tree: ast.Module) -> dict[str, ScriptConstant]:
    """The top-level constants of a script's syntax tree, by name in the order of their first assignment (a
    name assigned a literal again keeps its last literal, as CQGI does; one later assigned anything else is no
    constant)."""
    out: dict[str, ScriptConstant] = {}
    for i, node in enumerate(tree.body):
        if isinstance(node, ast.AnnAssign) and node.value is not None:
            targets, value = [node.target], node.value
        elif isinstance(node, ast.Assign) and len(node.targets) == 1:
            targets, value = node.targets, node.value
        else:
            if isinstance(node, ast.Assign | ast.AugAssign | ast.AnnAssign):  # a = b = 1.0, a += 1, a: int
                for t in node.targets if isinstance(node, ast.Assign) else [node.target]:
                    for n in ast.walk(t):
                        if isinstance(n, ast.Name):
                            out.pop(n.id, None)
            continue
        target = targets[0]
        if isinstance(target, ast.Name):
            _record(out, target.id, value, i, None, node.lineno)
        elif isinstance(target, ast.Tuple) and isinstance(value, ast.Tuple) and len(target.elts) == len(value.elts):
            for k, (t, v) in enumerate(zip(target.elts, value.elts, strict=True)):
                if isinstance(t, ast.Name):
                    _record(out, t.id, v, i, k, node.lineno)
    return out


def _record(out: dict[str, ScriptConstant], name: str, value: ast.expr, index: int, element: int | None,
            lineno: int) -> None:
    """``name = value`` (element ``element`` of a tuple assignment, statement ``index``): a constant when the value
    is a literal, else a name that is no constant (a later computed assignment replaces an earlier literal)."""
    ok, literal = _literal(value)
    if ok:
        out[name] = ScriptConstant(name, literal, index, element, lineno)
    else:
        out.pop(name, None)


def _descriptions(tree: ast.Module) -> dict[str, str]:
    """``describe_parameter(name, "text")`` calls anywhere in the script, by name (CQGI's own convention)."""
    out = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "describe_parameter" \
                and len(node.args) >= 2 and isinstance(node.args[0], ast.Name) \
                and isinstance(node.args[1], ast.Constant) and isinstance(node.args[1].value, str):
            out[node.args[0].id] = node.args[1].value
    return out


def _substituted(tree: ast.Module, constants: dict[str, ScriptConstant], values: JsonDict) -> ast.Module:
    """A copy of ``tree`` with each constant named in ``values`` assigned that value (a literal in place of
    the script's own: ``-12.0`` and ``x: float = 90.0`` are written like any other constant)."""
    out = copy.deepcopy(tree)
    for name, value in values.items():
        c = constants[name]
        node = out.body[c.statement]
        assert isinstance(node, ast.Assign | ast.AnnAssign) and node.value is not None
        old = node.value if c.element is None else node.value.elts[c.element]  # type: ignore[attr-defined]
        new = ast.copy_location(ast.Constant(value=value), old)
        if c.element is None:
            node.value = new
        else:
            node.value.elts[c.element] = new  # type: ignore[attr-defined]
    return ast.fix_missing_locations(out)


@dataclass(frozen=True)
class _Script:
    """A parsed CQGI script: its syntax tree, its constants and their descriptions."""

    path: Path
    tree: ast.Module
    constants: dict[str, ScriptConstant]
    descriptions: dict[str, str]


def _script(path: Path) -> _Script:
    tree = _tree(path)
    return _Script(path, tree, script_constants(tree), _descriptions(tree))


def _model(path: Path) -> Any:
    """CQGI's model of the script (parsing only: nothing of the script runs). CQGI prints, to stdout, an
    assignment it cannot read (a tuple with a negative number): that text is dropped (the constants are read
    here, ``script_constants``), so ``cadfeat parts --params`` prints JSON only."""
    from cadquery import cqgi

    _tree(path)  # a syntax error names the file and line
    with contextlib.redirect_stdout(io.StringIO()):
        return cqgi.parse(path.read_text(encoding="utf-8"))


def cqgi_parameters(path: str | Path, parameter_cls: Callable[..., Any], script: _Script | None = None
                    ) -> JsonDict:
    """The numeric constants of the script (``script_constants``: negative and annotated ones included), as
    ``parameter_cls`` (``cadfeat.cad.parts.Parameter``, passed in so that this module does not import ``parts``,
    which dispatches here) by name, in the script's order; bounds and unit from the ``# [lower, upper] unit``
    comment (else ±inf)."""
    path = Path(path)
    script = script if script is not None else _script(path)
    lines = path.read_text(encoding="utf-8").splitlines()
    out = {}
    for name, c in script.constants.items():
        default = c.value
        if isinstance(default, bool) or not isinstance(default, int | float) or name in _TEXT_CONSTANTS:
            continue
        is_int = isinstance(default, int)
        line = lines[c.lineno - 1]
        comment = line.split("#", 1)[1].strip() if "#" in line else ""
        lower, upper, unit = -math.inf, math.inf, ""
        match = BOUNDS_COMMENT.search(comment)
        where = f"{path}:{c.lineno}"
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
        description = script.descriptions.get(name) or comment
        out[name] = parameter_cls(name, default, lower, upper, unit, description, is_int)
    return out


def _text_constants(script: _Script) -> JsonDict:
    path, consts = script.path, script.constants
    out: JsonDict = {}
    for key in ("DESCRIPTION", "FIXED_HOLES"):
        value = consts[key].value if key in consts else ""
        if not isinstance(value, str):
            raise CadfeatError(f"{path}: {key} must be a string, got {type(value).__name__}")
        out[key] = value.strip()
    view = consts["VIEW_DIRECTION"].value if "VIEW_DIRECTION" in consts else None
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


#: ``__name__`` of a script run by cq-editor (CQGI runs it as ``"__cqgi__"``).
CQ_EDITOR_NAME = "__cq_main__"


def _cq_editor_prelude(tree: ast.Module) -> list[ast.stmt]:
    """What cq-editor gives a script that CQGI does not, for a script that uses it (statements run before the
    script's own): its ``__name__`` for a script that names ``"__cq_main__"`` (``if __name__ == "__cq_main__":
    show_object(...)``, a common guard), and its ``log(x)`` for a script that calls ``log`` (here: the logger
    ``cadfeat.cqgi``, at INFO). A script that defines or imports ``log`` itself overrides it, as in cq-editor."""
    out = []
    if any(isinstance(n, ast.Constant) and n.value == CQ_EDITOR_NAME for n in ast.walk(tree)):
        out.append(f"__name__ = {CQ_EDITOR_NAME!r}")
    if any(isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == "log" for n in ast.walk(tree)):
        out.append("log = __import__('logging').getLogger('cadfeat.cqgi').info")
    return ast.parse("\n".join(out)).body


def _with_prelude(tree: ast.Module, prelude: list[ast.stmt]) -> ast.Module:
    """``tree`` with ``prelude`` first (at the first statement's line, for tracebacks)."""
    if not prelude:
        return tree
    first = tree.body[0] if tree.body else None
    tree.body[:0] = [ast.copy_location(copy.deepcopy(s), first) if first is not None else copy.deepcopy(s)
                     for s in prelude]
    return ast.fix_missing_locations(tree)


def _builder(script: _Script, model: Any, names: list[str]) -> Any:
    """``build(**params)``: run the script through CQGI with ``params`` and return its one solid (after what
    cq-editor would give it, ``_cq_editor_prelude``)."""
    path = script.path
    prelude = _cq_editor_prelude(script.tree)

    def build(**params: Any) -> Any:
        unknown = sorted(set(params) - set(names))
        if unknown:
            raise CadfeatError(f"{path}: unknown parameter(s) {', '.join(unknown)}; allowed: {', '.join(names)}")
        # The values are written into a fresh copy of the script's syntax tree (CQGI's own substitution knows
        # only the constants its finder saw, and writes into its one tree): no build keeps an earlier value.
        values = {k: int(v) if isinstance(v, int) else float(v) for k, v in params.items()}
        model.ast_tree = _with_prelude(_substituted(script.tree, script.constants, values), prelude)
        with _two_argument_describe(), _script_dir_on_path(path):
            result = model.build()
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
    script = _script(path)
    model = _model(path)
    parameters = cqgi_parameters(path, parameter_cls, script)
    text = _text_constants(script)
    module = types.ModuleType(f"cadfeat_cqgi_{path.stem}")
    module.__file__ = str(path)
    module.build = _builder(script, model, list(parameters))  # type: ignore[attr-defined]
    module.PARAMETERS = {n: {"default": p.default, "bounds": (p.lower, p.upper), "unit": p.unit,  # type: ignore
                             "description": p.description} for n, p in parameters.items()}
    module.CQGI_MODEL = model  # type: ignore[attr-defined]
    return part_cls(path.stem, path, parameters, text["DESCRIPTION"], text["FIXED_HOLES"], text["VIEW_DIRECTION"],
                module)


def getparams(path: str | Path) -> list[JsonDict]:
    """cq-cli's ``--getparams`` listing of a CQGI script: one object per top-level constant
    (``script_constants``: negative and annotated ones too, which CQGI's own finder misses), in the script's
    order, with ``type`` (number | string | boolean; none for tuples), ``name``, ``caption`` (the
    ``describe_parameter`` text), ``initial`` (the value: always, also 0 / False / "", which cq-cli's
    ``main.py`` drops) and ``min`` / ``max`` / ``step`` from CQGI's valid values where CQGI has any — the
    fields of cq-cli's ``main.py``. Only the numeric ones are design parameters (``cqgi_parameters``)."""
    path = Path(path)
    script = _script(path)
    cqgi_meta = _model(path).metadata.parameters
    out = []
    for name, c in script.constants.items():
        entry: JsonDict = {}
        kind = "boolean" if isinstance(c.value, bool) else "number" if isinstance(c.value, int | float) \
            else "string" if isinstance(c.value, str) else None
        if kind:
            entry["type"] = kind
        entry["name"] = name
        if script.descriptions.get(name):
            entry["caption"] = script.descriptions[name]
        entry["initial"] = list(c.value) if isinstance(c.value, tuple) else c.value
        valid = getattr(cqgi_meta.get(name), "valid_values", None)
        if valid:
            entry["min"], entry["max"] = valid[0], valid[-1]
            entry["step"] = entry["max"] - entry["min"] if entry["max"] - entry["min"] > 0 else 1
        out.append(entry)
    return out
