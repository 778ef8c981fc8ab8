"""The set-up cache (issue 32 item 6): a study's set-up kept on disk, keyed by the hash of everything it reads.

Setting a study up is the slow part of ``cadfeat explore``, ``run`` and ``evaluate``: the part's CAD builds, the
design map ∂F/∂P (a build per finite difference), the objective normaliser (the payoff table), the part's
occlusion mesh and, for g_POSE in a metal part, its glare maps (a physically based render per pose).
``cached_setup`` returns the set-up from the cache when the same inputs were set up before, and sets it up
(``study.setup``) otherwise; ``save`` keeps a fresh set-up's products once its consumer has built the normaliser.
A set-up read from the cache is a ``CachedSetup``: the same numbers, bit for bit (the arrays are pickled, not
recomputed), and its CAD side — the part script or STEP file, and the original solid — is loaded only when
something asks for it (a rebuild, an export, a render), so a warm ``cadfeat explore`` imports no CAD kernel (nor
the renderer) at all.

Where (``cache_root``): ``$CADFEAT_CACHE_DIR``, else ``$XDG_CACHE_HOME/cadfeat``, else ``~/.cache/cadfeat``; the
entries are ``setups/<key>.pkl``. cadfeat creates that folder with a marker (``.cadfeat-cache.json`` and the
standard ``CACHEDIR.TAG``) and writes only into a folder that carries its marker (an existing non-empty folder
without it is left alone: the cache is then off, with a warning). ``cadfeat cache`` shows the folder and its
size; ``cadfeat cache --clear`` removes the entries cadfeat wrote there.

Off: ``CADFEAT_CACHE=off`` (also 0 / no / false), or ``--no-cache`` on ``run``, ``evaluate`` and ``explore``
(``cache=False`` in the Python API).

The key (``input_key``) is the SHA-256 of: the entry format, cadfeat's version and a digest of its own source and
data files (a changed cadfeat misses), the versions of Python and of the libraries the set-up's numbers come from
(CadQuery, OCP, numpy, SciPy, trimesh, numba, Embree), the resolved study (``StudyConfig.to_dict()``: defaults
filled in, hashed as a campaign's input hash is: ``study.inputs``) and its folder, the bytes of the part file —
and of the modules beside a part script that it imports —, the camera as built (a calibration file's values), the
trajectory's poses and times as built (a CSV's), the part pose and the integer parameters' values. A changed
input misses. What a part script reads some other way (a data file it opens) is not in the key: ``--no-cache``
after changing it.

An entry is a pickle (``FORMAT``) read only from cadfeat's own cache folder, and used only if its format and key
match; one that cannot be read is ignored with a ``CacheWarning`` and replaced by a fresh set-up. Entries are
written to a temporary file beside them and renamed into place: two processes setting up the same study write
whole files, the last rename wins, and a reader never sees half an entry.
"""

from __future__ import annotations

import ast
import contextlib
import dataclasses
import hashlib
import io
import os
import pickle
import platform
import secrets
import threading
import time
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict, TypeVar, cast

import numpy as np

from cadfeat._version import __version__
from cadfeat.errors import CadfeatError, CadfeatWarning
from cadfeat.study.inputs import canonical_json, sha256_file
from cadfeat.study.setup import StudySetup

if TYPE_CHECKING:  # pragma: no cover
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.cad.parts import Part
    from cadfeat.cad.step_parts import StepPart
    from cadfeat.design.constraints import ConstraintConfig
    from cadfeat.design.design_space import DesignSpace, FeatureModel
    from cadfeat.design.objectives import Normaliser
    from cadfeat.measures.glare import GlareMaps
    from cadfeat.study.schema import StudyConfig
    from cadfeat.study.setup import Scene

__all__ = ["CACHE_DIR_ENV", "CACHE_ENV", "FORMAT", "CacheEntry", "CacheWarning", "CachedSetup", "SetupCache",
           "cache_root", "cached_setup", "input_key", "open_cache", "product", "save", "sha256_file"]

CACHE_ENV = "CADFEAT_CACHE"
"""``off`` (0, no, false) turns the set-up cache off; anything else (or unset) leaves it on."""
CACHE_DIR_ENV = "CADFEAT_CACHE_DIR"
"""The cache folder (default ``$XDG_CACHE_HOME/cadfeat``, else ``~/.cache/cadfeat``)."""
FORMAT = 1
"""The entry format: an entry of another format is a miss (bump it when ``_products`` changes)."""
MARKER = ".cadfeat-cache.json"
TAG = "CACHEDIR.TAG"
TAG_TEXT = ("Signature: 8a477f597d28d172789f06886806bc55\n# This file is a cache directory tag created by cadfeat "
            "(its study set-up cache).\n# For information see https://bford.info/cachedir/\n")
ENTRIES = "setups"
LIBRARIES = ("cadquery", "cadquery-ocp", "numpy", "scipy", "trimesh", "numba", "embreex")
"""The distributions whose versions are in the key (the CAD kernel, the numerics, the ray tests)."""
_OFF = {"0", "off", "no", "false"}
_PACKAGE = Path(__file__).resolve().parents[1]
_SOURCE_SUFFIXES = (".py", ".json", ".csv", ".npz", ".toml")


class CacheWarning(CadfeatWarning):
    """The set-up cache could not be used (a corrupt entry, a folder cadfeat did not create): the study is set up
    as without it."""


def _warn(message: str) -> None:
    warnings.warn(message, CacheWarning, stacklevel=3)


# ----------------------------------------------------------------------------------------------- the key
@lru_cache(maxsize=1)
def source_digest() -> str:
    """SHA-256 of cadfeat's own source and data files (names and bytes): a changed cadfeat misses every entry,
    also between releases (a working copy keeps its version number)."""
    h = hashlib.sha256()
    for path in sorted(_PACKAGE.rglob("*")):
        if path.suffix in _SOURCE_SUFFIXES and "__pycache__" not in path.parts and path.is_file():
            h.update(path.relative_to(_PACKAGE).as_posix().encode() + b"\0")
            h.update(hashlib.sha256(path.read_bytes()).digest())
    return h.hexdigest()


@lru_cache(maxsize=1)
def library_versions() -> dict[str, str]:
    """{distribution: version} of ``LIBRARIES`` ("-" for one that is not installed) and Python's version."""
    from importlib import metadata

    out = {"python": platform.python_version()}
    for name in LIBRARIES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "-"
    return out


def part_files(path: Path) -> dict[str, str]:
    """{path: SHA-256} of the part file and, for a Python part script, of the modules beside it that it imports
    (``import helper`` / ``from helper import x`` with ``helper.py`` or a package ``helper/`` in its folder)."""
    files = {str(path): sha256_file(path)}
    if path.suffix != ".py":
        return files
    try:
        tree = ast.parse(path.read_text(encoding="utf-8"))
    except (SyntaxError, UnicodeDecodeError, ValueError):
        return files  # (the set-up reports it)
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module.split(".")[0])
    for name in sorted(names):
        module, package = path.parent / f"{name}.py", path.parent / name
        found = [module] if module.is_file() else sorted(package.rglob("*.py")) if package.is_dir() else []
        files.update({str(p): sha256_file(p) for p in found})
    return files


def resolved_ints(config: StudyConfig, int_values: Mapping[str, int] | None) -> dict[str, int]:
    """The integer parameters' values a part-script set-up uses (``setup_script``: start, else default, then
    ``int_values``)."""
    ints = {p.name: int(p.default if p.start is None else p.start) for p in config.design.parameters if p.is_int}
    ints.update({k: int(v) for k, v in (int_values or {}).items()})
    return dict(sorted(ints.items()))


def _array_digest(*arrays: np.ndarray) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(np.asarray(a, float))
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def input_key(config: StudyConfig, scene: Scene, int_values: Mapping[str, int] | None = None) -> str:
    """The cache key of a study's set-up (module docstring: what it covers)."""
    camera, trajectory, T_task_part = scene
    data = {
        "format": FORMAT, "cadfeat": __version__, "source": source_digest(), "libraries": library_versions(),
        "study": config.to_dict(), "base_dir": str(config.base_dir),
        "part": part_files(Path(config.study.part_path)),
        "camera": camera.to_dict(),
        "trajectory": _array_digest(trajectory.T_task_cam, trajectory.times_s),
        "part_pose": _array_digest(T_task_part),
        "int_values": resolved_ints(config, int_values) if config.study.part_kind == "script" else {},
    }
    return hashlib.sha256(canonical_json(data)).hexdigest()


# ---------------------------------------------------------------------------------------------- the folder
def cache_root() -> Path:
    """The cache folder (module docstring)."""
    given = os.environ.get(CACHE_DIR_ENV, "").strip()
    if given:
        return Path(given).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME", "").strip()
    return (Path(xdg).expanduser() if xdg else Path.home() / ".cache") / "cadfeat"


def cache_enabled(enabled: bool | None = None) -> bool:
    """``enabled`` if given, else the environment (``CADFEAT_CACHE``)."""
    if enabled is not None:
        return bool(enabled)
    return os.environ.get(CACHE_ENV, "").strip().lower() not in _OFF


def open_cache(enabled: bool | None = None, root: str | os.PathLike[str] | None = None) -> SetupCache | None:
    """The set-up cache (``root``: default ``cache_root()``), or None when it is off (``enabled`` False, or
    ``CADFEAT_CACHE=off`` when ``enabled`` is None) or its folder cannot be used (a ``CacheWarning`` says why)."""
    if not cache_enabled(enabled):
        return None
    cache = SetupCache(Path(root) if root is not None else cache_root())
    return cache if cache.claim() else None


def _atomic_write(path: Path, data: bytes) -> None:
    """``data`` into ``path`` via a temporary sibling and ``os.replace`` (never half-written)."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}-{secrets.token_hex(4)}")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


class SetupCache:
    """A set-up cache folder (module docstring): ``load(key)`` / ``store(key, products)``."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self.entries = self.root / ENTRIES

    def claim(self) -> bool:
        """Create the folder with cadfeat's marker, or check that an existing one carries it; False (with a
        ``CacheWarning``) for a folder cadfeat did not create or cannot write."""
        marker = self.root / MARKER
        try:
            if self.root.is_dir() and not marker.is_file() and any(self.root.iterdir()):
                _warn(f"set-up cache: {self.root} holds files cadfeat did not write (no {MARKER}); the cache is off. "
                      f"Give an empty or new folder ({CACHE_DIR_ENV}=DIR), or {CACHE_ENV}=off")
                return False
            self.entries.mkdir(parents=True, exist_ok=True)
            if not marker.is_file():
                _atomic_write(marker, canonical_json({"cadfeat_cache": 1, "created": _now(), "cadfeat": __version__,
                                                      "what": "cadfeat's study set-up cache; safe to delete"}))
                _atomic_write(self.root / TAG, TAG_TEXT.encode())
        except OSError as exc:
            _warn(f"set-up cache: cannot use {self.root} ({exc.strerror or exc}); the cache is off")
            return False
        return True

    def path(self, key: str) -> Path:
        return self.entries / f"{key}.pkl"

    def load(self, key: str) -> Products | None:
        """The products of entry ``key``, or None (no entry; an unreadable one: a ``CacheWarning``)."""
        path = self.path(key)
        try:
            data = path.read_bytes()
        except FileNotFoundError:
            return None
        except OSError as exc:
            _warn(f"set-up cache: {path} cannot be read ({exc.strerror or exc}); setting the study up again")
            return None
        try:
            entry: object = pickle.loads(data)  # noqa: S301 - only cadfeat's own cache folder (module docstring)
            if not isinstance(entry, dict):
                raise ValueError("not an entry of this format and key")
            entry = cast("dict[str, object]", entry)
            if entry.get("format") != FORMAT or entry.get("key") != key:
                raise ValueError("not an entry of this format and key")
            products = entry["products"]
            if not isinstance(products, dict):
                raise ValueError("no products")
            products = cast("Products", products)  # (an entry of this format and key: what ``_products`` kept)
        except Exception as exc:  # noqa: BLE001 - whatever a damaged file raises, it is a miss
            _warn(f"set-up cache: entry {path} is damaged ({type(exc).__name__}: {exc}); ignored, the study is set "
                  "up again and the entry replaced")
            return None
        return products

    def store(self, key: str, products: Products, label: str = "") -> Path | None:
        """Write entry ``key`` (atomically); None (with a ``CacheWarning``) when it cannot be written."""
        entry = {"format": FORMAT, "key": key, "created": _now(), "cadfeat": __version__, "study": label,
                 "products": dict(products)}
        path = self.path(key)
        try:
            self.entries.mkdir(parents=True, exist_ok=True)
            _atomic_write(path, pickle.dumps(entry, protocol=pickle.HIGHEST_PROTOCOL))
        except (OSError, pickle.PicklingError, TypeError, AttributeError) as exc:
            _warn(f"set-up cache: cannot write {path} ({exc}); the set-up is not kept")
            return None
        return path

    def listing(self) -> list[Path]:
        """The entries cadfeat wrote here (``setups/*.pkl``)."""
        return sorted(self.entries.glob("*.pkl")) if self.entries.is_dir() else []

    def clear(self) -> int:
        """Delete the entries cadfeat wrote (and temporary files of interrupted writes); the folder and its marker
        stay. Returns the number of entries deleted; ``CadfeatError`` for a folder without cadfeat's marker."""
        if not self.root.exists():
            return 0
        if not (self.root / MARKER).is_file():
            raise CadfeatError(f"{self.root}: not a cadfeat set-up cache (no {MARKER}); nothing was deleted")
        n = 0
        for path in [*self.listing(), *self.entries.glob(".*.pkl.tmp-*")] if self.entries.is_dir() else []:
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
                n += path.suffix == ".pkl"
        return n


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


# ----------------------------------------------------------------------------------------- the set-up
@dataclass
class CacheEntry:
    """A set-up's place in the cache: ``hit`` (read from it) or fresh; ``own_normaliser``: the set-up builds its
    own objective scales (not another set-up's, as the integer combinations of a run share the first's);
    ``products`` once read or saved (``extras`` among them: what other layers keep with it, ``product``)."""

    cache: SetupCache
    key: str
    hit: bool
    own_normaliser: bool = True
    products: Products | None = None
    extras: dict[str, object] = field(default_factory=dict[str, object])
    setup_s: float = 0.0
    """The wall time of the fresh set-up (s): on a hit, what the cache saved (about)."""


class _LazyCad:
    """The CAD side of a set-up read from the cache, loaded on first use (thread-safe): the part (a script:
    ``load_part``; a STEP file: ``load_step``) and the original solid (a script's from the BRep kept in the entry,
    exactly the solid the set-up had; a STEP part's own)."""

    def __init__(self, config: StudyConfig, view: np.ndarray | None, brep: bytes | None, time_limit_s: float | None):
        self.config, self.view, self.brep, self.time_limit_s = config, view, brep, time_limit_s
        self._lock = threading.RLock()
        self._part: Part | StepPart | None = None
        self._shape: Shape | None = None

    def part(self) -> Part | StepPart:
        with self._lock:
            if self._part is None:
                path = self.config.study.part_path
                if self.config.study.part_kind == "step":
                    from cadfeat.cad.step_parts import load_step

                    self._part = load_step(path, prefer_direction=self.view)
                else:
                    from cadfeat.cad.parts import load_part

                    part = load_part(path, self.time_limit_s)  # as the set-up: the camera's side is the entrance
                    self._part = dataclasses.replace(part, view_direction=self.view)
            return self._part

    def shape(self) -> Shape:
        with self._lock:
            shape = self._shape
            if shape is None:
                if self.brep is None:
                    shape = self.step().shape  # (a STEP part: its own solid; a script's is kept as BRep)
                else:
                    import cadquery as cq

                    read = cq.Shape.importBrep(io.BytesIO(self.brep))
                    solids = read.Solids()
                    shape = solids[0] if len(solids) == 1 else read
                self._shape = shape
            return shape

    def step(self) -> StepPart:
        """The part of a STEP study (``part``)."""
        return cast("StepPart", self.part())

    def script(self) -> Part:
        """The part of a part-script study (``part``)."""
        return cast("Part", self.part())

    def set_part(self, part: Part | StepPart | None) -> None:
        if part is not None:
            self._part = part

    def set_shape(self, shape: Shape | None) -> None:
        if shape is not None:
            self._shape = shape


class CachedSetup(StudySetup):
    """A ``StudySetup`` read from the set-up cache: ``shape0`` and ``part`` are loaded on first use (``_LazyCad``);
    every other field is the cached set-up's."""

    def __init__(self, cad: _LazyCad, **fields: Any) -> None:
        self._cad = cad
        super().__init__(shape0=cast("Shape", None), part=None, **fields)

    # (the dataclass __init__ assigns None to both: the setters ignore None)
    shape0 = property(lambda self: self._cad.shape(), lambda self, value: self._cad.set_shape(value))  # type: ignore[assignment]
    part = property(lambda self: self._cad.part(), lambda self, value: self._cad.set_part(value))  # type: ignore[assignment]

    def __repr__(self) -> str:
        key = self.cache_entry.key[:12] if self.cache_entry is not None else "?"
        return f"CachedSetup({self.config.label}, cache key {key})"


def cached_setup(config: StudyConfig, int_values: Mapping[str, int] | None = None, *, scene: Scene | None = None,
                 normaliser: Normaliser | None = None, time_limit_s: float | None = None,
                 cache: SetupCache | None = None, on_phase: Callable[[str], None] | None = None) -> StudySetup:
    """The set-up of a study — ``study.setup.setup_script`` (a part script, with the integer parameters at
    ``int_values``; ``scene`` and ``normaliser`` as its) or ``setup_study`` (a STEP part) — read from ``cache``
    when these inputs were set up before, else set up and registered for ``save``. ``cache`` None: no cache.
    ``on_phase(text)``: told whether the set-up is read from the cache or made (the explorer's progress)."""
    from cadfeat.study import setup as study_setup  # (through the module: tests replace its functions)

    step = config.study.part_kind == "step"

    def fresh() -> StudySetup:
        if step:
            return study_setup.setup_study(config, time_limit_s=time_limit_s)
        return study_setup.setup_script(config, int_values, scene, normaliser, time_limit_s=time_limit_s)

    if cache is None:
        return fresh()
    scene = scene or study_setup.load_scene(config)
    key = input_key(config, scene, int_values)
    products = cache.load(key)
    if products is not None:
        if on_phase is not None:
            on_phase("set-up read from the cache")
        setup = _from_products(config, scene, products, normaliser, time_limit_s)
        setup.cache_entry = CacheEntry(cache, key, True, normaliser is None, products,
                                       dict(products.get("extras") or {}), float(products.get("setup_s") or 0.0))
        return setup
    if on_phase is not None:
        on_phase("set-up: CAD builds, the design map and the occlusion mesh (not in the cache yet)")
    t0 = time.perf_counter()
    setup = fresh()
    setup.cache_entry = CacheEntry(cache, key, False, normaliser is None, setup_s=time.perf_counter() - t0)
    return setup


def save(setups: StudySetup | Iterable[StudySetup]) -> None:
    """Keep fresh set-ups' products in their cache (the set-ups ``cached_setup`` made; set-ups read from the cache
    or made without one are left alone). Call it once the consumer has built what it needs (the objective
    normaliser): what is built by then is kept."""
    for setup in [setups] if not isinstance(setups, Iterable) else setups:
        entry = getattr(setup, "cache_entry", None)
        if not isinstance(entry, CacheEntry) or entry.hit or entry.products is not None:
            continue
        entry.products = _products(setup, entry)
        entry.extras = dict(entry.products["extras"])
        entry.cache.store(entry.key, entry.products, setup.config.label)


T = TypeVar("T")


def product(setup: StudySetup, name: str, compute: Callable[[], T]) -> T:
    """A value kept with the set-up in its cache entry (e.g. the explorer's display mesh): read from the entry,
    else ``compute()``d and added to it (the entry is written again when it exists already)."""
    entry = getattr(setup, "cache_entry", None)
    entry = entry if isinstance(entry, CacheEntry) else None
    if entry is not None and name in entry.extras:
        return cast(T, entry.extras[name])  # (what ``compute`` gave under this name before)
    value = compute()
    if entry is not None:
        entry.extras[name] = value
        if entry.products is not None:
            entry.products["extras"] = dict(entry.extras)
            entry.cache.store(entry.key, entry.products, setup.config.label)
    return value


class Products(TypedDict):
    """A set-up's cache entry (``_products``; read back by ``_from_products``)."""

    holes0: list[Hole]
    fixed_mask: np.ndarray
    movable_mask: np.ndarray
    space: DesignSpace
    model: FeatureModel
    constraints: ConstraintConfig
    feature_mask: np.ndarray | None
    linear: bool
    int_values: dict[str, int]
    view_direction: np.ndarray | None
    values: Callable[[np.ndarray], Mapping[str, object]] | None
    mesh: tuple[np.ndarray, np.ndarray] | None
    normaliser: Normaliser | None
    glare: GlareMaps | None
    brep: bytes | None
    extras: dict[str, object]
    setup_s: float


def _products(setup: StudySetup, entry: CacheEntry) -> Products:
    """What a set-up's cache entry keeps: everything the set-up computed, the CAD side as BRep (scripts), and the
    part's display mesh (``report.view3d.mesh_arrays``: the explorer's 3-D view) among the extras."""
    from cadfeat.report.view3d import mesh_arrays  # lazy: would import pydantic at module load

    mesh = setup.problem.occlusion_mesh
    brep = None
    if setup.config.study.part_kind == "script":
        buf = io.BytesIO()
        setup.shape0.exportBrep(buf)
        brep = buf.getvalue()
    view = setup.view_direction
    return {
        "holes0": list(setup.holes0), "fixed_mask": np.asarray(setup.fixed_mask, bool),
        "movable_mask": np.asarray(setup.movable_mask, bool), "space": setup.space, "model": setup.model,
        "constraints": setup.constraints, "feature_mask": setup.problem.feature_mask,
        "linear": bool(setup.linear), "int_values": dict(setup.int_values),
        "view_direction": None if view is None else np.asarray(view, float),
        "values": setup.values if setup.config.study.part_kind == "script" else None,
        "mesh": None if mesh is None else (np.asarray(mesh.vertices), np.asarray(mesh.faces)),
        "normaliser": setup.problem.normaliser_built if entry.own_normaliser else None,
        "glare": setup.problem.glare,  # g_POSE's glare maps (a physically based render per pose), or None
        "brep": brep, "extras": {"display_mesh": mesh_arrays(setup.shape0), **entry.extras}, "setup_s": entry.setup_s,
    }


def _from_products(config: StudyConfig, scene: Scene, p: Products, normaliser: Normaliser | None,
                   time_limit_s: float | None) -> StudySetup:
    """A ``CachedSetup`` of an entry's products (the problem built by ``setup.build_problem``, as a fresh one)."""
    from cadfeat.measures.raycache import cache_rays
    from cadfeat.study.setup import ProblemPieces, build_problem, script_rebuilders, step_rebuilders

    camera, trajectory, T_task_part = scene
    mesh = None
    if p["mesh"] is not None:
        import trimesh

        mesh = cache_rays(trimesh.Trimesh(*p["mesh"], process=False))
    args = ProblemPieces(p["space"], p["model"], camera, trajectory, T_task_part, p["fixed_mask"])
    problem = build_problem(config, args, p["constraints"], mesh, p["feature_mask"],
                            normaliser if normaliser is not None else p["normaliser"])
    if p["glare"] is not None:
        problem.set_glare(p["glare"])
    cad = _LazyCad(config, p["view_direction"], p["brep"], time_limit_s)
    view = p["view_direction"]
    model, values = p["model"], p["values"]
    if config.study.part_kind == "step":
        from cadfeat.design.design_space import HoleMoveModel

        assert isinstance(model, HoleMoveModel)  # (a STEP set-up's model)
        rebuild_shape, rebuild_holes = step_rebuilders(config, cad.step, model, view, time_limit_s)
        values = p["space"].as_dict
    else:
        assert values is not None  # (a part script's set-up keeps its ``ScriptValues``)
        rebuild_shape, rebuild_holes = script_rebuilders(cad.script, values, view)
    return CachedSetup(cad, config=config, camera=camera, trajectory=trajectory, T_task_part=T_task_part,
                       holes0=list(p["holes0"]), fixed_mask=p["fixed_mask"], movable_mask=p["movable_mask"],
                       space=p["space"], model=p["model"], problem=problem, constraints=p["constraints"],
                       rebuild_shape=rebuild_shape, rebuild_holes=rebuild_holes, values=values,
                       linear=bool(p["linear"]), int_values=dict(p["int_values"]), time_limit_s=time_limit_s,
                       view_direction=view)
