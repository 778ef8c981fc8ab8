"""The pieces of a study's ``results.json`` (contracts: "results.json") and deterministic output files.

Everything here is plain data in, plain data out: holes → dicts, ``Measures`` arrays → per-feature and
per-pose summaries, floats rounded to ``DIGITS`` significant digits so that the same seed gives the same
file byte for byte (only ``created`` and ``timings_s`` vary). STEP headers carry a fixed time stamp and
product name for the same reason (``normalise_step_header``; the run time is ``created`` in results.json).
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import platform
import re
from collections.abc import Mapping, Sequence
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, cast, overload

import numpy as np

from cadfeat.cad.export import sha256_file
from cadfeat.cad.features.identity import hole_name
from cadfeat.results import SCHEMA_VERSION, StudyResults

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cad.features import Hole
    from cadfeat.measures.evaluate import Measures
    from cadfeat.results import FeatureData, HoleData, JsonDict, MeasureSummaryData, PerPoseData

__all__ = [
    "DIGITS",

    "SCHEMA_VERSION",
    "file_entry",
    "hole_dict",
    "measures_summary",
    "normalise_step_header",
    "plain",
    "plain_float",
    "plain_floats",
    "versions",
    "write_json",
    "write_results",
]

DIGITS = 10
"""Significant digits of floats in results.json (1e-10 relative: far below any tolerance used)."""
STEP_TIMESTAMP = "1970-01-01T00:00:00"
"""Time stamp written into STEP headers (or ``SOURCE_DATE_EPOCH`` if set): reproducible files."""
_PRODUCT = re.compile(rb"'Open CASCADE STEP translator[^']*'")
_FILE_NAME = re.compile(rb"(FILE_NAME\s*\(\s*'(?:[^']|'')*'\s*,\s*')([^']*)(')")


@overload
def plain(value: Mapping[str, object], digits: int = DIGITS) -> JsonDict: ...
@overload
def plain(value: object, digits: int = DIGITS) -> object: ...
def plain(value: object, digits: int = DIGITS) -> object:
    """JSON-ready copy: numpy → Python, floats rounded to ``digits`` significant digits, non-finite → None,
    tuples → lists, Paths → str. Integers stay integers."""
    if isinstance(value, Mapping):
        return {str(k): plain(v, digits) for k, v in cast("Mapping[object, object]", value).items()}
    if isinstance(value, list | tuple):
        return [plain(v, digits) for v in cast("Sequence[object]", value)]
    if isinstance(value, np.ndarray):
        return plain(value.tolist(), digits)
    if isinstance(value, bool | np.bool_):
        return bool(cast(bool, value))
    if isinstance(value, int | np.integer):
        return int(cast(int, value))
    if isinstance(value, float | np.floating):
        return plain_float(cast(float, value), digits)
    if isinstance(value, Path):
        return str(value)
    return value


def plain_float(value: float, digits: int = DIGITS) -> float | None:
    """``plain`` of a float (a numpy float too): rounded to ``digits`` significant digits, None when not finite."""
    x = float(value)
    if not math.isfinite(x):
        return None
    return 0.0 if x == 0 else float(f"{x:.{digits}g}")


def plain_floats(values: np.ndarray | Sequence[float]) -> list[float | None]:
    """``plain`` of a 1-D float array: each value as ``plain_float`` gives it."""
    return [plain_float(v) for v in np.asarray(values, float).tolist()]


def write_json(path: str | os.PathLike[str], data: Mapping[str, object]) -> Path:
    """Write ``data`` as deterministic JSON (sorted keys, 2-space indent, trailing newline)."""
    path = Path(path)
    path.write_text(json.dumps(plain(data), indent=2, sort_keys=True, ensure_ascii=False, allow_nan=False) + "\n",
                    encoding="utf-8")
    return path


def write_results(path: str | os.PathLike[str], data: Mapping[str, object]) -> StudyResults:
    """Write results.json through the typed model: ``data`` made JSON-ready (``plain``), validated as
    ``StudyResults`` (a missing or mistyped section fails here, before the file exists) and written as the
    model gives it back (the same data). Returns the typed results."""
    results = StudyResults.from_data(plain(data))
    write_json(path, results.to_data())
    return results


def hole_dict(hole: Hole, index: int, fixed: bool, movable: bool) -> HoleData:
    """One hole as results.json ``H`` = {index, name, centre_mm, axis, radius_mm, depth_mm, through, kind,
    fixed, movable} (part frame, mm)."""
    return {
        "index": int(index), "name": hole_name(hole, index),
        "centre_mm": np.asarray(hole.centre, float).tolist(), "axis": np.asarray(hole.axis, float).tolist(),
        "radius_mm": float(hole.radius_mm), "depth_mm": float(hole.depth_mm), "through": bool(hole.through),
        "kind": str(hole.kind), "fixed": bool(fixed), "movable": bool(movable),
    }


def _arr(m: Measures, name: str, shape: tuple[int, ...]) -> np.ndarray:
    value = getattr(m, name, None)
    return np.full(shape, np.nan) if value is None else np.asarray(value, dtype=float)


def worst_poses(m: Measures, min_axis_px: float, half_image_px: float) -> np.ndarray:
    """(N,) index of each feature's worst pose: the smallest of its FOV image margin (in units of the half
    image size), focus margin and resolution margin (in units of ``min_axis_px``) — all dimensionless, 0 at
    the limit — with invisible samples counted as −∞."""
    fov_px = np.asarray(m.fov_px, float)
    L, N = fov_px.shape
    score = np.minimum.reduce([fov_px / max(half_image_px, 1.0), _arr(m, "focus", (L, N)),
                               _arr(m, "resolution_px", (L, N)) / max(min_axis_px, 1e-9)])
    score = np.where(np.asarray(m.visible, bool), np.nan_to_num(score, nan=-np.inf), -np.inf)
    if not L:
        return np.zeros(int(N), dtype=np.int_)
    worst: np.ndarray = np.asarray(np.argmin(score, axis=0))
    return worst


def measures_summary(m: Measures, names: Sequence[str], times_s: np.ndarray, min_axis_px: float,
                     half_image_px: float) -> MeasureSummaryData:
    """results.json ``M``: per-feature minima over the trajectory and per-pose series (contracts); per feature
    also ``hidden_frac`` (share of poses where the part hides it, occlusion ray test), ``hidden_worst_pose``
    (first such pose, or None) and ``folded_frac`` (share past the lens's fold radius)."""
    fov = np.asarray(m.fov, float)
    L, N = fov.shape
    fov_px, focus = _arr(m, "fov_px", (L, N)), _arr(m, "focus", (L, N))
    res = _arr(m, "resolution_px", (L, N))
    visible = np.asarray(m.visible, bool)
    worst = worst_poses(m, min_axis_px, half_image_px)
    hidden = np.asarray(getattr(m, "hidden", np.zeros((L, N), bool)), bool)
    folded = np.asarray(getattr(m, "folded", np.zeros((L, N), bool)), bool)
    per_feature: list[FeatureData] = [
        {"index": j, "name": names[j], "fov_min": plain_float(fov[:, j].min()),
         "fov_px_min": plain_float(fov_px[:, j].min()), "focus_min": plain_float(focus[:, j].min()),
         "resolution_px_min": plain_float(res[:, j].min()), "visible_frac": plain_float(visible[:, j].mean()),
         "worst_pose": int(worst[j]), "hidden_frac": plain_float(hidden[:, j].mean()),
         "hidden_worst_pose": int(np.argmax(hidden[:, j])) if hidden[:, j].any() else None,
         "folded_frac": plain_float(folded[:, j].mean())} for j in range(N)]
    per_pose: PerPoseData = {
        "time_s": plain_floats(times_s), "resolvability": plain_floats(_arr(m, "resolvability", (L,))),
        "sigma_min": plain_floats(_arr(m, "sigma_min", (L,))), "condition": plain_floats(_arr(m, "condition", (L,))),
        "fov_min": plain_floats(fov.min(axis=1)), "focus_min": plain_floats(focus.min(axis=1)),
        "resolution_px_min": plain_floats(res.min(axis=1)), "visible": [int(v) for v in visible.sum(axis=1)],
        "centre_px": plain(_arr(m, "centre_px", (L, N, 2)))}
    return {"per_feature": per_feature, "per_pose": per_pose}


def normalise_step_header(path: str | os.PathLike[str], product: str) -> None:
    """Make a written STEP file reproducible: the ``FILE_NAME`` time stamp becomes ``STEP_TIMESTAMP`` (or the
    time of ``SOURCE_DATE_EPOCH``) and OCCT's per-process counter in the product name ("Open CASCADE STEP
    translator 7.9 2") becomes ``product`` — the same design then gives a byte-identical file."""
    path = Path(path)
    stamp = STEP_TIMESTAMP
    if os.environ.get("SOURCE_DATE_EPOCH", "").isdigit():
        stamp = _dt.datetime.fromtimestamp(int(os.environ["SOURCE_DATE_EPOCH"]), _dt.UTC).strftime("%Y-%m-%dT%H:%M:%S")
    data = path.read_bytes()
    head, rest = data[:16384], data[16384:]
    head = _FILE_NAME.sub(lambda mt: mt.group(1) + stamp.encode() + mt.group(3), head, count=1)
    name = product.replace("'", "").encode()
    head = _PRODUCT.sub(b"'" + name + b"'", head)
    path.write_bytes(head + rest)


def file_entry(path: Path, root: Path) -> JsonDict:
    """``{name, bytes, sha256}`` of a written file (name relative to the output folder)."""
    return {"name": path.relative_to(root).as_posix(), "bytes": path.stat().st_size, "sha256": sha256_file(path)}


def versions() -> dict[str, str]:
    """Versions of Python and the libraries a study depends on."""
    out = {"python": platform.python_version()}
    for lib in ("cadfeat", "numpy", "scipy", "cadquery", "cadquery-ocp", "trimesh", "opencv-python-headless",
                "pymoo", "pyvista", "rich"):
        try:
            out[lib] = metadata.version(lib)
        except metadata.PackageNotFoundError:
            continue
    return out


def now_iso() -> str:
    """The current UTC time, ISO 8601 to the second."""
    return _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
