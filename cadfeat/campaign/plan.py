"""A campaign's cases: each axis value applied to the base study, every resolved study validated, hashed.

``load_campaign(path)`` reads the campaign file (``spec.parse_campaign``), reads the base study, applies
``[overrides]``, expands part globs, builds one study dict per case (paths made absolute, so that a worker
in any folder — or on another machine with the same paths — reads the same files) and validates each with the
study layer's own validator (``load_study``), all before any work. A bad case is one line naming the campaign
file, the case and the study's own message (dotted key, allowed values).

A case's *input hash* is the SHA-256 of the resolved study (``StudyConfig.to_dict()``: defaults filled in, so
writing a default explicitly does not change it) and the bytes of every file it reads (part, calibration,
trajectory CSV): a finished case with the same hash is not run again.
"""

from __future__ import annotations

import copy
import glob
import hashlib
import json
import os
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, cast

from cadfeat.campaign.spec import CampaignError, CampaignFile, case_values, mode_of, parse_campaign
from cadfeat.study.inputs import canonical_json, sha256_file

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import JsonDict

__all__ = ["Campaign", "Case", "load_campaign", "sha256_file"]

_SLUG_CHARS = re.compile(r"[^A-Za-z0-9_.-]+")
_PATH_KEYS = (("study", "part"), ("camera", "calibration"), ("trajectory", "csv"))


@dataclass(frozen=True)
class Case:
    """One study of the campaign: ``name`` (its output sub-folder and study name), the swept ``values`` as
    shown in the summary, the resolved ``study`` dict the worker runs, its ``input_hash`` and the SHA-256 of
    each file it reads (``files``: absolute path → hash), and its wall-time limit ``timeout_s``."""

    index: int
    name: str
    values: JsonDict
    study: JsonDict
    input_hash: str
    files: dict[str, str]
    timeout_s: float


@dataclass(frozen=True)
class Campaign:
    """A validated campaign: its file, name, the base study file, the axes and the cases."""

    file: Path
    name: str
    description: str
    base_study: Path
    mode: str
    axes: tuple[str, ...]
    cases: tuple[Case, ...]
    retries: int
    model: CampaignFile = field(repr=False)


_canonical = canonical_json


def _read_base(label: str, path: Path) -> JsonDict:
    if not path.is_file():
        raise CampaignError(f"{label}: campaign.study: file {path} does not exist; allowed: an existing study file "
                            "(TOML), relative to the campaign file")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise CampaignError(f"{label}: campaign.study: {path} is not valid TOML ({exc}); allowed: a study "
                            "file") from None
    _absolute_paths(data, path.parent)
    return data


def _absolute_paths(study: JsonDict, base: Path) -> None:
    """Make the study's file paths (part, calibration, trajectory CSV) absolute, relative to ``base``."""
    for section, key in _PATH_KEYS:
        table = study.get(section)
        if isinstance(table, dict) and isinstance(path := cast("dict[str, object]", table).get(key), str):
            cast("dict[str, object]", table)[key] = str((base / path).resolve())


def _expand_parts(label: str, key: str, values: Sequence[object], base: Path, single: bool) -> list[str]:
    """Part paths or globs (relative to the campaign file) → absolute paths, sorted per glob."""
    out: list[str] = []
    for v in values:
        if not isinstance(v, str) or not v.strip():
            raise CampaignError(f"{label}: {key}: {v!r} is not a path; allowed: part files (.py, .step, .stp) or "
                                "globs, relative to the campaign file")
        pattern = str(base / v)
        found = sorted(glob.glob(pattern, recursive=True)) if glob.has_magic(v) else [pattern]
        if not found:
            raise CampaignError(f"{label}: {key}: {v!r} matches no file; allowed: part files or globs that "
                                "match at least one file, relative to the campaign file")
        if single and len(found) > 1:
            raise CampaignError(f"{label}: {key}: {v!r} matches {len(found)} files; allowed: one part per case "
                                "(use [axes] part = [...] to sweep several)")
        out += [str(Path(p).resolve()) for p in found]
    return out


def _camera(value: object, base: Path, label: str, key: str) -> JsonDict:
    if isinstance(value, str):
        return {"preset": value}
    if isinstance(value, Mapping):
        table = copy.deepcopy(dict(cast("Mapping[str, object]", value)))
        if isinstance(calibration := table.get("calibration"), str):
            table["calibration"] = str((base / calibration).resolve())
        return table
    raise CampaignError(f"{label}: {key}: {value!r} is not a camera; allowed: a preset name (cadfeat cameras) or "
                        "a [camera] table ({preset = ...}, {calibration = \"file.yaml\"} or intrinsics)")


def _table(study: JsonDict, section: str) -> dict[str, object]:
    """The study's table ``[section]`` (an empty one added when it has none)."""
    table = study.setdefault(section, {})
    if not isinstance(table, dict):
        raise CampaignError(f"[{section}] of the base study is not a table")
    return cast("dict[str, object]", table)


def _apply(study: JsonDict, key: str, value: object) -> None:
    if key == "part":
        _table(study, "study")["part"] = value
    elif key == "camera":
        study["camera"] = value
    else:
        section, _, name = key.partition(".")
        _table(study, section)[name] = copy.deepcopy(value)


def _shown(key: str, value: object, base: Path) -> object:
    """A swept value as the summary shows it: parts relative to the campaign folder, cameras by name."""
    if key == "part":
        return Path(os.path.relpath(str(value), base)).as_posix()
    if key == "camera" and isinstance(value, Mapping):
        value = cast("Mapping[str, object]", value)  # (``_camera``'s table)
        named = {"preset": value.get("preset"), "calibration": Path(str(value.get("calibration"))).name}
        key_ = "preset" if "preset" in value else "calibration" if "calibration" in value else None
        rest = ", ".join(f"{k}={v}" for k, v in value.items() if k != key_)
        if key_ is None:
            return json.dumps(value, sort_keys=True)
        return f"{named[key_]} ({rest})" if rest else named[key_]
    return value


def _slug_part(key: str, value: object) -> str:
    if key == "part":
        return Path(str(value)).stem
    if key == "camera":
        return str(value).split(" (")[0].removesuffix(".yaml").removesuffix(".yml").removesuffix(".json")
    if isinstance(value, list):
        return "x".join(map(str, cast("list[object]", value)))
    return str(value)


def case_name(values: Mapping[str, object]) -> str:
    """A case's folder and study name: its values, shortened, and a hash of them (unique per value set)."""
    slug = _SLUG_CHARS.sub("-", "_".join(_slug_part(k, v) for k, v in values.items())).strip("-._")[:48]
    digest = hashlib.sha256(_canonical(values)).hexdigest()[:8]
    return f"{slug}-{digest}" if slug else f"case-{digest}"


def _file_hashes(study: Mapping[str, object]) -> dict[str, str]:
    out: dict[str, str] = {}
    for section, key in _PATH_KEYS:
        table = study.get(section)
        value = cast("Mapping[str, object]", table).get(key) if isinstance(table, Mapping) else None
        if isinstance(value, str) and Path(value).is_file():
            out[value] = sha256_file(value)
    return out


def input_hash(config_dict: Mapping[str, object], files: Mapping[str, str]) -> str:
    """SHA-256 of the resolved study and the bytes of the files it reads (their hashes)."""
    return hashlib.sha256(_canonical({"study": config_dict, "files": dict(sorted(files.items()))})).hexdigest()


def _describe(values: Mapping[str, object]) -> str:
    return ", ".join(f"{k}={v}" for k, v in values.items())


def _validated(label: str, index: int, shown: Mapping[str, object], study: JsonDict) -> JsonDict:
    """The study's own validator on one case: its resolved dict (defaults filled in), or ``CampaignError``."""
    from cadfeat.study.schema import StudyError, load_study  # lazy: would import scipy.spatial at module load

    try:
        config = load_study(study)
    except StudyError as exc:
        msg = str(exc).removeprefix("<study dict>: ")
        raise CampaignError(f"{label}: case {index + 1} ({_describe(shown)}): {msg}") from None
    return config.to_dict()


def _overridden(label: str, base: JsonDict, overrides: Mapping[str, Mapping[str, object]],
                folder: Path) -> JsonDict:
    from cadfeat.study.schema import SECTIONS  # lazy: would import scipy.spatial at module load

    study = copy.deepcopy(base)
    for section, table in overrides.items():
        if section not in SECTIONS:
            raise CampaignError(f"{label}: overrides.{section}: unknown study section; allowed: "
                                f"{', '.join(SECTIONS)}")
        _table(study, section).update(copy.deepcopy(dict(table)))
    _absolute_paths({k: v for k, v in study.items() if k in overrides}, folder)
    return study


def load_campaign(path: str | Path) -> Campaign:
    """Read and validate a campaign file and every case's study, before any work (``CampaignError``)."""
    path = Path(path)
    label = str(path)
    model = parse_campaign(path)
    folder = path.parent.resolve()
    base_path = (folder / model.campaign.study).resolve()
    base = _overridden(label, _read_base(label, base_path), model.overrides, folder)
    if "part" in model.axes:
        model = model.model_copy(update={"axes": {**model.axes, "part": _expand_parts(
            label, "axes.part", model.axes["part"], folder, single=False)}})
    cases: list[Case] = []
    seen: dict[str, int] = {}
    for i, raw in enumerate(case_values(model)):
        raw = dict(raw)
        timeout = float(raw.pop("timeout_s", model.campaign.timeout_s))
        if not timeout > 0:
            raise CampaignError(f"{label}: cases[{i}].timeout_s: {timeout!r} is not allowed; allowed: a number of "
                                "seconds > 0")
        values: JsonDict = {}
        for key, value in raw.items():
            if key == "part" and model.cases:
                value = _expand_parts(label, f"cases[{i}].part", [value], folder, single=True)[0]
            elif key == "camera":
                value = _camera(value, folder, label, "axes.camera" if model.axes else f"cases[{i}].camera")
            values[key] = value
        shown = {k: _shown(k, v, folder) for k, v in values.items()}
        name = case_name(shown)
        if name in seen:
            raise CampaignError(f"{label}: case {i + 1} ({_describe(shown)}) repeats case {seen[name] + 1}; "
                                "allowed: distinct value sets")
        seen[name] = i
        study = copy.deepcopy(base)
        for key, value in values.items():
            _apply(study, key, value)
        _table(study, "study")["name"] = name
        resolved = _validated(label, i, shown, study)
        files = _file_hashes(study)
        cases.append(Case(i, name, shown, study, input_hash(resolved, files), files, timeout))
    axes = tuple(model.axes) if model.axes else tuple(dict.fromkeys(k for c in model.cases for k in c
                                                                     if k != "timeout_s"))
    return Campaign(path.resolve(), model.campaign.name, model.campaign.description, base_path, mode_of(model), axes,
                    tuple(cases), model.campaign.retries, model)
