"""Campaign files: the TOML format and its pydantic v2 model (``extra="forbid"``), with one-line errors.

A campaign is a base study plus axes to sweep (docs/guide/campaigns.md)::

    [campaign]   name, study (the base study file, relative to the campaign file), description,
                 timeout_s (wall-time limit of one case, s), retries (re-runs of a case whose worker died)
    [overrides]  tables merged into the base study first, e.g. [overrides.trajectory] n = 6
    [axes]       a full grid: each key an axis, each value the list of its values
    [[cases]]    or a list of cases: each a table of axis values (and optionally its own timeout_s)

Axis keys: ``part`` (part files or globs, relative to the campaign file), ``camera`` (a preset name, or a
table that replaces the study's [camera]: {preset = ...}, {calibration = "file.yaml"} or explicit
intrinsics), ``trajectory.<argument>``, ``objective.<setting>``, ``optimizer.<setting>``, ``study.seed``.
Only the campaign's own structure is checked here; every case's resolved study is then validated by the study
layer (``cadfeat.campaign.plan``), all before any work.
"""

from __future__ import annotations

import itertools
import re
import tomllib
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator
from pydantic_core import ErrorDetails

from cadfeat.errors import CadfeatError

__all__ = ["AXIS_SECTIONS", "CampaignError", "CampaignFile", "CampaignInfo", "parse_campaign"]

#: Study sections whose keys may be swept as ``<section>.<key>`` (``part`` and ``camera`` are axes of their own).
AXIS_SECTIONS = ("trajectory", "objective", "optimizer")
_SINGLE_AXES = ("part", "camera", "study.seed")
_NAME = r"^[A-Za-z0-9][A-Za-z0-9_.-]*$"
_AXIS_TEXT = ("part, camera, study.seed, trajectory.<argument>, objective.<setting>, optimizer.<setting> "
              "(see docs/guide/campaigns.md)")


class CampaignError(CadfeatError):
    """A campaign file is invalid: the message names the file, the dotted key and what is allowed."""


class CampaignInfo(BaseModel):
    """``[campaign]``: name (output folder), the base study, limits per case."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field(pattern=_NAME, description="a folder name: letters, digits, '_', '-', '.'")
    study: str = Field(min_length=1, description="the base study file (TOML), relative to the campaign file")
    description: str = ""
    timeout_s: float = Field(3600.0, gt=0, le=7 * 86_400, description="wall-time limit of one case (s)")
    retries: int = Field(1, ge=0, le=10, description="re-runs of a case whose worker process died")


def check_axis_key(key: str) -> str:
    """``key`` is an axis name (``_SINGLE_AXES`` or ``<section>.<key>`` of ``AXIS_SECTIONS``)."""
    section, _, rest = key.partition(".")
    if key in _SINGLE_AXES or (section in AXIS_SECTIONS and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", rest)):
        return key
    raise ValueError(f"unknown axis {key!r}")


class CampaignFile(BaseModel):
    """A whole campaign file: ``[campaign]``, ``[overrides]`` and either ``[axes]`` (grid) or ``[[cases]]``."""

    model_config = ConfigDict(extra="forbid")

    campaign: CampaignInfo
    overrides: dict[str, dict[str, object]] = Field(default_factory=dict)
    axes: dict[str, list[object]] = Field(default_factory=dict)
    cases: list[dict[str, object]] = Field(default_factory=list)

    @field_validator("axes")
    @classmethod
    def _axis_names(cls, axes: dict[str, list[object]]) -> dict[str, list[object]]:
        for key, values in axes.items():
            check_axis_key(key)
            if not values:
                raise ValueError(f"axis {key!r} has no values")
        return axes

    @field_validator("cases")
    @classmethod
    def _case_keys(cls, cases: list[dict[str, object]]) -> list[dict[str, object]]:
        for case in cases:
            for key in case:
                if key != "timeout_s":
                    check_axis_key(key)
        return cases

    @model_validator(mode="after")
    def _grid_or_cases(self) -> CampaignFile:
        if bool(self.axes) == bool(self.cases):
            raise ValueError("give either [axes] (a full grid) or [[cases]] (a list of cases), not "
                             + ("both" if self.axes else "neither"))
        return self


def _allowed(err: ErrorDetails) -> str:
    """The allowed values of one pydantic error, in words."""
    loc = [str(p) for p in err["loc"]]
    kind = err["type"]
    if kind == "extra_forbidden":
        model: type[BaseModel] = CampaignInfo if loc[:1] == ["campaign"] and len(loc) == 2 else CampaignFile
        return "keys " + ", ".join(model.model_fields)
    if "axis" in err["msg"]:
        return _AXIS_TEXT + (" and timeout_s" if loc[:1] == ["cases"] else "")
    field = CampaignInfo.model_fields.get(loc[-1]) if loc[:1] == ["campaign"] else None
    if field is not None and field.description:
        return field.description
    return "see docs/guide/campaigns.md"


def _dotted(loc: tuple[int | str, ...]) -> str:
    out = ""
    for p in loc:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "(file)"


def one_line(label: str, exc: ValidationError) -> CampaignError:
    """The first error of a pydantic validation as one line: file, dotted key, problem, allowed values."""
    err = exc.errors()[0]
    msg = err["msg"].removeprefix("Value error, ")
    given = err.get("input")
    shown = "" if err["type"] in ("missing", "extra_forbidden") or isinstance(given, dict | list) else \
        f" (given: {given!r})"
    return CampaignError(f"{label}: {_dotted(err['loc'])}: {msg}{shown}; allowed: {_allowed(err)}")


def parse_campaign(path: str | Path) -> CampaignFile:
    """Read and check a campaign file's structure (TOML, sections, keys, types); ``CampaignError`` otherwise."""
    path = Path(path)
    label = str(path)
    if not path.is_file():
        raise CampaignError(f"{label}: campaign file does not exist; allowed: a path to a .toml campaign file")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise CampaignError(f"{label}: not valid TOML: {exc}; allowed: a TOML campaign file "
                            "(docs/guide/campaigns.md)") from None
    try:
        return CampaignFile.model_validate(data)
    except ValidationError as exc:
        raise one_line(label, exc) from None


def case_values(model: CampaignFile) -> list[dict[str, object]]:
    """The raw axis values of every case (grid: the Cartesian product, first axis slowest), ``timeout_s`` kept."""
    if model.cases:
        return [dict(c) for c in model.cases]
    keys = list(model.axes)
    return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*model.axes.values())]


Mode = Literal["grid", "cases"]


def mode_of(model: CampaignFile) -> Mode:
    return "grid" if model.axes else "cases"
