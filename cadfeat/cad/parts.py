"""Parametric part scripts: the part-script protocol, loading, validated builds, time-limited builds.

A part script is a plain Python file (``parts/*.py``) that also runs unchanged in cq-editor::

    DESCRIPTION = "one line"
    PARAMETERS = {"pitch_mm": {"default": 8.57, "bounds": (4.0, 20.0), "unit": "mm",
                               "description": "distance between hole centres"}, ...}
    VIEW_DIRECTION = (0, 0, 1)        # optional: the side a camera looks from (part frame)
    FIXED_HOLES = "..."               # optional: which holes are functional (may not move)

    def build(**params) -> cq.Workplane: ...
    def expected_holes(**params) -> list[dict]: ...   # optional: analytic holes (tests), "fixed" flags

    if "show_object" in globals():    # cq-editor
        show_object(build(**{k: v["default"] for k, v in PARAMETERS.items()}))

An integer parameter has an ``int`` default (and int bounds). ``load_part(path) -> Part`` validates the
script; ``Part.build(**overrides)`` validates the values and returns one ``cadquery.Solid`` (mm);
``build_shape(part, params, timeout_s)`` runs a build in a worker process with a time limit (docs/design.md,
"Known pitfalls": a CAD rebuild may hang), raising ``PartBuildError``; ``load_part(path,
time_limit_s)`` runs the script's import and every ``Part.build`` that way (the ``cadfeat`` commands pass
``[study] build_timeout_s`` or ``--build-timeout``; None: in this process).
A part script is Python run with the user's rights: its output is captured, ``sys.exit`` is an error. The
worker processes, the time limit and the output capture live in ``cadfeat.cad.sandbox``.

CadQuery is imported inside the functions (``import cadfeat`` stays light).
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.util
import inspect
import io
import math
import os
import sys
import traceback
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.cad import cqgi_parts
from cadfeat.cad.cqgi_parts import cad_shapes
from cadfeat.cad.features import extract_holes
from cadfeat.cad.features.identity import hole_name, pair_holes
from cadfeat.cad.sandbox import (
    DEFAULT_BUILD_TIMEOUT_S,
    PartBuildError,
    call_with_time_limit,
    check_time_limit,
    contained,
    run_worker,
    start_workers,
    worker_setup,
)
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from multiprocessing.connection import Connection

    import cadquery as cq

    from cadfeat.cad.features import Hole

__all__ = [
    "PARTS_DIR",
    "Parameter",
    "Part",
    "PartBuildError",
    "DEFAULT_BUILD_TIMEOUT_S",
    "build_shape",
    "call_with_time_limit",
    "start_workers",
    "find_parts",
    "load_part",
    "load_parts",
]

#: The parts library of the repository (``parts/`` beside the ``cadfeat`` package).
PARTS_DIR = Path(__file__).resolve().parents[2] / "parts"
PARAMETER_KEYS = ("default", "bounds", "unit", "description")
"""Keys allowed in one ``PARAMETERS`` entry (``default`` and ``bounds`` are required)."""


# ------------------------------------------------------------------------------------------ parameters
@dataclass(frozen=True)
class Parameter:
    """One design parameter of a part script: default, bounds [lower, upper], unit, description."""

    name: str
    default: float | int
    lower: float | int
    upper: float | int
    unit: str = ""
    description: str = ""
    is_int: bool = False

    def check(self, value: object, where: str) -> float | int:
        """``value`` as a float (int for integer parameters) within bounds, or ``CadfeatError``."""
        allowed = f"allowed: {'an integer' if self.is_int else 'a number'} in [{self.lower:g}, {self.upper:g}]" \
                  f"{' ' + self.unit if self.unit else ''}"
        if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
            raise CadfeatError(f"{where}: parameter {self.name!r} = {value!r} is not a number; {allowed}")
        if not math.isfinite(float(value)):
            raise CadfeatError(f"{where}: parameter {self.name!r} = {value!r} is not finite; {allowed}")
        if self.is_int:
            if float(value) != int(value):
                raise CadfeatError(f"{where}: parameter {self.name!r} = {value!r} is not an integer; {allowed}")
            value = int(value)
        else:
            value = float(value)
        if not self.lower <= value <= self.upper:
            raise CadfeatError(f"{where}: parameter {self.name!r} = {value:g} is out of bounds; {allowed}")
        return value

    def describe(self) -> str:
        """``name = default unit [lower, upper] (int) -- description``: one line for listings."""
        unit = f" {self.unit}" if self.unit else ""
        kind = " (integer)" if self.is_int else ""
        return f"{self.name} = {self.default:g}{unit} in [{self.lower:g}, {self.upper:g}]{kind}  {self.description}"


def _parse_parameter(name: object, spec: object, where: str) -> Parameter:
    """One ``PARAMETERS`` entry, validated (errors name the file, the key and what is allowed)."""
    if not isinstance(name, str) or not name.isidentifier():
        raise CadfeatError(f"{where}: PARAMETERS key {name!r} is not a valid Python identifier "
                           "(build(**params) receives it as a keyword)")
    key = f"PARAMETERS[{name!r}]"
    if not isinstance(spec, Mapping):
        raise CadfeatError(f"{where}: {key} must be a dict with keys {', '.join(PARAMETER_KEYS)}; "
                           f"got {type(spec).__name__}")
    unknown = sorted(set(spec) - set(PARAMETER_KEYS))
    if unknown:
        raise CadfeatError(f"{where}: {key} has unknown key(s) {', '.join(map(repr, unknown))}; "
                           f"allowed: {', '.join(PARAMETER_KEYS)}")
    for required in ("default", "bounds"):
        if required not in spec:
            raise CadfeatError(f"{where}: {key} lacks {required!r} (required keys: default, bounds)")
    default, bounds = spec["default"], spec["bounds"]
    is_int = isinstance(default, int | np.integer) and not isinstance(default, bool)
    if isinstance(default, bool) or not isinstance(default, int | float | np.integer | np.floating) \
            or not math.isfinite(float(default)):
        raise CadfeatError(f"{where}: {key}['default'] = {default!r} must be a finite number (int for integer "
                           "parameters)")
    if (not isinstance(bounds, list | tuple) or len(bounds) != 2
            or any(isinstance(b, bool) or not isinstance(b, int | float | np.integer | np.floating)
                   or not math.isfinite(float(b)) for b in bounds)):
        raise CadfeatError(f"{where}: {key}['bounds'] = {bounds!r} must be (lower, upper), two finite numbers")
    lower, upper = bounds
    if is_int and any(float(b) != int(b) for b in bounds):
        raise CadfeatError(f"{where}: {key}['bounds'] = {bounds!r} must be integers for an integer parameter")
    cast = int if is_int else float
    lower, upper, default = cast(lower), cast(upper), cast(default)
    if not lower <= default <= upper:
        raise CadfeatError(f"{where}: {key}: default {default:g} is outside bounds [{lower:g}, {upper:g}]")
    for text_key in ("unit", "description"):
        if not isinstance(spec.get(text_key, ""), str):
            raise CadfeatError(f"{where}: {key}[{text_key!r}] must be a string")
    return Parameter(name, default, lower, upper, spec.get("unit", ""), spec.get("description", ""), is_int)


# ----------------------------------------------------------------------------------------------- parts
@dataclass(frozen=True)
class Part:
    """A loaded part script (see the module docstring for the protocol)."""

    name: str
    path: Path
    parameters: dict[str, Parameter]
    description: str = ""
    fixed_holes: str = ""
    view_direction: np.ndarray | None = None
    module: ModuleType | None = field(default=None, repr=False, compare=False)
    time_limit_s: float | None = field(default=None, compare=False)
    """The time limit (s) of each ``build``, in a worker process; None: in this process, no limit. Given to
    ``load_part``, so a part carries its own limit."""

    def __reduce__(self) -> tuple[Callable[[str], Part], tuple[str]]:
        """Pickled as its path (re-loaded on unpickling, in a worker: no limit of its own), so parts can be sent
        to worker processes."""
        return load_part, (str(self.path),)

    def defaults(self) -> dict[str, float | int]:
        """The default value of every parameter."""
        return {n: p.default for n, p in self.parameters.items()}

    def resolve(self, **overrides: object) -> dict[str, float | int]:
        """Defaults updated by ``overrides``, validated: unknown names / bad values raise ``CadfeatError``."""
        unknown = sorted(set(overrides) - set(self.parameters))
        if unknown:
            raise CadfeatError(f"{self.path}: unknown parameter(s) {', '.join(map(repr, unknown))}; "
                               f"allowed: {', '.join(self.parameters) or '(none)'}")
        values = self.defaults()
        for name, value in overrides.items():
            values[name] = self.parameters[name].check(value, str(self.path))
        return values

    def build(self, **overrides: object) -> cq.Solid:
        """Build the part: one ``cadquery.Solid`` (mm), in this process, or within the part's ``time_limit_s``
        in a worker process (``build_shape``). Raises ``PartBuildError``."""
        if self.time_limit_s is not None:
            return build_shape(self, overrides, self.time_limit_s)
        params = self.resolve(**overrides)
        try:
            with contained(self.path, f"build({_fmt(params)})"):
                result = self.module.build(**params)
        except PartBuildError:
            raise
        except CadfeatError as exc:  # (e.g. sys.exit in the script)
            raise PartBuildError(str(exc)) from exc
        except Exception as exc:
            raise PartBuildError(f"{self.path}: build({_fmt(params)}) raised {type(exc).__name__}: {exc}") from exc
        return _one_solid(result, f"{self.path}: build({_fmt(params)})")

    def holes(self, **overrides: object) -> list[Hole]:
        """The extracted holes of ``build(**overrides)`` (through holes enter on the ``view_direction`` side),
        named by ``name_holes``."""
        holes = extract_holes(self.build(**overrides), prefer_direction=self.view_direction)
        return self.name_holes(holes, overrides)

    def holes_timed(self, params: Mapping[str, object] | None = None, timeout_s: float | None = None) -> list[Hole]:
        """``holes(**params)``, built in a worker process with a time limit when ``timeout_s`` is given."""
        if timeout_s is None:
            return self.holes(**dict(params or {}))

        holes = extract_holes(build_shape(self, params, timeout_s), prefer_direction=self.view_direction)
        return self.name_holes(holes, params)

    def name_holes(self, holes: Sequence[Hole], params: Mapping[str, object] | None = None,
                   tol_mm: float = 1e-3) -> list[Hole]:
        """``holes`` (extracted at ``params``) with names that stay with the physical hole:

        - a script with ``expected_holes``: the hole whose centre is within ``tol_mm`` of entry k gets the
          entry's ``name``, or ``H<k+1>`` (the script's own order, the same for every parameter value);
        - otherwise: each hole is paired with a hole of the DEFAULT build (extraction order there gives
          H1 … HN) by ``identity.pair_holes(..., bounded=False)`` (centre distance + radius change + axis
          change, one to one, Hungarian) and takes that hole's name, so changing a parameter never swaps two
          names.
        Holes left over (a parameter added holes) get ``H<N+1>`` … in extraction order."""

        holes = list(holes)
        if not holes:
            return holes
        names: list[str | None] = [None] * len(holes)
        centres = np.array([h.centre for h in holes], float)
        expected = self.expected_holes(**dict(params or {})) if self.module is not None else None
        if expected:
            ref = np.array([e["centre"] for e in expected], float).reshape(-1, 3)
            d = np.linalg.norm(centres[:, None] - ref[None], axis=-1)
            taken: set[int] = set()
            for i in np.argsort(d.min(axis=1), kind="stable"):
                k = int(np.argmin(np.where([j in taken for j in range(len(ref))], np.inf, d[i])))
                if d[i, k] <= tol_mm:
                    taken.add(k)
                    names[i] = str(expected[k].get("name") or f"H{k + 1}")
            n_ref = len(expected)
        else:  # the default build's holes, paired by identity.pair_holes (unbounded: its cost is stated there)
            reference = self._default_holes()
            n_ref = len(reference)
            for i, k in enumerate(pair_holes(holes, reference, bounded=False)):
                if k >= 0:
                    names[i] = hole_name(reference[int(k)], int(k))
        extra = n_ref
        out = []
        for h, name in zip(holes, names, strict=True):
            if name is None:
                extra += 1
                name = f"H{extra}"
            out.append(dataclasses.replace(h, name=name))
        return out

    def _default_holes(self) -> list[Hole]:
        """The holes of the default build (extraction order), cached on the part."""
        cache = self.__dict__.get("_default_holes_cache")
        if cache is None:
            cache = extract_holes(self.build(), prefer_direction=self.view_direction)
            object.__setattr__(self, "_default_holes_cache", cache)
        return cache

    def expected_holes(self, **overrides: object) -> list[dict[str, object]] | None:
        """The script's analytic holes (``expected_holes(**params)``: dicts centre, axis, radius_mm, optional
        kind, fixed, name), or None if the script has none."""
        func = getattr(self.module, "expected_holes", None)
        return None if func is None else func(**self.resolve(**overrides))

    def fixed_mask(self, holes: Sequence[Hole], params: Mapping[str, object] | None = None,
                   tol_mm: float = 1e-6) -> np.ndarray:
        """(N,) bool: which of ``holes`` (extracted at ``params``) the script marks ``"fixed": True`` in
        ``expected_holes`` (functional holes that may not move); matched by centre within ``tol_mm``.
        All False for a script without ``expected_holes``."""
        expected = self.expected_holes(**dict(params or {})) or []
        fixed = np.array([c for e in expected if e.get("fixed") for c in [e["centre"]]], dtype=float).reshape(-1, 3)
        if len(holes) == 0 or len(fixed) == 0:
            return np.zeros(len(holes), dtype=bool)
        centres = np.stack([h.centre for h in holes])
        return (np.linalg.norm(centres[:, None] - fixed[None], axis=-1) <= tol_mm).any(axis=1)


def _fmt(params: Mapping[str, object]) -> str:
    return ", ".join(f"{k}={v!r}" for k, v in params.items())


def _one_solid(result: object, what: str) -> cq.Solid:
    """The single solid of a build result (Workplane, Shape or OCP shape)."""
    if result is None:
        raise PartBuildError(f"{what} returned None; it must return a cadquery Workplane or Shape with one solid")
    shapes = cad_shapes(result)
    if shapes is None:
        raise PartBuildError(f"{what} returned {type(result).__name__}; it must return a cadquery Workplane or "
                             "Shape with one solid")
    solids = [s for shape in shapes for s in shape.Solids()]
    if len(solids) != 1:
        raise PartBuildError(f"{what} returned {len(solids)} solids; a part must be exactly one solid")
    return solids[0]


def _module_name(path: Path) -> str:
    digest = hashlib.sha1(str(path).encode()).hexdigest()[:12]
    stem = "".join(c if c.isalnum() else "_" for c in path.stem)
    return f"cadfeat_part_{stem}_{digest}"


def _import_script(path: Path) -> ModuleType:
    """Execute the script as a fresh module (unique name; registered in ``sys.modules`` while it runs)."""
    name = _module_name(path)
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise CadfeatError(f"{path}: cannot be imported as a Python part script (expected a .py file)")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        with contained(path, "importing the part script", echo=True):
            spec.loader.exec_module(module)
    except (KeyboardInterrupt, CadfeatError):
        sys.modules.pop(name, None)
        raise
    except SyntaxError as exc:
        sys.modules.pop(name, None)
        raise CadfeatError(f"{exc.filename or path}:{exc.lineno}: syntax error: {exc.msg}") from None
    except Exception as exc:
        sys.modules.pop(name, None)
        tb = traceback.extract_tb(exc.__traceback__)
        line = next((f.lineno for f in reversed(tb) if Path(f.filename) == path), None)
        where = f"{path}:{line}" if line else str(path)
        raise CadfeatError(f"{where}: importing the part script raised {type(exc).__name__}: {exc}") from exc
    return module


def load_part(path: str | os.PathLike[str], time_limit_s: float | None = None) -> Part:
    """Load and validate a part script: a path, or the bare name of a library part (``"thesis_hub"``).

    ``time_limit_s``: the import and every ``Part.build`` run in a worker process killed after that many
    seconds (``PartBuildError``); None (the default): in this process, no limit.

    Raises ``CadfeatError`` naming the file (and line / key) for a missing file, a syntax error, a script
    raising on import, no ``build``, bad ``PARAMETERS``, or a ``build`` signature not matching them.
    """
    given = Path(path).expanduser()
    if not given.exists() and given.parent == Path(".") and given.suffix in ("", ".py"):
        library = PARTS_DIR / f"{given.stem}.py"  # a bare name: a part of the library
        given = library if library.is_file() else given
    path = given.resolve()
    if not path.is_file():
        names = ", ".join(p.stem for p in find_parts()) if PARTS_DIR.is_dir() else "(no library)"
        what = "is not a regular file" if path.exists() else "part script not found"
        raise CadfeatError(f"{path}: {what} (library parts: {names})")

    limit = check_time_limit(time_limit_s)
    if cqgi_parts.is_cqgi_script(path):  # a cq-editor / CQGI script: parsed by CQGI, run only to build
        return dataclasses.replace(cqgi_parts.load_cqgi_part(path, Part, Parameter), time_limit_s=limit)
    if limit is not None:
        start_workers()
        _import_in_worker(path, limit)  # a loop or a crash at import time stays in the worker
    module = _import_script(path)
    where = str(path)
    if not callable(getattr(module, "build", None)):
        raise CadfeatError(f"{where}: no build(**params) function; a part script defines PARAMETERS and build")
    if not hasattr(module, "PARAMETERS"):
        raise CadfeatError(f"{where}: no PARAMETERS dict; define PARAMETERS = {{name: {{'default': v, "
                           f"'bounds': (lo, hi), 'unit': 'mm', 'description': '...'}}}}")
    if not isinstance(module.PARAMETERS, Mapping):
        raise CadfeatError(f"{where}: PARAMETERS must be a dict name -> {{{', '.join(PARAMETER_KEYS)}}}, "
                           f"got {type(module.PARAMETERS).__name__}")
    parameters = {str(n): _parse_parameter(n, s, where) for n, s in module.PARAMETERS.items()}
    _check_signature(module.build, parameters, where)
    view = cqgi_parts.unit_view_direction(getattr(module, "VIEW_DIRECTION", None), where)
    text = {k: getattr(module, k, "") for k in ("DESCRIPTION", "FIXED_HOLES")}
    for key, value in text.items():
        if not isinstance(value, str):
            raise CadfeatError(f"{where}: {key} must be a string, got {type(value).__name__}")
    return Part(path.stem, path, parameters, text["DESCRIPTION"].strip(), text["FIXED_HOLES"].strip(), view, module,
                limit)


def _check_signature(build: Callable[..., object], parameters: Mapping[str, Parameter], where: str) -> None:
    """``build`` must accept every parameter as a keyword, and require no other argument."""
    try:
        sig = inspect.signature(build)
    except (TypeError, ValueError):  # pragma: no cover - builtins / C functions
        return
    kinds = {p.kind for p in sig.parameters.values()}
    accepted = {n for n, p in sig.parameters.items()
                if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
    missing = [] if inspect.Parameter.VAR_KEYWORD in kinds else [n for n in parameters if n not in accepted]
    required = [n for n, p in sig.parameters.items() if p.default is p.empty and n not in parameters
                and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
    if missing or required:
        raise CadfeatError(f"{where}: build{sig} does not match PARAMETERS ({', '.join(parameters) or 'none'}): "
                           + "; ".join(filter(None, [missing and f"not accepted: {', '.join(missing)}",
                                                     required and f"required but not in PARAMETERS: "
                                                                  f"{', '.join(required)}"])))


def find_parts(directory: str | os.PathLike[str] | None = None) -> list[Path]:
    """The part scripts (``*.py`` not starting with ``_``) of ``directory`` (default ``PARTS_DIR``), sorted."""
    directory = Path(directory) if directory is not None else PARTS_DIR
    if not directory.is_dir():
        raise CadfeatError(f"{directory}: not a directory of part scripts")
    return sorted(p for p in directory.glob("*.py") if not p.name.startswith("_"))


def load_parts(directory: str | os.PathLike[str] | None = None) -> list[Part]:
    """Every part script of ``directory`` (default ``PARTS_DIR``), loaded and validated."""
    return [load_part(p) for p in find_parts(directory)]


# ------------------------------------------------------------------------------ time-limited builds
def _worker(path: str, params: Mapping[str, float | int] | None, conn: Connection) -> None:
    """Worker process: import the script, build (``params`` None: import only), send ('ok', BRep bytes) or
    ('error', message)."""
    worker_setup()
    try:
        part = load_part(path)
        if params is None:
            conn.send(("ok", b""))
            return
        solid = part.build(**params)
        buf = io.BytesIO()
        solid.exportBrep(buf)
        conn.send(("ok", buf.getvalue()))
    except BaseException as exc:  # noqa: BLE001 - everything goes back to the parent as a message
        conn.send(("error", f"{exc}" if isinstance(exc, CadfeatError) else f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


def build_shape(part: Part, params: Mapping[str, object] | None = None, timeout_s: float = 30.0) -> cq.Solid:
    """Build ``part`` with ``params`` in a worker process, within ``timeout_s`` seconds.

    The solid comes back as BRep text (``Shape.exportBrep``/``importBrep``: exact geometry). A build that
    raises, returns no solid, dies, or runs longer than ``timeout_s`` (the worker is killed) raises
    ``PartBuildError``; bad parameter names/values raise ``CadfeatError`` before any process starts.
    """
    values = part.resolve(**dict(params or {}))
    payload = _in_worker(part.path, values, timeout_s, f"build({_fmt(values)})")
    import cadquery as cq  # (after the worker: a first import here overlaps nothing)

    shape = cq.Shape.importBrep(io.BytesIO(payload))
    return _one_solid(shape, f"{part.path}: build({_fmt(values)})")


def _import_in_worker(path: Path, timeout_s: float) -> None:
    """Import the script in a worker process within ``timeout_s`` (raises what the import would raise)."""
    _in_worker(path, None, timeout_s, "importing the part script")


def _in_worker(path: Path, values: Mapping[str, float | int] | None, timeout_s: float, what: str) -> bytes:
    status, payload = run_worker(_worker, (str(path), values), timeout_s, f"{path}: {what}")
    if status != "ok":
        message = payload if payload.startswith(str(path)) else f"{path}: {payload}"
        raise (PartBuildError if values is not None else CadfeatError)(message)
    return payload


