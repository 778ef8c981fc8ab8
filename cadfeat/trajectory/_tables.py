"""A study file's ``[trajectory]`` table → ``Trajectory`` (a library kind + its arguments, or a CSV file)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from cadfeat.errors import CadfeatError
from cadfeat.trajectory._core import (
    Trajectory,
    TrajectoryError,
)
from cadfeat.trajectory._csv import read_csv
from cadfeat.trajectory._library import (
    TRAJECTORY_KINDS,
    kind_arguments,
)


# ---------------------------------------------------------------------- study-file tables
def trajectory_from_dict(spec: Mapping[str, Any], origin: str = "trajectory",
                         base_dir: str | Path | None = None) -> Trajectory:
    """Build a trajectory from plain data: ``{"kind": name, **arguments}`` or ``{"csv": path}``.

    Either form may add ``name``. ``origin`` names the source (e.g. ``"study.toml [trajectory]"``) in
    error messages; a relative CSV path is resolved against ``base_dir`` (the study file's folder).
    Raises one ``TrajectoryError`` naming origin, key and the allowed values.
    """
    if not isinstance(spec, Mapping):
        raise TrajectoryError(f"{origin}: expected a table with 'kind' or 'csv', got {type(spec).__name__}")
    spec = dict(spec)
    name = spec.pop("name", None)
    if name is not None and not isinstance(name, str):
        raise TrajectoryError(f"{origin}: name: expected a string, got {name!r}")
    if ("kind" in spec) == ("csv" in spec):
        raise TrajectoryError(f"{origin}: give exactly one of 'kind' (one of {', '.join(TRAJECTORY_KINDS)}) "
                              f"or 'csv' (a CSV file of poses)")
    if "csv" in spec:
        traj = _from_csv_spec(spec, origin, base_dir)
    else:
        traj = _from_kind_spec(spec, origin)
    return traj if name is None else Trajectory(traj.T_task_cam, traj.times_s, name, traj.screws)


def _from_csv_spec(spec: dict[str, Any], origin: str, base_dir: str | Path | None) -> Trajectory:
    extra = sorted(set(spec) - {"csv"})
    if extra:
        raise TrajectoryError(f"{origin}: unknown key(s) {', '.join(extra)} with 'csv'; allowed: csv, name")
    if not isinstance(spec["csv"], str | Path):
        raise TrajectoryError(f"{origin}: csv: expected a file path, got {spec['csv']!r}")
    path = Path(spec["csv"])
    if base_dir is not None and not path.is_absolute():
        path = Path(base_dir) / path
    try:
        return read_csv(path)
    except TrajectoryError as exc:
        raise TrajectoryError(f"{origin}: csv: {exc}") from exc


def _from_kind_spec(spec: dict[str, Any], origin: str) -> Trajectory:
    kind = spec.pop("kind")
    if not isinstance(kind, str) or kind not in TRAJECTORY_KINDS:
        raise TrajectoryError(f"{origin}: kind: unknown trajectory kind {kind!r}; "
                              f"allowed: {', '.join(TRAJECTORY_KINDS)}")
    args = kind_arguments(kind)
    allowed = ", ".join(a.name for a in args)
    unknown = sorted(set(spec) - {a.name for a in args})
    if unknown:
        raise TrajectoryError(f"{origin}: unknown key(s) {', '.join(unknown)} for kind '{kind}'; "
                              f"allowed: kind, name, {allowed}")
    missing = [a.name for a in args if a.required and a.name not in spec]
    if missing:
        raise TrajectoryError(f"{origin}: kind '{kind}' needs {', '.join(missing)}; arguments: {allowed}")
    values = {}
    for a in args:
        if a.name in spec:
            try:
                values[a.name] = a.arg_type.convert(spec[a.name])
            except TypeError as exc:
                raise TrajectoryError(f"{origin}: {a.name}: {exc}, got {spec[a.name]!r}; "
                                      f"allowed: {a.arg_type.description}") from exc
    try:
        return TRAJECTORY_KINDS[kind](**values)
    except CadfeatError as exc:
        raise TrajectoryError(f"{origin}: {exc}") from exc
